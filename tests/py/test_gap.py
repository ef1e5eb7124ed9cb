"""Gap diagnosis (bench/gap): replay, detection against the committed null
calibration, attribution, held-out shrink, and a CI-sized blind campaign."""

import numpy as np
import pytest

from bench.campaigns.gap.validate import blind, run_campaign
from bench.gap import null as nullmod
from bench.gap.diagnose import diagnose, public
from bench.gap.load import prepare
from bench.gap.replay import reference

reality = pytest.importorskip("bench.sim.reality")

DURATION_S = 120.0


def _log(seed, effects):
    log, _ = reality.simulate_log_with_key(seed, effects, duration_s=DURATION_S, with_truth=False)
    return blind(log)


@pytest.fixture(scope="module")
def calibration():
    cal = nullmod.load()
    assert cal, "bench/gap/data/null_calibration.json missing (python -m bench.commands.null_calibration)"
    return cal


def test_replay_reproduces_flight_innovations_after_convergence():
    log, _ = reality.simulate_log_with_key(21, {}, duration_s=60.0)
    d = prepare(log)
    res = reference(d)
    flight = log["update"]
    # The flight filter started from a pose the log does not hold (t = 0);
    # once both have converged the replayed innovations equal the flight's.
    t_late = flight["t_s"][-1] - 10.0
    f_sel = flight["t_s"] >= t_late
    r_sel = res.t >= t_late
    assert np.sum(f_sel) == np.sum(r_sel) > 5
    assert np.max(np.abs(flight["innovation"][f_sel] - res.innovation[r_sel])) < 5e-3


def test_chained_runs_are_split_into_segments():
    log, _ = reality.simulate_log_with_key(11, {}, duration_s=DURATION_S)
    d = prepare(log)
    runs = reality.simulate_runs(11, None, DURATION_S)
    assert int(d.pose_start.sum()) == len(runs)


def test_null_log_gives_no_gap(calibration):
    r = public(diagnose(_log(4242, {}), calibration=calibration))
    assert r["gap_detected"] is False
    assert r["verdict"] == "no_gap"


def test_accel_bias_detected_attributed_and_fitted(calibration):
    bias = np.array([8e-4, -6e-4, 4e-4])
    r = public(diagnose(_log(77, {"accel_bias": bias}), calibration=calibration))
    assert r["gap_detected"]
    assert r["attribution"][0]["effect"] == "accel_bias"
    assert r["verdict"] in ("explained", "ambiguous")
    assert r["shrink_heldout"]["fraction"] > 0.5
    fitted = np.array([p["value"] for p in r["attribution"][0]["parameters"].values()])
    assert np.max(np.abs(fitted - bias)) < 1.5e-4


def test_thrust_loss_seen_through_the_dynamics_channel(calibration):
    loss = np.array([0.05, 0.2, 0.1, 0.15, 0.02, 0.12, 0.18, 0.08])
    r = public(diagnose(_log(78, {"thrust_loss": loss}), calibration=calibration))
    assert r["gap_detected"]
    assert r["attribution"][0]["effect"] == "thrust_loss"
    assert r["shrink_heldout"]["fraction"] > 0.8
    fitted = np.array([p["value"] for p in r["attribution"][0]["parameters"].values()])
    assert np.max(np.abs(fitted - loss)) < 0.03


def test_ci_sized_blind_campaign_runs_end_to_end(tmp_path, capsys):
    out = tmp_path / "vg.json"
    res = run_campaign(4, seed=3, out=str(out), workers=1, duration_s=40.0, progress=False)
    assert (tmp_path / "vg.json.prereg.json").exists()
    assert res["keys_match_preregistration"]
    assert res["runs"] == 4 and len(res["answers"]) == 4
    assert sum(sum(v.values()) for v in res["confusion"].values()) == 4
    assert all(a["verdict"] in ("no_gap", "explained", "ambiguous", "unexplained") for a in res["answers"])
    drawn = [k for k in res["keys"] if k["effect"] is not None]
    for k in drawn:  # each effect drawn at scale x its run's minimum detectable size, or scored apart
        if k["detectable"]:
            from bench.sim.effects import EFFECTS

            spec = EFFECTS[k["effect"]]
            assert spec.size(k["effects"][k["effect"]]) == pytest.approx(k["scale"] * k["min_detectable"], rel=1e-9)
            assert k["lambda_at_min_detectable"] >= k["lambda_required"]
    for k, a in zip(res["keys"], res["answers"]):  # scored for separability after the answer
        assert ("separability" in a) == (k["effect"] is not None)
    # The campaign records' tables (docs/results/) render from the full JSON.
    import json

    from bench.campaigns.gap import results_tables
    from bench.report import write_json

    write_json(str(out), res, strict=True)  # what validate-gap writes: strict JSON
    json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(f"bare {c} in the JSON"))
    assert results_tables.main([str(out)]) == 0
    md = capsys.readouterr().out
    assert "| false alarms on null runs |" in md and "### Per in-library effect" in md
    assert "### Held-out shrink by effect" in md


def test_required_noncentrality_gives_the_power_in_a_seeded_draw():
    from scipy.stats import chi2

    from bench.campaigns.gap.detectable import required_noncentrality

    rng = np.random.default_rng(5)
    for k in (1, 3, 16):
        c = float(chi2.isf(1e-4, k))
        lam = required_noncentrality(k, c, 0.95)
        # A noncentral chi-square(k, lam): |z + m|^2 with |m|^2 = lam.
        z = rng.standard_normal((40000, k))
        z[:, 0] += np.sqrt(lam)
        frac = np.mean(np.sum(z**2, axis=1) > c)
        assert abs(frac - 0.95) < 4 * np.sqrt(0.95 * 0.05 / 40000), (k, frac)


def test_min_detectable_size_puts_the_signature_at_the_required_noncentrality(calibration):
    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS

    spec = EFFECTS["accel_bias"]
    unit = spec.draw_fn(np.random.default_rng(2), 1.0)
    md = min_detectable_size(31, "accel_bias", unit, 60.0, calibration)
    assert md["detectable"] and md["k"] == 3
    # The answer is a probed size whose own closed-loop run reaches the required noncentrality.
    assert md["size"] in [p["size"] for p in md["probes"]]
    assert md["lambda_at_size"] >= md["lambda_required"]
    # A linear effect: the last probe sits at the answer and its lambda at the target.
    last = md["probes"][-1]
    assert last["size"] == pytest.approx(md["size"], rel=0.05)
    assert last["lambda"] == pytest.approx(md["lambda_required"], rel=0.10)
    # Twice the size, four times the noncentrality (lambda ~ size^2).
    first = md["probes"][0]
    assert first["lambda"] / last["lambda"] == pytest.approx((first["size"] / last["size"]) ** 2, rel=0.25)


def test_an_effect_no_sensible_size_shows_is_reported_not_detectable(calibration):
    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS

    # A 0.75 m docking at mm/s holds range nearly still: host eccentricity up to
    # 0.05 moves the relative orbit by far less than the pose noise in 60 s.
    spec = EFFECTS["host_eccentricity"]
    md = min_detectable_size(31, "host_eccentricity", spec.draw_fn(np.random.default_rng(2), 1.0), 60.0, calibration)
    assert not md["detectable"] and np.isnan(md["size"])


def test_gyro_unwhitening_inverts_the_whitening():
    from bench.gap import dyn

    d = prepare(_log(12, {}))
    ch = dyn.build(d)
    g = ch.kind == 1
    w = np.random.default_rng(0).standard_normal((int(g.sum()), 3))
    assert np.allclose(ch.whiten_gyro(ch.unwhiten_gyro(w)), w, atol=1e-12)


def test_bundled_reality_run_is_diagnosed_blind(calibration):
    from bench.gap import bundled
    from bench.sim.flight_log import read_flight_log

    log = read_flight_log(bundled.LOG)
    assert "truth" not in log.streams and "effects" not in (log.config or {})
    r = public(diagnose(log, calibration=calibration))
    key = bundled.sealed_key()
    (truth,) = key["effects"]
    # A docking log cannot rule out a nozzle tilt beside the loss (the loss
    # of the same valves absorbs it): ambiguous, the tilt named as possible.
    assert r["gap_detected"] and r["verdict"] == "ambiguous"
    assert r["attribution"][0]["effect"] == truth
    assert [(a["set"], a["add"]) for a in r["ambiguous_with"]] == [
        ([truth, "thruster_misalignment"], "thruster_misalignment")
    ]
    assert r["location"]["effect_acts_while"]["peak"] == "firing"
    assert r["shrink_heldout"]["fraction"] >= 0.8


def test_a_chained_log_reports_the_shrink_on_held_out_runs(calibration):
    log, _ = reality.simulate_log_with_key(
        5, {"thrust_loss": [0.02, 0.02, 0.02, 0, 0, 0, 0, 0]}, duration_s=400.0, with_truth=False
    )
    r = public(diagnose(blind(log), calibration=calibration))
    runs = r["shrink_heldout_runs"]
    assert runs["runs"] >= 2 and runs["heldout_runs"] >= 1
    assert r["attribution"][0]["effect"] == "thrust_loss"
    # Fitted on the even runs only, the effect closes the gap on the odd ones.
    assert runs["measurable"] and runs["fraction"] >= 0.8 and runs["ci95"][0] > 0.5
    # Losses on the three faulty valves, none on the others (2 mm/s^2 of 6.7 is 0.02 +- 0.01).
    loss = np.array(list(runs["parameters"].values()))
    assert np.all(np.abs(loss[:3] - 0.02) < 0.012) and np.all(np.abs(loss[3:]) < 0.012)


def test_a_single_run_log_says_why_there_is_no_held_out_run_shrink(calibration):
    log = _log(5, {"accel_bias": [4e-4, -3e-4, 2e-4]})
    assert np.all(np.diff(log["imu"]["t_s"]) < 0.15)  # one approach, 120 s long
    r = public(diagnose(log, calibration=calibration))
    assert r["gap_detected"]
    assert r["shrink_heldout_runs"]["fraction"] is None and "one run" in r["shrink_heldout_runs"]["reason"]


def test_proxops_run_ends_with_the_three_answers_then_the_sealed_key(tmp_path, capsys):
    from bench.commands.run import diagnose_bundled

    assert diagnose_bundled(tmp_path / "gap") == 0
    out = capsys.readouterr().out
    where, which, how_far, key = (out.index(s) for s in ("where:", "which:", "how far:", "sealed key"))
    assert where < which < how_far < key  # the key is opened only after the answers
    assert "thrust_loss (ambiguous; cannot be told from: thrust_loss + thruster_misalignment)" in out
    assert (tmp_path / "gap" / "README.md").exists() and (tmp_path / "gap" / "diagnosis.json").exists()


def test_a_nozzle_tilt_in_a_docking_run_is_not_separable_from_thrust_loss():
    from bench.campaigns.gap.separability import DELTA2_95, separability

    # Fixed couples: the gyro sees a small tilt's torque as a valve's lost torque.
    tilt = np.zeros(24)
    tilt[[1, 5, 13, 20]] = [0.006, -0.0045, 0.006, 0.0045]
    s = separability(31, "thruster_misalignment", {"thruster_misalignment": tilt.tolist()}, 60.0, True)
    assert s["lambda"] > 30.0  # detectable...
    assert s["closest"] == "thrust_loss" and s["delta2_min"] < DELTA2_95 and not s["separable"]  # ...not attributable
    # An accelerometer bias is nothing like any other candidate's signature.
    b = separability(31, "accel_bias", {"accel_bias": [4e-4, -3e-4, 2e-4]}, 60.0, True)
    assert b["separable"] and b["delta2_min"] > 0.5 * b["lambda"]


def test_single_valve_characterisation_separates_thrust_loss_that_docking_cannot():
    from bench.campaigns.gap.characterise import compare
    from bench.campaigns.gap.separability import DELTA2_95
    from bench.sim.plans import single_valve_scripts

    scripts = single_valve_scripts(fire_s=3.0, coast_s=20.0)
    assert len(scripts) == 8
    for i, s in enumerate(scripts):  # closed, valve i alone for 3 s, closed for 20 s
        assert s[:20] == [0] * 20 and s[20:50] == [1 << i] * 30 and s[50:] == [0] * 200
    r = compare(1, "thrust_loss", 0.0069, fire_s=3.0, coast_s=20.0)
    dock, char = r["docking"], r["characterisation"]
    # Docking: detectable (lambda well above the screen's ~37) but a nozzle
    # tilt set reproduces the losses; held through a coast, a loss's rate
    # change along the valve's torque is nothing a tilt can give.
    assert dock["lambda"] > 37.0 and dock["closest"] == "thruster_misalignment"
    assert dock["delta2"] < DELTA2_95 and dock["fraction"] < 0.1
    # Each valve fires once: the split gives every valve's firing to both
    # halves (quantify.excitation_split, 16 blocks), so the training rows
    # hold half of each firing and its coast. The loss separates from a
    # tilt there at 0.0070, a third of what docking needs (0.020).
    assert char["fraction"] > 0.5 and char["delta2"] > 8.0 * dock["delta2"]
    assert char["size_to_separate"] < 0.4 * dock["size_to_separate"]


def test_deficit_cells_keep_only_where_the_training_gap_lies():
    from bench.gap import quantify

    rng = np.random.default_rng(4)
    n_nav, n_acc, seg_len = 60, 600, 10
    nis_train = rng.chisquare(6, n_nav)  # null
    lab = np.r_[
        np.full(n_acc, quantify.CELL_ACCEL_COAST),
        np.full(n_acc, quantify.CELL_ACCEL_FIRE),
        np.full(n_acc, quantify.CELL_GYRO),
    ]
    seg = np.arange(lab.size) // seg_len
    gap = np.where(lab == quantify.CELL_ACCEL_FIRE, 0.3, 0.0)[:, None] * np.ones(3)  # a slow gap while firing
    e = rng.standard_normal((lab.size, 3)) + gap
    assert quantify.gap_cells(nis_train, e, lab, seg) == [quantify.CELL_ACCEL_FIRE]
    # Held out: the same gap; a fix that removes it shrinks the cell's deficit by
    # about all of it, and the null rows elsewhere add no noise to that.
    e_held = rng.standard_normal((lab.size, 3)) + gap
    e_fixed = e_held - gap
    t = np.arange(lab.size) * 0.1
    nis_h = rng.chisquare(6, n_nav)
    sh = quantify.shrink_combined(
        t[:n_nav], nis_h, nis_h, t, e_held, e_fixed, cells=[quantify.CELL_ACCEL_FIRE], lab_dyn=lab, seg_dyn=seg
    )
    n_seg = n_acc // seg_len
    assert sh["deficit_null_sd"] == pytest.approx(np.sqrt(0.5 * 3 * n_seg))
    assert sh["measurable"] and sh["fraction"] == pytest.approx(1.0, abs=0.3)
    assert sh["cells"] == ["accelerometer, firing"]
    # Row by row the same gap has the same deficit (81) but a null spread of
    # 30 instead of 9.5: the segments' means keep the gap and drop the noise.
    rows = quantify.shrink_combined(
        t[:n_nav], nis_h, nis_h, t, e_held, e_fixed, cells=[quantify.CELL_ACCEL_FIRE], lab_dyn=lab
    )
    assert rows["deficit_null_sd"] == pytest.approx(np.sqrt(0.5 * 3 * n_acc))
    z_seg = sh["deficit_before"] / sh["deficit_null_sd"]
    assert z_seg > 2.0 * rows["deficit_before"] / rows["deficit_null_sd"]


def test_segments_cut_at_valve_changes_runs_and_windows():
    from types import SimpleNamespace

    from bench.gap import quantify

    dt, n = 0.05, 100  # 5 s at 20 Hz
    t_acc = np.arange(n) * dt
    t_acc[60:] += 1.0  # a second run after a break
    open_ = np.zeros((n, 2))
    open_[10:14, 0] = 1.0
    open_[14:16, 1] = 0.5
    k = np.r_[np.arange(1, 60), np.arange(61, n)]
    ch = SimpleNamespace(
        open_=open_,
        W=np.zeros((k.size, 2)),
        rows=n + k.size,
        t=np.r_[t_acc, t_acc[k]],
        kind=np.r_[np.zeros(n, int), np.ones(k.size, int)],
        dt=dt,
        seg_bounds=[(0, 59), (59, k.size)],
    )
    seg = quantify.dyn_segments(ch)
    acc, gyro = seg[:n], seg[n:]
    assert len(np.unique(acc[10:14])) == 1 and acc[9] != acc[10] and acc[14] != acc[13] and acc[16] != acc[15]
    assert acc[59] != acc[60]  # a new run
    assert np.all(np.diff(t_acc[acc == acc[30]]) < quantify.SEGMENT_S)
    assert set(acc) & set(gyro) == set()
    assert gyro[57] != gyro[59]  # the runs' whitening bounds
    # The rows of every segment lie inside one SEGMENT_S window.
    for s_ in np.unique(seg):
        ts = ch.t[seg == s_]
        assert ts.max() - ts.min() < quantify.SEGMENT_S


def test_signature_distance_is_zero_inside_the_other_span_and_full_outside():
    from bench.gap.attribute import Fit
    from bench.gap.candidates import CANDIDATES
    from bench.gap.verdict import signature_distance

    rng = np.random.default_rng(1)
    Jb = rng.standard_normal((200, 3))
    a_in = Fit("gyro_bias", "sensor", np.array([CANDIDATES["gyro_bias"].scale]), np.zeros(1), 0.0, 0.0)
    a_in.J_u = Jb @ np.array([[1.0], [2.0], [0.5]])  # inside b's span
    b = Fit("accel_bias", "sensor", np.zeros(3), np.zeros(3), 0.0, 0.0)
    b.J_u = Jb
    assert signature_distance(a_in, b) == pytest.approx(0.0, abs=1e-9)
    a_out = Fit("gyro_bias", "sensor", np.array([CANDIDATES["gyro_bias"].scale]), np.zeros(1), 0.0, 0.0)
    v = rng.standard_normal(200)
    v -= Jb @ np.linalg.lstsq(Jb, v, rcond=None)[0]  # orthogonal to b's span
    a_out.J_u = v[:, None]
    assert signature_distance(a_out, b) == pytest.approx(float(v @ v), rel=1e-9)


def test_a_thrust_gain_is_no_thrust_loss():
    from bench.gap.attribute import Fit, bound_excess
    from bench.gap.candidates import CANDIDATES
    from bench.gap.verdict import signature_distance

    loss = CANDIDATES["thrust_loss"]
    assert loss.nonnegative and loss.lower == 0.0 and CANDIDATES["gyro_bias"].lower == -CANDIDATES["gyro_bias"].bound
    rng = np.random.default_rng(2)
    Jb = np.linalg.qr(rng.standard_normal((300, 8)))[0] * np.arange(1.0, 9.0)  # each valve its own direction
    b = Fit("thrust_loss", "dynamics", np.zeros(8), np.zeros(8), 0.0, 0.0)
    b.J_u = Jb
    theta = np.array([0.5, 0.2, 0.0, 0.0, 0.3, 0.0, 0.1, 0.0])  # losses, in units of the candidate's scale
    a = Fit("gyro_bias", "sensor", np.array([CANDIDATES["gyro_bias"].scale]), np.zeros(1), 0.0, 0.0)
    a.J_u = (Jb @ theta)[:, None]  # the signature of these losses
    assert signature_distance(a, b) == pytest.approx(0.0, abs=1e-9)
    a.J_u = -a.J_u  # the same valves gaining thrust: no loss reproduces any of it
    assert signature_distance(a, b) == pytest.approx(float(theta @ Jb.T @ Jb @ theta), rel=1e-9)
    # A fit that wants a negative loss lies beyond the lower bound, in its sigmas.
    assert bound_excess(np.array([0.01, -0.03]), np.array([0.01, 0.01]), 0.9, 0.0) == pytest.approx(3.0)
    assert bound_excess(np.array([0.01, -0.03]), np.array([0.01, 0.01]), 0.9) == 0.0


def test_half_cauchy_prior_doubles_the_density_and_a_parameter_held_at_zero_keeps_half_its_mass():
    from bench.gap.attribute import ln_bayes_factor

    J = np.diag([3.0, 2.0, 4.0])
    u = np.array([0.4, 0.7, 1.1])
    free = ln_bayes_factor(10.0, u, J)
    assert ln_bayes_factor(10.0, u, J, nonnegative=True) == pytest.approx(free + 3 * np.log(2.0))
    u0 = np.array([0.4, 0.0, 1.1])
    assert ln_bayes_factor(10.0, u0, J, nonnegative=True) == pytest.approx(
        ln_bayes_factor(10.0, u0, J) + 2 * np.log(2.0)
    )


def test_a_characterisation_flown_after_docking_is_replayed_run_for_run():
    from bench.sim.plans import single_valve_scripts

    then = single_valve_scripts(fire_s=1.0, coast_s=2.0)
    runs = reality.simulate_runs(12, {"thrust_loss": [0.0, 0.1, 0, 0, 0, 0, 0, 0]}, 20.0, then_scripts=then)
    n_dock = len(runs) - len(then)
    assert n_dock >= 1 and sum(r.summary.t_end_s for r in runs[:n_dock]) >= 20.0 - 0.1 * n_dock - 1e-9
    for r, sc in zip(runs[n_dock:], then):  # each valve alone, then closed, one run each
        assert list(r.config) == sc
    # Replayed open loop without the effect: the same runs, the same valves.
    again = reality.simulate_runs(12, {}, 20.0, scripts=[r.config for r in runs], then_scripts=then)
    assert len(again) == len(runs)
    assert all(np.array_equal(a.config, r.config) for a, r in zip(again, runs))


def test_a_campaign_with_the_characterisation_records_it_in_every_key():
    from bench.campaigns.gap.validate import draw_campaign, key_hash, then_scripts

    dock, char = draw_campaign(20, 5), draw_campaign(20, 5, "docking+characterisation")
    assert all("manoeuvres" not in k and then_scripts(k) is None for k in dock)
    assert all(k["manoeuvres"] == "docking+characterisation" and len(then_scripts(k)) == 8 for k in char)
    assert [key_hash(k) for k in dock] != [key_hash(k) for k in char]
    with pytest.raises(ValueError, match="manoeuvres"):
        draw_campaign(5, 5, "slalom")


def test_a_fit_that_buys_one_channel_with_another_is_a_contradiction():
    from bench.gap.quantify import channel_gain
    from bench.gap.verdict import Z_CONTRADICT

    rng = np.random.default_rng(8)
    n = rng.standard_normal(3000)
    sig = np.zeros(3000)
    sig[:300] = 0.4  # the channel's data carry this
    # The right correction removes what is there: the channel gains ~ |sig|^2 / 2.
    right = channel_gain(n + sig, n)
    assert right["gain"] == pytest.approx(0.5 * sig @ sig, abs=4 * np.sqrt(sig @ sig))
    assert right["z"] > 3.0
    # A correction where the data show nothing costs ~ q / 2: z ~ -sqrt(q) / 2.
    wrong = channel_gain(n, n - sig)
    assert wrong["q"] == pytest.approx(sig @ sig)
    assert wrong["z"] < -Z_CONTRADICT
    # Fitted noise alone (a small correction along the noise) never counts against a channel.
    fit_noise = channel_gain(n, n - 0.05 * n)
    assert fit_noise["z"] > 0.0
    assert channel_gain(n, n)["z"] == 0.0


def test_each_kind_of_log_has_a_null_calibration_made_on_its_own_manoeuvres():
    dock = nullmod.load(manoeuvres="docking")
    char = nullmod.load(manoeuvres="docking+characterisation")
    assert dock == nullmod.load()
    assert char["manoeuvres"] == "docking+characterisation" and char["runs"] >= 1000
    assert "--manoeuvres docking+characterisation" in char["command"]
    for cal in (dock, char):  # each threshold leaves about FA_EACH of its own null runs above it
        for stat, key in (("map_max_abs_z", "null_map_max_abs_z"), ("screen_logp", "null_screen_logp")):
            above = np.mean(np.asarray(cal[key]) > cal["thresholds"][stat])
            assert above <= 2 * nullmod.FA_EACH
        assert cal["false_alarm_rate"] <= 0.02


def test_the_latency_candidate_reproduces_latency_through_spins_and_run_ends():
    # Each single-valve run ends spinning; the next starts at rest. The
    # candidate must turn a run's last pose by that run's rate.
    from bench.campaigns.gap.detectable import residuals_of
    from bench.gap.attribute import signature
    from bench.sim.plans import single_valve_scripts

    then = single_valve_scripts(fire_s=3.0, coast_s=6.0)
    tau = 0.1
    runs1 = reality.simulate_runs(4, {"camera_latency": [tau]}, 30.0, then_scripts=then)
    scripts = [r.config for r in runs1]
    runs0 = reality.simulate_runs(4, {}, 30.0, scripts=scripts, then_scripts=then)
    cfg = reality.log_config(4, 30.0)
    ctx0, e0, rows_ok = residuals_of(reality.runs_to_log(runs0, cfg, 1.0, with_truth=False))
    _, w, e_dyn = residuals_of(reality.runs_to_log(runs1, cfg, 1.0, with_truth=False), ctx0)
    s = np.concatenate([w[rows_ok].ravel(), e_dyn]) - e0  # the effect's whitened signature
    J = signature(ctx0, "camera_latency", rows_ok)[0]
    theta = np.linalg.lstsq(-J, s, rcond=None)[0]
    left = s + J @ theta
    assert s @ s > 50.0  # the spins show it
    assert theta[0] == pytest.approx(tau, rel=0.05)
    assert left @ left < 0.05 * (s @ s)


def test_bootstrap_interval_of_a_median_narrows_with_more_runs_and_holds_the_median():
    from bench.campaigns.gap.results_tables import median_interval

    rng = np.random.default_rng(3)
    small, large = rng.normal(0.8, 0.3, 40), rng.normal(0.8, 0.3, 1000)
    lo_s, hi_s = median_interval(small)
    lo_l, hi_l = median_interval(large)
    assert lo_s < np.median(small) < hi_s and lo_l < np.median(large) < hi_l
    assert (hi_l - lo_l) < 0.4 * (hi_s - lo_s)  # about sqrt(40 / 1000) = 0.2 as wide
    assert median_interval(small) == (lo_s, hi_s)  # seeded
    assert median_interval(np.array([0.7])) == (0.7, 0.7)  # one run: every resample is it
    assert median_interval(np.array([0.7, 0.7, 0.7])) == (0.7, 0.7)


def test_the_clock_candidate_undoes_a_drifting_flight_clock():
    """A flight clock fast by eps on a docking-then-characterisation log: the
    candidate's closed-form correction takes the drift's change of the
    dynamics channel away, and the diagnosis names clock_drift alone with eps inside its
    interval; the same valves flown without the drift give no gap and an
    eps fit within its noise."""
    from bench.campaigns.gap.detectable import _bench_simulate
    from bench.gap import dyn
    from bench.gap.attribute import candidate
    from bench.sim.plans import then_scripts

    key = {"manoeuvres": "docking+characterisation"}
    eps = 0.01  # four times its minimum detectable size in these logs
    simulate = _bench_simulate(21, DURATION_S, then_scripts(key))
    drifted, scripts = simulate({"clock_drift": [eps]})
    null, _ = simulate({}, scripts)  # the same valves and noise, no drift
    ch1, ch0 = dyn.build(prepare(drifted)), dyn.build(prepare(null))
    # The gyro rows' noise model is taken at each log's own stamps and rates
    # (dyn.gyro_whiteners); compare the model on one of them.
    ch1.chol = ch0.chol
    ch1.e0 = ch1.residual()
    change = ch1.e0 - ch0.e0
    # The candidate's correction at eps (e0 + J eps) takes the change away.
    correction = eps * ch0.jacobian("clock_drift")[..., 0]
    gyro = ch0.kind == 1
    assert np.sum(change[gyro] ** 2) > 100.0  # the drift shows on the gyro rows
    assert np.sum((change + correction)[gyro] ** 2) < 1e-6 * np.sum(change[gyro] ** 2)
    assert np.sum(change[~gyro] ** 2) < 1e-6 * np.sum(change[gyro] ** 2)  # and not on the accelerometer's
    assert candidate(prepare(null), "clock_drift").bound == 0.05

    cal = nullmod.load(manoeuvres=key["manoeuvres"])
    r = public(diagnose(blind(drifted), calibration=cal))
    assert [m["effect"] for m in r["effects"]] == ["clock_drift"]
    # To first order a drifting clock is one gyro scale on every axis and one
    # thrust scale on every valve: that pair is listed beside the answer.
    assert r["verdict"] == "ambiguous" and ["gyro_scale", "thrust_loss"] in [
        sorted(a["set"]) for a in r["ambiguous_with"]
    ]
    p = r["effects"][0]["parameters"]["eps [1]"]
    assert abs(p["value"] - eps) < 2.0 * p["sigma"] and p["sigma"] < 0.1 * eps

    res = diagnose(blind(null), calibration=cal)
    assert public(res)["verdict"] == "no_gap"
    fit = next(f for f in res["_internal"]["fits"] if f.name == "clock_drift")
    assert abs(fit.theta[0]) < 3.0 * fit.sigma[0] and fit.sigma[0] < 0.1 * eps


def test_diagnosis_progress_is_whole_lines_off_a_terminal(calibration, capsys, monkeypatch):
    # Asked for in a log file (not a terminal): whole lines of replays done,
    # no carriage returns; not asked for: nothing.
    log = _log(3, {})
    monkeypatch.setenv("PROXOPS_PROGRESS", "1")
    diagnose(log, calibration=calibration, progress=True)
    err = capsys.readouterr().err
    assert "diagnose" in err and "replay" in err and "\r" not in err
    monkeypatch.delenv("PROXOPS_PROGRESS")
    diagnose(log, calibration=calibration, progress=True)
    assert capsys.readouterr().err == ""
