"""A null calibration given with `proxops diagnose --calibration FILE` is
checked before its thresholds are trusted: an empty object, a threshold
that is missing, NaN or raised above what the file's own null runs give,
a calibration of another code version or of the wrong shape is refused
with one line naming the field (exit 2), never turned into "no gap"."""

from __future__ import annotations

import copy
import json

import pytest

from bench import cli
from bench.gap import bundled, log_null, null
from bench.gap.calibration_file import problem

COMMITTED = [
    null.DATA,
    null.DATA_BY_MANOEUVRES["docking+characterisation"],
    null.DATA.with_name("null_calibration_12kg.json"),
]


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: p.name)
def test_the_committed_calibrations_hold(path):
    assert problem(json.loads(path.read_text())) is None


def _committed() -> dict:
    return json.loads(null.DATA.read_text())


def _with(**changes) -> dict:
    cal = copy.deepcopy(_committed())
    for k, v in changes.items():
        if v is None:
            cal.pop(k, None)
        else:
            cal[k] = v
    return cal


def _thr(**changes) -> dict:
    return dict(_committed()["thresholds"], **changes)


BAD = [
    ("empty", {}, "thresholds.map_max_abs_z missing: an empty object"),
    ("not an object", [1, 2], "expected a JSON object"),
    ("no thresholds", _with(thresholds=None), "thresholds.map_max_abs_z missing"),
    ("thresholds not an object", _with(thresholds=[1, 2]), "thresholds.map_max_abs_z missing"),
    ("NaN threshold", _with(thresholds=_thr(map_max_abs_z=float("nan"))), "thresholds.map_max_abs_z: nan"),
    ("negative threshold", _with(thresholds=_thr(screen_logp=-1.0)), "thresholds.screen_logp: -1.0"),
    ("string threshold", _with(thresholds=_thr(screen_logp="4")), "thresholds.screen_logp: '4'"),
    ("raised threshold", _with(thresholds=_thr(map_max_abs_z=200.0)), "thresholds.map_max_abs_z: 200 is not the"),
    ("runs not a count", _with(runs=[1]), "runs: [1]"),
    ("runs not the values", _with(runs=999), "null_map_max_abs_z: 1000 values, not one per run"),
    ("a null value not finite", _with(null_screen_logp=[float("inf")] * 1000), "null_screen_logp[0]: inf"),
    ("no false-alarm target", _with(false_alarm_target_each=None), "false_alarm_target_each: None"),
    ("another code version", _with(version=log_null.VERSION + 1), "version:"),
    ("for_log not a boolean", _with(for_log="yes"), "for_log: 'yes'"),
]


@pytest.mark.parametrize("what, cal, message", BAD, ids=[b[0] for b in BAD])
def test_a_damaged_calibration_is_refused_naming_the_field(what, cal, message):
    why = problem(cal)
    assert why is not None and message in why, why


def _for_log() -> dict:
    """A calibration made for a log, as log_null stores it (3 null runs)."""
    vals_z, vals_b = [3.1, 4.2, 3.7], [2.0, 2.9, 2.4]
    return {
        "thresholds": {
            "map_max_abs_z": log_null.tail_threshold(vals_z)[0],
            "screen_logp": log_null.tail_threshold(vals_b)[0],
        },
        "false_alarm_target_each": log_null.FA_EACH,
        "runs": 3,
        "seed": 7100,
        "fingerprint": "ab" * 32,
        "for_log": True,
        "null_map_max_abs_z": vals_z,
        "null_screen_logp": vals_b,
        "version": log_null.VERSION,
    }


def test_a_calibration_made_for_a_log_needs_this_version_and_a_fingerprint():
    assert problem(_for_log()) is None
    for change, message in (
        ({"version": log_null.VERSION - 1}, "version: "),
        ({"fingerprint": None}, "fingerprint: missing"),
        ({"fingerprint": "xyz"}, "fingerprint: missing or not a SHA-256"),
        ({"seed": -1}, "seed: -1"),
        ({"thresholds": dict(_for_log()["thresholds"], screen_logp=50.0)}, "not its null values'"),
    ):
        assert message in problem(dict(_for_log(), **change)), change


def test_a_calibration_made_for_a_log_kept_as_its_vehicles_holds():
    # A team keeps the calibration made for its first log for the vehicle's
    # next logs (--calibration): no fingerprint, the method says its tail.
    cal = {k: v for k, v in _for_log().items() if k not in ("for_log", "fingerprint", "version")}
    cal["method"] = "parametric bootstrap of the log's own flight; per statistic, the predictive exponential tail"
    assert problem(cal) is None
    raised = dict(cal, thresholds=dict(cal["thresholds"], screen_logp=cal["thresholds"]["screen_logp"] + 1.0))
    assert "its null values give" in problem(raised)


@pytest.mark.parametrize("text", ["{}", json.dumps(_with(thresholds=_thr(map_max_abs_z=1e9)))], ids=["empty", "raised"])
def test_diagnose_refuses_the_file_in_one_line_and_writes_nothing(tmp_path, capsys, text):
    cal = tmp_path / "cal.json"
    cal.write_text(text)
    out = tmp_path / "out.json"
    rc = cli.main(["diagnose", str(bundled.LOG), "--calibration", str(cal), "--json", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert rc == 2, captured.out[-500:]
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"proxops diagnose: error: --calibration {cal}: thresholds")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]
