"""Gap diagnosis (bench/gap): replay, detection against the committed null
calibration, attribution, held-out shrink, and a CI-sized blind campaign."""
import numpy as np
import pytest

from bench.gap import null as nullmod
from bench.gap.diagnose import diagnose, public
from bench.gap.replay import prepare, reference
from bench.gap.validate import blind, run_campaign

reality = pytest.importorskip("bench.reality")

DURATION_S = 120.0


def _log(seed, effects):
    log, _ = reality.simulate_log_with_key(seed, effects, duration_s=DURATION_S, with_truth=False)
    return blind(log)


@pytest.fixture(scope="module")
def calibration():
    cal = nullmod.load()
    assert cal, "bench/gap/data/null_calibration.json missing (python -m bench.gap.null)"
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


def test_ci_sized_blind_campaign_runs_end_to_end(tmp_path):
    out = tmp_path / "vg.json"
    res = run_campaign(4, seed=3, out=str(out), workers=1, duration_s=40.0, progress=False)
    assert (tmp_path / "vg.json.prereg.json").exists()
    assert res["keys_match_preregistration"]
    assert res["runs"] == 4 and len(res["answers"]) == 4
    assert sum(sum(v.values()) for v in res["confusion"].values()) == 4
    assert all(a["verdict"] in ("no_gap", "explained", "ambiguous", "unexplained") for a in res["answers"])
