"""The hostile-input campaign: flight logs, their descriptions, `--effects`,
`--calibration` files and campaign store records with one thing wrong at a
time, generated (a seeded generator and Hypothesis), beside the named cases
found by hand. Every one must give exit 2 and one line on stderr naming
what is wrong, no traceback, and touch nothing (no output, no report); a
store record must count as not stored rather than crash the summary.

The bounds the log is read within are docs/FLIGHT_LOG.md, "Bounds". Kept
fast: every case is refused before any diagnosis or simulation runs."""

from __future__ import annotations

import copy
import json
import os
import random
import tempfile
from pathlib import Path

# Hypothesis keeps caches (its text strategies' character tables) in a folder;
# in the tests' own cache folder (conftest.py), not in the checkout.
os.environ.setdefault("HYPOTHESIS_STORAGE_DIRECTORY", os.path.join(os.environ["PROXOPS_CACHE"], "hypothesis"))

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench import cli
from bench.gap import bundled, null
from bench.gap.calibration_file import problem
from bench.runner import records
from bench.runner.store import damaged
from bench.sim.flight_log import STREAMS, write_flight_log
from bench.sim.log_description import bench_description

WHOLE_RUN = {"t_start_s": 0.0, "t_end_s": 120.05, "manoeuvre": "docking", "starts_at_rest": True}
SETTINGS = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,  # nothing written into the checkout
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


def _refused(args: list, capsys, folder: Path, keep: set, prog: str = "diagnose") -> str:
    """Runs the command; asserts exit 2, one line, nothing but ``keep`` in
    ``folder``; returns the line."""
    rc = cli.main(args)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert rc == 2, (rc, captured.err[-2000:])
    assert len(lines) == 1 and lines[0].startswith(f"proxops {prog}: error: "), captured.err[-2000:]
    assert "Traceback" not in captured.err and captured.out == ""
    assert {p.name for p in folder.iterdir()} == keep
    return lines[0]


def _diagnose_refuses(path: Path, capsys) -> str:
    folder = path.parent
    out, rep = folder / "out.json", folder / "report"
    return _refused(
        ["diagnose", str(path), "--json", str(out), "--report", str(rep), "--quiet"], capsys, folder, {path.name}
    )


# --- Logs written by hand: the hostile files, each one thing wrong ---


def _attr(name, value):
    def post(h):
        h.attrs[name] = value

    return post


def _replace(where, make):
    def post(h):
        del h[where]
        make(h, where)

    return post


def _soft(target):
    return lambda h, where: h.__setitem__(where, h5py.SoftLink(target))


def _huge_shape(h, where):
    h.create_dataset(where, shape=(2**40, 3), dtype="f8", chunks=(1024, 3))


def _three_gigabytes(h):
    for i in range(3):  # 1 GiB each as declared; nothing stored
        h["imu"].create_dataset(f"big{i}", shape=(2_000_000, 64), dtype="f8", chunks=(10_000, 64))


def _external(h, where):
    other = Path(h.filename).with_name("other.h5")
    with h5py.File(other, "w") as o:
        o["x"] = np.arange(10.0)
    h[where] = h5py.ExternalLink(other.name, "/x")


def _group_in_stream(h):
    h["imu"].create_group("more")


def _valves_on_times(log, last_on):
    v = log["valves"]
    on = ((v["mask"][:, None] >> np.arange(8)) & 1) * v["interval_s"][:, None]
    on[-1, 0] = last_on
    log.streams["valves"] = {"t_s": v["t_s"], "on_time_s": on}


def _row(stream, field, row, value, dtype=float):
    def mutate(log):
        log[stream][field] = np.array(log[stream][field], dtype=dtype)
        log[stream][field][row] = value

    return mutate


def _desc(path, value):
    def mutate(log):
        node = log.description
        *keys, last = path
        for k in keys:
            node = node[k]
        node[last] = value

    return mutate


def _two_samples(log):
    log.description.pop("segments")
    for s in ("imu", "pose", "valves"):
        log.streams[s] = {k: v[:2] for k, v in log[s].items()}
    log["pose"]["t_capture_s"] = log["pose"]["t_delivered_s"] = log["imu"]["t_s"].copy()


def _shift_poses(by):
    def mutate(log):
        for k in ("t_capture_s", "t_delivered_s"):
            log["pose"][k] = log["pose"][k] + by

    return mutate


DEEP = '{"vehicle":' + '{"a":' * 100000 + "1" + "}" * 100001
BIG_INT = json.dumps(dict(bench_description(), segments=[WHOLE_RUN])).replace(
    '"mass_kg": 3.0', '"mass_kg": ' + "9" * 400
)

NAMED = [
    # (case, mutation of the in-memory log, change to the written file, what the line names)
    ("deeply nested description", None, _attr("description_json", DEEP), "/description_json: nested deeper than"),
    ("deeply nested config", None, _attr("config_json", "[" * 100000 + "]" * 100000), "/config_json: nested deeper"),
    ("400-digit integer", None, _attr("description_json", BIG_INT), "/description_json: not valid JSON (an integer"),
    ("description not UTF-8", None, _attr("description_json", np.bytes_(b"\xff\xfe")), "/description_json: not UTF-8"),
    ("format_version 2.7", None, _attr("format_version", 2.7), "/format_version: 2.7 is not an integer"),
    ("format_version a string", None, _attr("format_version", "2"), "/format_version: '2' is not an integer"),
    ("format_version 1e300", None, _attr("format_version", 1e300), "/format_version: 1e+300 is not an integer"),
    (
        "a huge declared shape",
        None,
        _replace("imu/accel_b_mps2", _huge_shape),
        "imu/accel_b_mps2: shape (1099511627776",
    ),
    ("fields of 3 GiB together", None, _three_gigabytes, "imu/big2: the log's fields exceed 2 GiB together"),
    ("a dangling link", None, _replace("imu/t_s", _soft("/nowhere")), "imu/t_s: a soft link"),
    ("a cyclic link", None, _replace("valves", _soft("/valves")), "valves: a soft link"),
    ("a link back to its stream", None, lambda h: h.__setitem__("imu/loop", h5py.SoftLink("/imu")), "imu/loop: a soft"),
    ("an external link", None, _replace("imu/t_s", _external), "imu/t_s: an external link"),
    ("a group inside a stream", None, _group_in_stream, "imu/more: a group inside a stream"),
    ("a stream that is a dataset", None, _replace("valves", lambda h, w: h.create_dataset(w, data=[1.0])), "valves: "),
    ("complex accelerometer data", _row("imu", "accel_b_mps2", 0, 1j, complex), None, "imu/accel_b_mps2: not real"),
    (
        "time stamps as strings",
        lambda log: log["imu"].__setitem__("t_s", log["imu"]["t_s"].astype("S")),
        None,
        "imu/t_s: not numeric",
    ),
    ("a time stamp of 1e300", _row("imu", "t_s", 1198, 1e300), None, "imu/t_s row 1198: beyond the bound"),
    ("an accelerometer value of 1e300", _row("imu", "accel_b_mps2", 5, 1e300), None, "imu/accel_b_mps2 row 5: beyond"),
    ("an on-time of 1e300 s", lambda log: _valves_on_times(log, 1e300), None, "valves/on_time_s row 1198: beyond"),
    ("a negative pose sigma", _row("pose", "r_sigma_m", 3, -0.04), None, "pose/r_sigma_m row 3: not positive"),
    ("a pose sigma of 1e-300", _row("pose", "att_sigma_rad", 0, 1e-300), None, "pose/att_sigma_rad row 0: below"),
    ("a pose sigma of 1e300", _row("pose", "r_sigma_m", 0, 1e300), None, "pose/r_sigma_m row 0: beyond the bound"),
    ("imu.rate_hz 1e-300", _desc(("imu", "rate_hz"), 1e-300), None, "imu.rate_hz: 1e-300 must be >= 0.01"),
    ("imu.rate_hz slower than the stamps", _desc(("imu", "rate_hz"), 1.0), None, "imu.rate_hz: 1 Hz means each sample"),
    ("a vector of strings", _desc(("vehicle", "com_b_m"), ["a", 0, 0]), None, "vehicle.com_b_m: expected 3 numbers"),
    ("a mass of 1e300", _desc(("vehicle", "mass_kg"), 1e300), None, "vehicle.mass_kg: 1e+300 must be <="),
    ("a segment ending at 1e300 s", _desc(("segments", 0, "t_end_s"), 1e300), None, "segments[0].t_end_s: 1e+300"),
    ("poses after the data", _shift_poses(1000.0), None, "segments[0]: holds no pose capture"),
    ("a 2-sample log", _two_samples, None, "imu/t_s: 2 samples inside the segments"),
]


@pytest.mark.parametrize("what, mutate, post, message", NAMED, ids=[c[0] for c in NAMED])
def test_a_hostile_log_is_refused_in_one_line(docking_log, tmp_path, capsys, what, mutate, post, message):
    log = copy.deepcopy(docking_log)
    if mutate is not None:
        mutate(log)
    path = write_flight_log(tmp_path / "log.h5", log, validate=False)
    if post is not None:
        with h5py.File(path, "a") as h:
            post(h)
    keep = {p.name for p in tmp_path.iterdir()}
    out = tmp_path / "out.json"
    line = _refused(
        ["diagnose", str(path), "--json", str(out), "--report", str(tmp_path / "r"), "--quiet"], capsys, tmp_path, keep
    )
    assert message in line, line


# --- Generated: one field of one stream made hostile (seeded) ---

HOSTILE_ARRAYS = {
    "NaN": lambda a, rng: _put(a, rng, np.nan),
    "infinite": lambda a, rng: _put(a, rng, -np.inf),
    "1e300": lambda a, rng: _put(a, rng, 1e300),
    "-1e300": lambda a, rng: _put(a, rng, -1e300),
    "complex": lambda a, rng: a.astype(complex) * (1 + 1e-3j),
    "strings": lambda a, rng: a.astype("S"),
    "a column too many": lambda a, rng: np.column_stack([a, a[:, :1] if a.ndim == 2 else a]),
    "a row short": lambda a, rng: a[:-1],
    "three dimensions": lambda a, rng: a[..., None, None],
}


def _put(a, rng, value):
    a = np.array(a, dtype=float)
    a.reshape(a.shape[0], -1)[rng.randrange(a.shape[0]), rng.randrange(a.reshape(a.shape[0], -1).shape[1])] = value
    return a


def _generated_stream_cases(seed: int, n: int) -> list:
    rng = random.Random(seed)
    fields = [(s.name, f.name) for s in STREAMS if s.name in ("imu", "pose") for f in s.fields] + [
        ("valves", "t_s"),
        ("valves", "interval_s"),
        ("valves", "mask"),
    ]
    return [(rng.choice(fields), rng.choice(sorted(HOSTILE_ARRAYS)), rng.randrange(2**31)) for _ in range(n)]


GENERATED = _generated_stream_cases(3501, 30)


@pytest.mark.parametrize("where, how, seed", GENERATED, ids=[f"{w[0]}/{w[1]}-{h}" for w, h, _ in GENERATED])
def test_a_generated_hostile_field_is_refused_naming_its_stream(docking_log, tmp_path, capsys, where, how, seed):
    stream, field = where
    log = copy.deepcopy(docking_log)
    log[stream][field] = HOSTILE_ARRAYS[how](np.asarray(log[stream][field]), random.Random(seed))
    path = write_flight_log(tmp_path / "log.h5", log, validate=False)
    line = _diagnose_refuses(path, capsys)
    assert f"{stream}/" in line or f"{stream}:" in line, line


# --- Hypothesis: one leaf of the description made hostile ---


def _leaves(node, path=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(node, list) and node and isinstance(node[0], dict):
        for i, v in enumerate(node):
            yield from _leaves(v, path + (i,))
    else:
        yield path


DESCRIPTION = dict(bench_description(), imu=dict(bench_description()["imu"], rate_hz=10.0), segments=[WHOLE_RUN])
LEAVES = sorted(_leaves(DESCRIPTION), key=str)
HOSTILE_VALUES = st.one_of(
    st.sampled_from([float("nan"), float("inf"), -float("inf"), 1e300, -1e300, 10**400, 10**19, "", "a", [], {}]),
    st.floats(min_value=1e13, max_value=1e308).flatmap(lambda x: st.sampled_from([x, -x])),
    st.text(min_size=1, max_size=5),
    st.recursive(st.just([]), lambda inner: st.lists(inner, min_size=1, max_size=2), max_leaves=40),
    st.dictionaries(st.text(max_size=3), st.integers(), min_size=1, max_size=2),
)


def _field_name(path) -> str:
    return str(path[-1]) if not isinstance(path[-1], int) else str(path[-2])


@SETTINGS
@given(path=st.sampled_from(LEAVES), value=HOSTILE_VALUES)
def test_a_hostile_description_value_is_refused_naming_the_field(docking_log, capsys, path, value):
    if isinstance(value, str) and path[-1] in ("manoeuvre", "sample") and value in ("docking", "other", "mean"):
        return  # a valid value of that field
    log = copy.deepcopy(docking_log)
    log.description = copy.deepcopy(DESCRIPTION)
    _desc(path, value)(log)
    with tempfile.TemporaryDirectory() as d:
        path_h5 = write_flight_log(Path(d) / "log.h5", log, validate=False)
        line = _diagnose_refuses(path_h5, capsys)
    json_level = "/description_json: not valid JSON" in line or "nested deeper" in line
    assert json_level or _field_name(path) in line, (path, value, line)


# --- Hypothesis: --effects with one thing wrong ---

EFFECT_NAMES = ["thrust_loss", "thruster_misalignment", "accel_bias", "gyro_bias", "camera_latency", "no_such_effect"]


@SETTINGS
@given(name=st.sampled_from(EFFECT_NAMES), value=HOSTILE_VALUES | st.sampled_from([5, -2, [1e300], [0.1] * 7]))
def test_a_hostile_effect_is_refused_naming_it(capsys, name, value):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        text = json.dumps({name: value})
        line = _refused(
            ["simulate", "--effects", text, "--out", str(folder / "sim.h5"), "--key", str(folder / "key.json")],
            capsys,
            folder,
            set(),
            prog="simulate",
        )
    assert f"--effects: {name}" in line or "--effects: not JSON" in line, line


# --- Hypothesis: a --calibration file with one key made hostile ---

COMMITTED = json.loads(null.DATA.read_text())
CALIBRATION_KEYS = ["thresholds", "runs", "false_alarm_target_each", "null_map_max_abs_z", "null_screen_logp"]


@SETTINGS
@given(key=st.sampled_from(CALIBRATION_KEYS), value=HOSTILE_VALUES)
def test_a_hostile_calibration_value_is_refused_naming_the_key(key, value):
    cal = dict(COMMITTED, **{key: value})
    why = problem(cal)
    assert why is not None and (key in why or "null_" in why or "thresholds" in why), (key, value, why)


@pytest.mark.parametrize("text", ["{}", "[]", "null", '{"thresholds": {}}', json.dumps(dict(COMMITTED, runs=1e300))])
def test_diagnose_refuses_a_hostile_calibration_file(tmp_path, capsys, text):
    cal = tmp_path / "cal.json"
    cal.write_text(text)
    out = tmp_path / "out.json"
    line = _refused(
        ["diagnose", str(bundled.LOG), "--calibration", str(cal), "--json", str(out), "--quiet"],
        capsys,
        tmp_path,
        {"cal.json"},
    )
    assert f"--calibration {cal}: " in line


# --- Hypothesis: a store record with one key made hostile ---

RECORD = {
    "index": 7,
    "ok": True,
    "input_sha256": "0" * 64,
    "result": {"x": 1.0},
    "result_sha256": records.sha256({"x": 1.0}),
    "seed": 3,
}


@SETTINGS
@given(key=st.sampled_from(["index", "ok", "input_sha256", "result", "result_sha256"]), value=HOSTILE_VALUES)
def test_a_hostile_store_record_is_not_used(key, value):
    assert damaged(RECORD, "run-000007.json") is None
    if key == "input_sha256" and isinstance(value, str):
        return  # another input's hash: a record of another run's input, run again (runner.map), not damaged
    rec = dict(RECORD, **{key: value})
    assert damaged(records.loads(records.dumps(rec)), "run-000007.json") is not None, (key, value)


@SETTINGS
@given(
    value=st.recursive(
        st.none() | st.booleans() | st.floats() | st.text(max_size=3),
        lambda c: st.lists(c) | st.dictionaries(st.text(max_size=3), c),
    )
)
def test_any_json_as_a_store_record_is_judged_without_raising(value):
    assert damaged(value, "run-000000.json") is not None or value == RECORD
