"""The diagnosis of a user's own log: the vehicle it describes, time stamps
as real logs have them, pulse-width-modulated valves, a calibration that
must hold for the log, and answers that say what was examined."""

import copy
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.gap import bundled, log_null
from bench.gap import null as nullmod
from bench.gap.answers import answer_lines
from bench.gap.diagnose import diagnose, public
from bench.gap.load import prepare
from bench.sim.flight_log import read_flight_log

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bundled_log():
    return read_flight_log(bundled.LOG)


@pytest.fixture(scope="module")
def calibration():
    return nullmod.load()


def _answer(log, cal):
    return public(diagnose(log, calibration=cal))


@pytest.fixture(scope="module")
def bundled_answer(bundled_log, calibration):
    return _gist(_answer(bundled_log, calibration))


def _gist(r) -> tuple:
    """The answer's verdict, its first effect and the sets it cannot rule out."""
    return r["verdict"], r["attribution"][0]["effect"], [a.get("set", [a.get("effect")]) for a in r["ambiguous_with"]]


@pytest.mark.parametrize("how", ["shift_1us", "float32", "jitter"])
def test_time_stamps_as_real_logs_have_them_keep_the_answer(bundled_log, calibration, bundled_answer, how):
    log = copy.deepcopy(bundled_log)
    t = log["imu"]["t_s"]
    if how == "shift_1us":
        log["imu"]["t_s"] = t - 1e-6
    elif how == "float32":
        log["imu"]["t_s"] = t.astype(np.float32).astype(np.float64)
    else:
        log["imu"]["t_s"] = t + np.random.default_rng(1).uniform(-0.004, 0.004, t.size)
    r = _answer(log, calibration)
    assert _gist(r) == bundled_answer and bundled_answer[1] == "thrust_loss"


def test_pose_captures_between_imu_ticks_are_all_used(bundled_log, calibration, bundled_answer):
    base = prepare(bundled_log)
    log = copy.deepcopy(bundled_log)
    log["pose"]["t_capture_s"] = log["pose"]["t_capture_s"] + 0.003
    log["pose"]["t_delivered_s"] = log["pose"]["t_delivered_s"] + 0.003
    d = prepare(log)
    assert d.pose_tc.size == base.pose_tc.size  # none dropped
    assert np.allclose(d.pose_align_s, -0.003)  # each moved back to its tick
    r = _answer(log, calibration)
    assert _gist(r) == bundled_answer and bundled_answer[1] == "thrust_loss"
    assert r["log"]["pose_updates"] == base.pose_tc.size


def test_a_log_without_valves_says_the_dynamics_were_not_examined(bundled_log, calibration):
    log = copy.deepcopy(bundled_log)
    del log.streams["valves"]
    r = _answer(log, calibration)
    ex = r["examined"]
    assert not ex["channels"]["accelerometer vs valves"]["examined"]
    assert any(x.startswith("dynamics") and "no valves stream" in x for x in ex["not_examined"])
    text = "\n".join(t for _, t in answer_lines(r))
    assert "not examined: accelerometer vs valves" in text and "no valves stream" in text


def test_unexplained_prints_no_shrink_and_nothing_not_finite(bundled_log, calibration):
    r = _answer(bundled_log, calibration)
    fake = copy.deepcopy(r)
    fake["verdict"] = "unexplained"
    text = "\n".join(t for _, t in answer_lines(fake))
    assert "no shrink to report" in text and "%" not in text.split("how far")[-1].split("examined")[0]
    fake = copy.deepcopy(r)
    fake["attribution"][0]["shrink_heldout"].update(fraction=float("nan"), measurable=False)
    text = "\n".join(t for _, t in answer_lines(fake))
    assert "nan" not in text and "not measurable" in text


def test_one_where_for_cli_json_and_report(bundled_log, calibration, tmp_path):
    from bench.gap.report import write_report

    res = diagnose(bundled_log, calibration=calibration)
    page = write_report(res, tmp_path, "bundled").read_text()
    where = [t for lab, t in answer_lines(public(res)) if lab == "where"][0]
    assert where in page
    assert "strongest while" not in page or "acts mostly" not in page
    # a dynamics-only effect: the figure and RMS lines show the accelerometer and gyro, before and after
    assert "accelerometer and gyro against the valve model" in page
    rms = [ln for ln in page.splitlines() if ln.startswith("RMS on held-out rows")][0]
    assert (
        "->" in rms
        and rms.split("accel x ")[1].split(" -> ")[0] != rms.split("accel x ")[1].split(" -> ")[1].split(",")[0]
    )


def test_defaults_taken_are_named(bundled_log, calibration):
    r = _answer(bundled_log, calibration)
    named = " ".join(r["examined"]["defaults_used"])
    assert "vehicle.thrusters" in named and "segments" in named


def test_a_calibration_for_another_vehicle_is_refused(calibration):
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import simulate
    from bench.sim.vehicles import inspector_12kg

    desc = inspector_12kg()
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=4, per_run=12, fire_s=0.5, coast_s=1.0, passes=1),
        {},
        seed=4,
        with_truth=False,
    )
    with pytest.raises(log_null.CalibrationMismatch, match="made for the bench's 3 kg inspector.*12 thrusters"):
        diagnose(log, calibration=calibration, calibration_source="docking.json")


def test_stated_manoeuvres_must_match_the_calibration(bundled_log, calibration):
    log = copy.deepcopy(bundled_log)
    t = log["imu"]["t_s"]
    log.description = {
        "segments": [{"t_start_s": float(t[0] - 0.1), "t_end_s": float(t[-1]), "manoeuvre": "characterisation"}]
    }
    with pytest.raises(
        log_null.CalibrationMismatch, match="made for logs that fly docking; this log flies characterisation"
    ):
        diagnose(log, calibration=calibration, calibration_source="docking.json")


def test_a_calibration_made_for_the_log_is_cached(tmp_path):
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import simulate
    from bench.sim.vehicles import inspector_12kg

    desc = inspector_12kg()
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=6, per_run=12, fire_s=0.5, coast_s=1.0, passes=1),
        {},
        seed=6,
        with_truth=False,
    )
    cal = log_null.calibrate_for_log(log, runs=10, seed=3, workers=2, cache_dir=tmp_path, progress=False)
    assert cal["runs"] == 10 and cal["from_cache"] is None and np.all(np.isfinite(list(cal["thresholds"].values())))
    again = log_null.calibrate_for_log(log, runs=10, seed=3, workers=2, cache_dir=tmp_path, progress=False)
    assert again["from_cache"] and again["thresholds"] == cal["thresholds"]
    # it holds for this log and is refused for another
    log_null.check_supplied(again, log, prepare(log), "cal.json")
    other = copy.deepcopy(log)
    other["valves"]["on_time_s"][3, 0] += 0.01
    with pytest.raises(log_null.CalibrationMismatch, match="on-times more than 5 ms apart"):
        log_null.check_supplied(again, other, prepare(other), "cal.json")


def test_the_example_writes_a_log_a_user_would(tmp_path):
    out = tmp_path / "user.h5"
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "write_flight_log.py"), str(out)],
        check=True,
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    # it says what takes the time before it starts, and what it wrote at the end
    assert done.stderr.startswith("simulating a 12 kg inspector") and "simulated in" in done.stderr
    assert done.stdout.startswith(f"wrote {out}")
    log = read_flight_log(out)
    d = prepare(log)
    assert d.desc.n_thrusters == 12 and d.desc.imu_rate_hz == 20.0
    assert d.valves.shape[1] == 12 and 0.0 < d.valves.max() < 1.0  # pulse-width modulated
    assert not d.dropped  # every pose on a tick of its own run


def test_cli_refuses_bad_calibration_and_outputs_without_touching_files(tmp_path, capsys):
    from bench.cli import main

    out = tmp_path / "d.json"
    out.write_text("earlier answer\n")
    rc = main(
        ["diagnose", str(bundled.LOG), "--json", str(out), "--calibration", str(tmp_path / "typo.json"), "--quiet"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "typo.json: no such file" in err[0]
    bad = tmp_path / "bad.json"
    bad.write_text('{"runs": 3}')
    rc = main(["diagnose", str(bundled.LOG), "--json", str(out), "--calibration", str(bad), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "thresholds.map_max_abs_z missing" in err[0]
    rc = main(["diagnose", str(bundled.LOG), "--json", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and "is a folder" in err[0]
    assert out.read_text() == "earlier answer\n"


def test_cli_writes_the_answer_with_its_calibration_and_what_it_examined(tmp_path, capsys):
    from bench.cli import main

    out = tmp_path / "d.json"
    assert main(["diagnose", str(bundled.LOG), "--json", str(out), "--report", str(tmp_path / "rep"), "--quiet"]) == 0
    r = json.loads(out.read_text())
    assert r["calibration"]["source"].startswith("committed") and r["examined"]["channels"]["pose"]["examined"]
    assert (tmp_path / "rep" / "README.md").exists() and (tmp_path / "rep" / "residuals.png").exists()
    text = capsys.readouterr().out
    assert "which:" in text and "thrust_loss" in text and "examined:" in text


def test_cli_json_is_strict_and_can_go_to_stdout(capsys):
    from bench.cli import main

    assert main(["diagnose", str(bundled.LOG), "--json", "-", "--quiet"]) == 0
    text = capsys.readouterr().out
    r = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in the JSON"))
    assert r["verdict"] == "ambiguous" and r["attribution"][0]["effect"] == "thrust_loss"
