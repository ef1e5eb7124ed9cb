"""Every mistake a user can make in a flight log, its description or the
effects of a simulated log: `proxops diagnose` and `proxops simulate` exit 2
with one line on stderr that names the field, no traceback, and write
nothing. Each case below is a valid log (the bundled docking run, written
as format version 2 with the bench inspector described) with one field
wrong."""

from __future__ import annotations

import copy
import json

import h5py
import numpy as np
import pytest

from bench import cli
from bench.sim.flight_log import FlightLog, write_flight_log
from bench.sim.vehicles import inspector_12kg

WHOLE_RUN = {"t_start_s": 0.0, "t_end_s": 120.05, "manoeuvre": "docking", "starts_at_rest": True}


def _keep(log: FlightLog, stream: str, mask) -> None:
    log.streams[stream] = {k: v[mask] for k, v in log[stream].items()}


def _segments(*spans):
    return [dict(WHOLE_RUN, t_start_s=a, t_end_s=b) for a, b in spans]


def _too_few_imu(log):
    _keep(log, "imu", (log["imu"]["t_s"] > 0.45) & (log["imu"]["t_s"] < 1.15))
    _keep(log, "valves", log["valves"]["t_s"] < 1.15)
    _keep(log, "pose", np.arange(log["pose"]["t_capture_s"].size) < 2)
    log["pose"]["t_capture_s"] = log["pose"]["t_delivered_s"] = np.array([1.0, 1.1])
    log.description["segments"] = _segments((0.0, 1.15))


def _one_pose_per_run(log):
    log.description["segments"] = _segments((0.0, 59.95), (60.0, 120.05))
    _keep(log, "pose", np.isin(np.arange(log["pose"]["t_capture_s"].size), [29, 89]))  # at 30 s and 90.7 s


def _on_times(log, n_thrusters: int):
    v = log["valves"]
    bits = (v["mask"][:, None] >> np.arange(n_thrusters)) & 1
    log.streams["valves"] = {"t_s": v["t_s"], "on_time_s": bits * v["interval_s"][:, None]}


def _twelve_thrusters(log, misspelt: bool = False):
    desc = inspector_12kg()
    if misspelt:
        desc["vehicle"]["thruster"] = desc["vehicle"].pop("thrusters")
    log.description = dict(desc, segments=[dict(WHOLE_RUN)])
    _on_times(log, 8 if not misspelt else 12)


def _set(path: str, value):
    def mutate(log):
        *keys, last = path.split(".")
        node = log.description
        for k in keys:
            node = node.setdefault(k, {}) if not k.isdigit() else node[int(k)]
        node[last] = value

    return mutate


def _row(stream: str, field: str, row: int, value):
    def mutate(log):
        log[stream][field] = np.array(log[stream][field], dtype=float)
        log[stream][field][row] = value

    return mutate


DIAGNOSE = [
    ("segments outside the data", _set("segments", _segments((500.0, 600.0))), "segments[0]: holds no IMU sample"),
    (
        "a segment without IMU samples",
        _set("segments", _segments((0.0, 120.05), (200.0, 300.0))),
        "segments[1]: holds no IMU sample",
    ),
    (
        "a segment without a pose",
        _set("segments", _segments((0.0, 0.95), (0.96, 120.05))),
        "segments[0]: holds no pose capture",
    ),
    (
        "poses off every IMU tick",
        lambda log: (_set("imu.rate_hz", 100.0)(log), _set("pose_sensor.time_offset_s", 0.05)(log)),
        "pose/t_capture_s: no pose within one IMU interval of an IMU sample",
    ),
    ("one pose in each run", _one_pose_per_run, "log.h5: pose/t_capture_s: 2 pose(s) on the IMU ticks, each the first"),
    ("fewer than a handful of IMU samples", _too_few_imu, "log.h5: imu/t_s: 7 samples inside the segments"),
    ("valve columns not the thrusters", _twelve_thrusters, "valves/on_time_s: wrong shape (1199, 8), expected (N, 12)"),
    (
        "a misspelt description key",
        lambda log: _twelve_thrusters(log, misspelt=True),
        "/description_json: vehicle.thruster: unknown field",
    ),
    (
        "a pulse past the next command",
        _row("valves", "interval_s", 5, 0.2),
        "valves/interval_s row 5: pulse of 0.2 s runs past the next command",
    ),
    ("overlapping segments", _set("segments", _segments((0.0, 60.0), (50.0, 120.05))), "segments[1].t_start_s"),
    ("starts_at_rest not a boolean", _set("segments.0.starts_at_rest", "yes"), "segments[0].starts_at_rest"),
    ("an IMU rate of zero", _set("imu.rate_hz", 0), "imu.rate_hz"),
    ("a non-finite accelerometer sample", _row("imu", "accel_b_mps2", 3, np.nan), "imu/accel_b_mps2 row 3: not finite"),
    ("a quaternion off unit norm", _row("pose", "q_hb", 2, [1.0, 0.1, 0.0, 0.0]), "pose/q_hb row 2: quaternion"),
    ("time going backwards", _row("imu", "t_s", 9, 0.5), "imu/t_s row 9: time not increasing (0.9 then 0.5)"),
    ("a pose sigma of zero", _row("pose", "r_sigma_m", 4, 0.0), "pose/r_sigma_m row 4: not positive (0.0)"),
    ("an empty list of segments", _set("segments", []), "segments: an empty list"),
]


def _one_line(capsys, prog: str) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"proxops {prog}: error: ") and "Traceback" not in captured.err
    assert captured.out == ""
    return lines[0]


@pytest.mark.parametrize("what, mutate, message", DIAGNOSE, ids=[c[0] for c in DIAGNOSE])
def test_diagnose_names_the_wrong_field_and_writes_nothing(docking_log, tmp_path, capsys, what, mutate, message):
    log = copy.deepcopy(docking_log)
    mutate(log)
    path = write_flight_log(tmp_path / "log.h5", log, validate=False)
    out, rep = tmp_path / "out.json", tmp_path / "rep"
    assert cli.main(["diagnose", str(path), "--json", str(out), "--report", str(rep), "--quiet"]) == 2
    line = _one_line(capsys, "diagnose")
    assert message in line, line
    assert "; " not in line.split(message)[1]  # the first problem is the only one
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.h5"]


def test_diagnose_names_a_file_that_is_no_flight_log(tmp_path, capsys):
    (tmp_path / "log.h5").write_text("time,ax,ay,az\n")
    with h5py.File(tmp_path / "empty.h5", "w"):
        pass
    for name, message in (("log.h5", "not an HDF5 file"), ("empty.h5", "attribute 'format' is None")):
        out = tmp_path / "out.json"
        assert cli.main(["diagnose", str(tmp_path / name), "--json", str(out), "--quiet"]) == 2
        assert message in _one_line(capsys, "diagnose")
        assert not out.exists()


SIMULATE = [
    ('{"no_such_effect": 1}', "--effects: no_such_effect: not an effect this engine simulates"),
    ('{"clock_drift": 0.001}', "--effects: clock_drift: not an effect this engine simulates"),
    (
        '{"thrust_loss": [0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1]}',
        "--effects: thrust_loss: expected 1 value or 12 (one per thruster of the described vehicle), got 8",
    ),
    ('{"thrust_loss": {"loss": 0.1}}', "--effects: thrust_loss: expected a number or a list of numbers"),
    ('{"camera_latency": "0.1"}', "--effects: camera_latency: expected a number or a list of numbers"),
    ('{"camera_latency": true}', "--effects: camera_latency: expected a number or a list of numbers"),
    ('{"accel_bias": [NaN, 0, 0]}', "--effects: accel_bias: not finite"),
    ('{"accel_bias": [0.001, 0]}', "--effects: accel_bias: expected 3 values (bx, by, bz), got 2"),
    ('{"accel_bias": [1, 0, 0]}', "--effects: accel_bias: size 1 m/s^2 beyond its physical bound"),
    ('{"thrust_loss": 1.5}', "--effects: thrust_loss: 1.5 beyond the physical bound"),
    ('{"camera_latency": -0.1}', "--effects: camera_latency: latency = -0.1 must be >= 0"),
    ('{"thruster_misalignment": [[0.01, 0.0, 0.0], [0.01, 0.0]]}', "--effects: thruster_misalignment: expected rows"),
    ('{"thruster_misalignment": [0.01, 0.0, 0.0]}', "--effects: thruster_misalignment: expected 36 values"),
    ('{"thrust_loss": 0.1', "--effects: not JSON"),
    ("[0.1]", "--effects: expected a JSON object"),
    ('{"thrust_loss": [1e300]}', "--effects: thrust_loss: 1e+300 beyond the physical bound"),
    ('{"thrust_loss": 5}', "--effects: thrust_loss: 5 beyond the physical bound"),
    ('{"gyro_bias": [1e300, 0, 0]}', "--effects: gyro_bias: size inf rad/s beyond its physical bound"),
    ('{"thrust_loss": ' + "9" * 400 + "}", "--effects: not JSON (an integer of 400 digits)"),
    ('{"thrust_loss": ' + "[" * 100000 + "]" * 100000 + "}", "--effects: not JSON (nested too deeply)"),
]


def test_simulate_names_an_effects_path_that_is_no_json_file(tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text('{"a":' * 100000 + "1" + "}" * 100000)
    for arg, message in ((str(tmp_path), "a folder, expected a JSON object"), (str(deep), "nested too deeply")):
        out = tmp_path / "sim.h5"
        assert cli.main(["simulate", "--effects", arg, "--out", str(out)]) == 2
        assert message in _one_line(capsys, "simulate")
        assert sorted(p.name for p in tmp_path.iterdir()) == ["deep.json"]


@pytest.mark.parametrize("effects, message", SIMULATE)
def test_simulate_names_the_wrong_effect_and_writes_nothing(tmp_path, capsys, effects, message):
    out, key = tmp_path / "sim.h5", tmp_path / "key.json"
    assert cli.main(["simulate", "--effects", effects, "--out", str(out), "--key", str(key)]) == 2
    assert message in _one_line(capsys, "simulate")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "text, message",
    [
        ("{not json", "not JSON"),
        ("[1, 2]", "expected a JSON object"),
        (json.dumps({"vehicle": {"mass_kg": 12.0, "thruster": []}}), "vehicle.thruster: unknown field"),
        (json.dumps({"imu": {"rate_hz": -10}}), "imu.rate_hz: -10.0 must be >= 0.01"),
    ],
)
def test_simulate_names_the_wrong_description_field(tmp_path, capsys, text, message):
    desc = tmp_path / "desc.json"
    desc.write_text(text)
    out = tmp_path / "sim.h5"
    assert cli.main(["simulate", "--description", str(desc), "--out", str(out)]) == 2
    line = _one_line(capsys, "simulate")
    assert f"--description {desc}: " in line and message in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["desc.json"]
