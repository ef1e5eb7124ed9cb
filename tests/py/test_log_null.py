"""The null calibration made for a log: its tail model, checked on the
committed 1000-run calibrations; the pose noise drawn at the log's own
sigmas; the key of its cache and the checks on a cached entry; the
false-alarm campaign on random vehicles (its mechanics, not its rate)."""

import copy
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.campaigns.gap import log_null_far
from bench.campaigns.gap.log_null_far import MAX_RATIO, tail_evidence
from bench.gap import log_null
from bench.gap.log_null import FA_EACH, STATISTICS, frechet_threshold, tail_threshold

DATA = Path(__file__).resolve().parents[2] / "bench" / "gap" / "data"


def test_tail_from_40_runs_holds_the_false_alarm_rate():
    # 500 random 40-run calibrations drawn from each committed 1000-run one;
    # each pair of thresholds judged on all 1000 null runs.
    ev = tail_evidence(draws=500, seed=2026, models={"used": lambda v: tail_threshold(v)[0]})
    for manoeuvres, rows in ev["models"].items():
        r = rows["used"]
        assert r["false_alarm_median"] <= 2 * FA_EACH, (manoeuvres, r)
        assert r["false_alarm_p95"] <= 0.02, (manoeuvres, r)
        for k in STATISTICS:  # each statistic at its own target
            assert r[f"false_alarm_mean_{k}"] <= 1.25 * FA_EACH, (manoeuvres, k, r)
        # and not far above the values it was made from
        assert r["ratio_to_max_p99"] <= MAX_RATIO, (manoeuvres, r)


def test_a_long_lower_tail_does_not_move_the_threshold():
    # Null values far below the tail (a log's runs where a statistic is
    # near zero) pulled the Gumbel fitted to log(values) far above the
    # values themselves; the tail fitted to the top ignores them.
    rng = np.random.default_rng(5)
    cal = json.loads((DATA / "null_calibration.json").read_text())
    for k in STATISTICS:
        for _ in range(20):
            v = rng.choice(np.array(cal[f"null_{k}"]), 40, replace=False)
            low = log_null_far._stretched_low(v, rng)
            assert np.sum(low < v) >= 10
            assert tail_threshold(low)[0] == tail_threshold(v)[0] <= MAX_RATIO * v.max()
        assert frechet_threshold(low) > MAX_RATIO * low.max()


def test_leave_one_out_judges_each_null_run_by_the_others():
    rng = np.random.default_rng(3)
    null = {k: rng.gumbel(3.0, 0.5, 40) for k in STATISTICS}
    flagged, n = log_null_far.leave_one_out(null)
    assert n == 40 and 0 <= flagged <= 3
    null["screen_logp"][7] = 50.0  # far above the others: flagged
    assert log_null_far.leave_one_out(null)[0] >= 1


def test_the_tail_is_fitted_to_the_top_and_recorded():
    v = np.arange(1.0, 41.0)
    thr, tail = tail_threshold(v)
    assert (tail["n"], tail["k"], tail["u"]) == (40, 24, 16.0)
    assert tail["mean_excess"] == pytest.approx(12.5) and tail["p_above_u"] == pytest.approx(25 / 41)
    assert thr == pytest.approx(16.0 + 24 * 12.5 * ((25 / 41 / FA_EACH) ** (1 / 24) - 1))
    w = v.copy()
    w[:15] = 1e-6  # the values below u
    assert tail_threshold(w)[0] == thr
    with pytest.raises(ValueError, match="finite"):
        tail_threshold([1.0, np.nan, 2.0])


def test_stated_bias_stability_puts_biases_into_the_null():
    """A bias within the IMU's stated stability is part of the null: each
    bootstrap flight carries a constant bias drawn at that size."""
    from bench.gap.log_null import _bench_like, null_log_like, stated_biases
    from bench.sim.log_description import resolve
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import simulate
    from bench.sim.vehicles import inspector_12kg

    base = inspector_12kg()
    assert stated_biases(base, 1) == {}
    stated = copy.deepcopy(base)
    stated["imu"]["gyro_bias_stability_rps"] = 2e-3
    stated["imu"]["accel_bias_stability_mps2"] = 1e-3
    g = np.array([stated_biases(stated, s)["gyro_bias"] for s in range(600)])
    a = np.array([stated_biases(stated, s)["accel_bias"] for s in range(600)])
    assert np.allclose(g.std(axis=0), 2e-3, rtol=0.12) and np.allclose(a.std(axis=0), 1e-3, rtol=0.12)
    assert np.all(np.abs(g.mean(axis=0)) < 4 * 2e-3 / np.sqrt(600))
    assert _bench_like(resolve(stated), resolve(base)) == [
        "another accelerometer bias stability",
        "another gyro bias stability",
    ]

    plan = characterisation_plan(base, seed=3)[:1]
    log0, _ = simulate(base, plan, {}, seed=3, with_truth=False)
    log1 = copy.deepcopy(log0)
    log1.description = dict(log1.description, imu=stated["imu"])
    n0, n1 = null_log_like(log0, seed=11), null_log_like(log1, seed=11)
    dg = n1.streams["imu"]["omega_bi_b_rps"] - n0.streams["imu"]["omega_bi_b_rps"]
    np.testing.assert_allclose(dg, np.broadcast_to(stated_biases(stated, 11)["gyro_bias"], dg.shape), atol=1e-6)


@pytest.fixture(scope="module")
def one_vehicle():
    """(description, plan, clocks, log A, log B): two effect-free logs of one
    random vehicle flying one plan, other noise (seeds 11 and 12), the same
    time stamps relative to each run, written a day and a bit apart."""
    from bench.sim.plans import characterisation_plan
    from bench.sim.random_vehicle import random_clocks, random_description
    from bench.sim.vehicle_sim import simulate

    desc = random_description(1)
    plan = characterisation_plan(desc, 1)[:2]
    clocks = dataclasses.replace(
        random_clocks(1, desc["imu"]["rate_hz"]), imu_jitter_s=0.0, imu_drop_frac=0.0, pose_jitter_s=0.0
    )
    a, _ = simulate(desc, plan, {}, seed=11, clocks=clocks, with_truth=False)
    later = dataclasses.replace(clocks, epoch_s=clocks.epoch_s + 86400.25)
    b, _ = simulate(desc, plan, {}, seed=12, clocks=later, with_truth=False)
    return desc, plan, clocks, a, b


def test_two_logs_of_one_vehicle_and_plan_share_a_key(one_vehicle):
    desc, _, _, a, b = one_vehicle
    assert not np.allclose(a["pose"]["r_hill_m"][0], b["pose"]["r_hill_m"][0])  # other noise, other first pose
    assert a["imu"]["t_s"][0] != b["imu"]["t_s"][0]
    key = log_null.fingerprint(a, 40, 7100)
    assert log_null.fingerprint(b, 40, 7100) == key
    assert log_null.fingerprint(a, 41, 7100) != key and log_null.fingerprint(a, 40, 7101) != key

    valve = copy.deepcopy(a)
    valve["valves"]["on_time_s"][3] += 1e-3 * (valve["valves"]["on_time_s"][3] > 0)
    heavier = copy.deepcopy(a)
    heavier.description = dict(a.description, vehicle=dict(desc["vehicle"], mass_kg=desc["vehicle"]["mass_kg"] * 1.01))
    noisier = copy.deepcopy(a)
    noisier["pose"]["att_sigma_rad"] = noisier["pose"]["att_sigma_rad"] * 1.5
    for other in (valve, heavier, noisier):
        assert log_null.fingerprint(other, 40, 7100) != key


def test_the_bootstrap_draws_pose_noise_at_the_logs_own_sigmas(one_vehicle):
    log = copy.deepcopy(one_vehicle[3])
    n_pose = log["pose"]["r_sigma_m"].size
    log["pose"]["r_sigma_m"] = np.full(n_pose, 0.2)
    log["pose"]["att_sigma_rad"] = np.full(n_pose, 0.03)
    prepared = log_null.plan_of(log)
    n1, n2 = (log_null.null_log_like(log, s, prepared) for s in (1, 2))
    for n in (n1, n2):
        assert n["pose"]["r_sigma_m"].size == prepared[3].pose_tc.size
        np.testing.assert_allclose(n["pose"]["r_sigma_m"], 0.2)
        np.testing.assert_allclose(n["pose"]["att_sigma_rad"], 0.03)
    # The same flight (same start, commands, stamps), other noise: the
    # differences carry twice each pose's variance.
    dr = n1["pose"]["r_hill_m"] - n2["pose"]["r_hill_m"]
    assert np.std(dr) == pytest.approx(0.2 * math.sqrt(2), rel=0.1)
    q1, q2 = n1["pose"]["q_hb"], n2["pose"]["q_hb"]
    ang = 2 * np.arccos(np.clip(np.abs(np.sum(q1 * q2, axis=1)), 0, 1))
    # |difference of two 3-D rotations of sigma s each| has RMS sqrt(6) s
    assert np.sqrt(np.mean(ang**2)) == pytest.approx(0.03 * math.sqrt(6), rel=0.1)


def test_a_damaged_or_mismatched_cache_entry_is_made_again(one_vehicle, tmp_path):
    log = copy.deepcopy(one_vehicle[3])
    cal = log_null.calibrate_for_log(log, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    key = cal["fingerprint"]
    assert cal["from_cache"] is None and cal["tail"]["screen_logp"]["n"] == 3
    assert log_null.unusable(cal, key, 3) is None
    entry = Path(cal["cached_at"])
    stored = json.loads(entry.read_text())

    def variant(**changes):
        v = copy.deepcopy(stored)
        for k, x in changes.items():
            v[k] = x
        return v

    bad = {
        "not finite": variant(thresholds={**stored["thresholds"], "map_max_abs_z": float("nan")}),
        "not its null values'": variant(
            thresholds={**stored["thresholds"], "screen_logp": 3 * cal["thresholds"]["screen_logp"]}
        ),
        "another log": variant(fingerprint="0" * 64),
        "version": variant(version=1),
        "null_screen_logp missing": variant(null_screen_logp=None),
    }
    for why, v in bad.items():
        assert why in log_null.unusable(v, key, 3), why
    # A cached entry with a NaN threshold is not used: made again, from the same runs' seeds.
    entry.write_text(json.dumps(bad["not finite"]))
    again = log_null.calibrate_for_log(log, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    assert again["from_cache"] is None and "not finite" in again["made_again_because"]
    assert again["thresholds"] == cal["thresholds"]
    third = log_null.calibrate_for_log(log, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    assert third["from_cache"] and third["thresholds"] == cal["thresholds"]
    # Supplied with --calibration, a raised threshold is refused.
    from bench.gap.load import prepare

    with pytest.raises(log_null.CalibrationMismatch, match="not its null values"):
        log_null.check_supplied(bad["not its null values'"], log, prepare(log), "cal.json")


def test_false_alarm_campaign_mechanics(tmp_path):
    """Two random vehicles, 3 null runs each, 2 fresh logs each: the
    mechanics of ``python -m bench.campaigns.gap.log_null_far far`` (not its rate)."""
    from bench.runner.runner import Campaign
    from bench.runner.store import RunStore

    def run():
        store = RunStore("log-null-far", {"test": 1}, root=tmp_path / "runs")
        return log_null_far.far(2, 2, 3, 17, Campaign(store, workers=1, progress=False), cache_dir=tmp_path / "cal")

    res = run()
    assert res["summary"]["vehicles"] == len(res["vehicles"]) == 2
    for v in res["vehicles"]:
        assert len(v["logs"]) == 2 and not v["failed_logs"] and not v["calibration_from_cache"]
        assert v["tail"]["map_max_abs_z"]["n"] == 3 and v["leave_one_out"][1] == 3
        for s in [v["own_log"]] + v["logs"]:
            over = {k: s[k] > v["thresholds"][k] for k in STATISTICS}
            assert s["over"] == over and s["false_alarm"] == any(over.values())
    f = res["summary"]["fresh_logs"]
    assert f["logs"] == 4 and f["false_alarms"] == sum(s["false_alarm"] for v in res["vehicles"] for s in v["logs"])
    assert 0.0 <= f["interval95"][0] <= f["interval95"][1] <= 1.0
    assert res["summary"]["leave_one_out"]["logs"] == 6
    again = run()  # resumed: the calibrations from their cache, the logs' statistics from the store
    assert all(v["calibration_from_cache"] for v in again["vehicles"])
    assert again["summary"] == res["summary"]


def test_another_flight_of_the_plan_with_its_own_jitter_shares_its_calibration(tmp_path):
    """Two flights of one vehicle and plan, each with its own jittered and
    dropped IMU samples and its own epoch: two fingerprints, one family, the
    same timing shape, so the second log's calibration is the first's, from
    the cache. With the gyro rows' noise through the gyroscopic term in the
    model, the thresholds no longer follow the stamps (docs/GAP.md, "The
    cache"). A flight at another IMU rate, with other valves or with a
    command 10 ms later does not share it."""
    from bench.gap.load import prepare
    from bench.sim.plans import characterisation_plan
    from bench.sim.random_vehicle import random_clocks, random_description
    from bench.sim.vehicle_sim import simulate

    desc = random_description(4)
    plan = characterisation_plan(desc, 4)[:2]
    clocks = dataclasses.replace(
        random_clocks(4, desc["imu"]["rate_hz"]), imu_jitter_s=0.05 / desc["imu"]["rate_hz"], imu_drop_frac=0.01
    )
    a, _ = simulate(desc, plan, {}, seed=21, clocks=clocks, with_truth=False)
    b, _ = simulate(desc, plan, {}, seed=22, clocks=dataclasses.replace(clocks, epoch_s=clocks.epoch_s + 3600.0))
    assert not np.array_equal(np.diff(a["imu"]["t_s"]), np.diff(b["imu"]["t_s"]))  # other jitter and drops
    assert log_null.fingerprint(a, 40, 7100) != log_null.fingerprint(b, 40, 7100)
    assert log_null.family(a, 40, 7100) == log_null.family(b, 40, 7100)
    pa, pb = log_null.plan_of(a), log_null.plan_of(b)
    assert log_null.shape_differs(log_null.timing_shape(pa), log_null.timing_shape(pb)) is None

    faster = dict(desc, imu=dict(desc["imu"], rate_hz=2 * desc["imu"]["rate_hz"]))
    c, _ = simulate(faster, plan, {}, seed=21, clocks=clocks, with_truth=False)
    assert log_null.family(c, 40, 7100) != log_null.family(a, 40, 7100)
    other_valves = plan[::-1]  # the same runs, flown in the other order
    e, _ = simulate(desc, other_valves, {}, seed=21, clocks=clocks, with_truth=False)
    assert log_null.family(e, 40, 7100) != log_null.family(a, 40, 7100)
    later = copy.deepcopy(b)
    later["valves"]["t_s"] = later["valves"]["t_s"] + np.where(np.arange(later["valves"]["t_s"].size) == 2, 0.01, 0.0)
    off = log_null.shape_differs(log_null.timing_shape(pa), log_null.timing_shape(log_null.plan_of(later)))
    assert off is not None and "command" in off

    cal = log_null.calibrate_for_log(a, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    shared = log_null.calibrate_for_log(b, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    assert shared["from_cache"] and shared["thresholds"] == cal["thresholds"]
    assert "another flight of this vehicle and plan" in shared["shared_from"]
    log_null.check_supplied(cal, b, prepare(b), "cal.json")  # supplied: accepted for the second flight
    with pytest.raises(log_null.CalibrationMismatch, match="command"):
        log_null.check_supplied(cal, later, prepare(later), "cal.json")
    with pytest.raises(log_null.CalibrationMismatch, match="another vehicle or plan"):
        log_null.check_supplied(cal, e, prepare(e), "cal.json")
    # A damaged or edited shape is refused, never read: supplied, one line;
    # cached, the second flight makes its own.
    for damaged in ([{}], [dict(cal["shape"][0], imu_jitter_s="x")], [dict(cal["shape"][0], cmd_t_s=[[1.0], 2.0])]):
        with pytest.raises(log_null.CalibrationMismatch, match="not a timing shape"):
            log_null.check_supplied(dict(cal, shape=damaged + cal["shape"][1:]), b, prepare(b), "cal.json")
    entry = Path(cal["cached_at"])
    entry.write_text(json.dumps(dict(json.loads(entry.read_text()), shape=[{}] * len(cal["shape"]))))
    own = log_null.calibrate_for_log(b, runs=3, seed=3, workers=1, cache_dir=tmp_path, progress=False)
    assert own["from_cache"] is None and own["fingerprint"] != cal["fingerprint"]
