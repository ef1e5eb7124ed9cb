"""The flight log's description (format version 2): every field checked and
named when wrong, defaults named when taken, the vehicle built from it."""

import copy
import re
from pathlib import Path

import numpy as np
import pydantic
import pytest

from bench.sim.log_description import MASS_KG, MAX_THRUSTERS, Description, DescriptionError, resolve
from bench.sim.vehicle import Vehicle
from bench.sim.vehicles import inspector_12kg


def test_no_description_is_the_bench_inspector_and_says_so():
    r = resolve(None)
    v, ref = r.vehicle(), Vehicle()
    np.testing.assert_allclose(v.thruster_forces_b_n(), ref.thruster_forces_b_n())
    np.testing.assert_allclose(v.thruster_torques_b_nm(), ref.thruster_torques_b_nm())
    assert r.mass_kg == ref.mass_kg
    named = " ".join(r.defaults)
    for key in ("vehicle.mass_kg", "vehicle.thrusters", "imu.accel_sigma_mps2", "orbit.radius_m", "segments"):
        assert key in named


def test_second_vehicle_resolves_without_defaults_but_segments():
    r = resolve(inspector_12kg())
    assert r.n_thrusters == 12 and r.mass_kg == 12.0
    assert [d.split(" ")[0] for d in r.defaults] == ["segments"]
    # sigma from the noise density: density * sqrt(rate)
    assert r.accel_sigma_mps2 == pytest.approx(4e-4 * np.sqrt(20.0))
    # thruster positions about the centre of mass, which is off the body origin
    v = r.vehicle()
    np.testing.assert_allclose(
        v.positions_b_m[0],
        np.asarray(inspector_12kg()["vehicle"]["thrusters"][0]["position_b_m"]) - np.array([0.003, -0.005, 0.012]),
    )
    F, T = v.thruster_forces_b_n(), v.thruster_torques_b_nm()
    assert np.linalg.matrix_rank(np.hstack([F, T])) == 6  # every axis of force and torque reachable


@pytest.mark.parametrize(
    "path, value, message",
    [
        (("vehicle", "mass_kg"), -1.0, "vehicle.mass_kg: -1.0 must be >= 0.01"),
        (("vehicle", "inertia_kgm2"), [1.0, 1.0, 3.0], "vehicle.inertia_kgm2: breaks the triangle inequality"),
        (("vehicle", "inertia_kgm2"), [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], "vehicle.inertia_kgm2: not symmetric"),
        (("imu", "rate_hz"), 0.0, "imu.rate_hz: 0.0 must be >= 0.01"),
        (("imu", "sample"), "point", "imu.sample: 'point' not supported"),
        (("imu", "q_body_imu"), [1.0, 0.1, 0.0, 0.0], "imu.q_body_imu: quaternion [w, x, y, z] norm"),
        (("imu", "acel_sigma_mps2"), 0.1, "imu.acel_sigma_mps2: unknown field"),
        (("pose_sensor", "latency_s"), -0.1, "pose_sensor.latency_s: -0.1 must be >= 0.0"),
        (("orbit", "altitude_m"), float("nan"), "orbit.altitude_m: expected a finite number"),
        (("vehicle", "envelope_m"), 0.0, "vehicle.envelope_m: 0.0 must be > 0.0"),
        (("imu", "gyro_bias_stability_rps"), -1e-4, "imu.gyro_bias_stability_rps: -0.0001 must be >= 0.0"),
        (("imu", "accel_bias_stability_mps2"), "small", "imu.accel_bias_stability_mps2: expected a finite number"),
        # Beyond the physical bounds, or not numbers at all: named, not an overflow or a bare conversion error.
        (("vehicle", "mass_kg"), 1e300, "vehicle.mass_kg: 1e+300 must be <= 100000.0"),
        (("vehicle", "mass_kg"), 10**400, "vehicle.mass_kg: expected a finite number"),
        (("vehicle", "com_b_m"), ["a", 0, 0], "vehicle.com_b_m: expected 3 numbers, got ['a', 0, 0]"),
        (("vehicle", "com_b_m"), [[1, 2], 3, 4], "vehicle.com_b_m: expected 3 numbers"),
        (("vehicle", "com_b_m"), [1e3, 0, 0], "vehicle.com_b_m: 1000 m from the body origin, more than 100 m"),
        (("vehicle", "inertia_kgm2"), ["a", 0, 0], "vehicle.inertia_kgm2: expected 3 principal moments"),
        (("vehicle", "inertia_kgm2"), [1e300, 1e300, 1e300], "vehicle.inertia_kgm2: principal moments"),
        (("imu", "rate_hz"), 1e-300, "imu.rate_hz: 1e-300 must be >= 0.01"),
        (("imu", "gyro_noise_density_rps_rthz"), 1e300, "imu.gyro_noise_density_rps_rthz: a per-sample sigma"),
        (("imu", "gyro_noise_density_rps_rthz"), 1e-300, "imu.gyro_noise_density_rps_rthz: a per-sample sigma"),
        (("imu", "accel_noise_density_mps2_rthz"), 1e3, "imu.accel_noise_density_mps2_rthz: a per-sample sigma"),
        (("pose_sensor", "time_offset_s"), 1e300, "pose_sensor.time_offset_s: 1e+300 must be <= 10000000000.0"),
        (("pose_sensor", "latency_s"), 1e6, "pose_sensor.latency_s: 1000000.0 must be <= 60.0"),
        # Thrusters too strong for the vehicle: its simulated flights leave the range of finite numbers.
        (("vehicle", "mass_kg"), 0.01, "vehicle.mass_kg: 0.01 kg with 1.2 N of thrust accelerates at 120 m/s^2"),
        (("vehicle", "inertia_kgm2"), [1e-8, 1e-8, 1e-8], "vehicle.thrusters[0]: its torque of 0.00908 N m turns"),
    ],
)
def test_bad_field_is_named(path, value, message):
    d = inspector_12kg()
    d[path[0]][path[1]] = value
    with pytest.raises(DescriptionError) as e:
        resolve(d)
    assert message in str(e.value)


def test_bad_thruster_is_named_with_its_index():
    d = inspector_12kg()
    d["vehicle"]["thrusters"][3]["direction_b"] = [0.5, 0.5, 0.0]
    with pytest.raises(DescriptionError, match=r"vehicle\.thrusters\[3\]\.direction_b: not a unit vector"):
        resolve(d)
    d = inspector_12kg()
    del d["vehicle"]["thrusters"][5]["thrust_n"]
    with pytest.raises(DescriptionError, match=r"vehicle\.thrusters\[5\]\.thrust_n: missing"):
        resolve(d)


def test_segments_checked():
    d = inspector_12kg()
    d["segments"] = [{"t_start_s": 0.0, "t_end_s": 10.0, "manoeuvre": "docking"}, {"t_start_s": 5.0, "t_end_s": 20.0}]
    with pytest.raises(DescriptionError, match=r"segments\[1\]\.t_start_s: 5.0 overlaps"):
        resolve(d)
    d["segments"] = [{"t_start_s": 0.0, "t_end_s": 10.0, "manoeuvre": "dancing"}]
    with pytest.raises(DescriptionError, match=r"segments\[0\]\.manoeuvre: 'dancing' is not one of"):
        resolve(d)
    d["segments"] = [{"t_start_s": 0.0, "t_end_s": 10.0, "manoeuvre": "docking", "starts_at_rest": False}]
    r = resolve(d)
    assert r.manoeuvres() == ["docking"] and not r.segments[0].starts_at_rest


def test_version1_config_keys_still_read():
    r = resolve(None, {"orbit_radius_m": 7.0e6, "noise": {"accel_sigma_mps2": 0.01}, "vehicle": {"mass_kg": 6.0}})
    assert r.orbit_radius_m == 7.0e6 and r.accel_sigma_mps2 == 0.01 and r.mass_kg == 6.0
    assert not any(x.startswith("vehicle.mass_kg") for x in r.defaults)


def test_envelope_defaults_to_the_described_points_and_bounds_the_lever_arm():
    from bench.gap.candidates import CANDIDATES, candidates_for

    r = resolve(None)  # the bench inspector: thrusters at the corners of a 0.20 m cube
    assert r.envelope_m == pytest.approx(0.2 * np.sqrt(3.0))
    assert any(d.startswith("vehicle.envelope_m = 0.346") for d in r.defaults)
    d = inspector_12kg()
    assert resolve(d).envelope_m == d["vehicle"]["envelope_m"] == pytest.approx(0.442, abs=1e-3)
    c = candidates_for(12, resolve(d).envelope_m)
    assert c["camera_lever_arm"].bound == pytest.approx(0.442, abs=1e-3)
    assert c["camera_lever_arm"].bound != CANDIDATES["camera_lever_arm"].bound
    assert c["com_offset"] == CANDIDATES["com_offset"]  # nothing else scaled


def test_draws_stay_physical_on_the_vehicle():
    from bench.sim.effects import EFFECTS, max_size_for

    v = resolve(inspector_12kg())
    assert max_size_for("camera_lever_arm", v) == pytest.approx(0.442, abs=1e-3)
    # twelve 0.1 N valves: at most 0.1 / (g0 20 s) kg/s each
    assert max_size_for("mass_depletion", v) == pytest.approx(0.1 / (9.80665 * 20.0))
    assert max_size_for("camera_lever_arm") == EFFECTS["camera_lever_arm"].max_size
    assert max_size_for("gyro_bias", v) == EFFECTS["gyro_bias"].max_size


def test_bias_stability_is_named_when_not_stated():
    r = resolve(None)
    assert r.accel_bias_stability_mps2 == 0.0 and r.gyro_bias_stability_rps == 0.0
    named = " ".join(r.defaults)
    assert "imu.accel_bias_stability_mps2 = 0 (not stated" in named
    assert "imu.gyro_bias_stability_rps = 0 (not stated" in named


# --- The schema (pydantic models) is what checks ---

DOC = Path(__file__).resolve().parents[2] / "docs" / "FLIGHT_LOG.md"
DELETE = object()
SEGMENT = {"t_start_s": 0.0, "t_end_s": 10.0}

# One bad field of the 12 kg inspector's description at a time: the whole
# message, and what refuses it: the model ("schema", Description.model_validate
# raises) or resolve()'s checks across fields and of defaults ("resolve").
BAD = [
    (("vehicle", "com_b_m"), [1, 2], "schema", "vehicle.com_b_m: expected 3 numbers, got [1, 2]"),
    (("imu", "position_b_m"), [float("nan"), 0, 0], "schema", "imu.position_b_m: not finite ([nan, 0, 0])"),
    (
        ("pose_sensor", "reference_point_b_m"),
        [0, 0, 150.0],
        "schema",
        "pose_sensor.reference_point_b_m: 150 m from the body origin, more than 100 m",
    ),
    (
        ("vehicle", "thrusters", 0, "thrust_n"),
        "0.1",
        "schema",
        "vehicle.thrusters[0].thrust_n: expected a finite number, got '0.1'",
    ),
    (("vehicle", "mass_kg"), True, "schema", "vehicle.mass_kg: expected a finite number, got True"),
    (
        ("vehicle", "thrusters", 0, "min_on_time_s"),
        -0.01,
        "schema",
        "vehicle.thrusters[0].min_on_time_s: -0.01 must be >= 0.0",
    ),
    (("vehicle", "thrusters", 0, "thrust_n"), 0, "schema", "vehicle.thrusters[0].thrust_n: 0.0 must be > 0.0"),
    (("orbit", "altitude_m"), 1e9, "schema", "orbit.altitude_m: 1000000000.0 must be <= 100000000.0"),
    (("imu",), [], "schema", "imu: expected an object, got list"),
    (
        ("pose_sensor", "latency"),
        0.1,
        "schema",
        "pose_sensor.latency: unknown field (known: reference_point_b_m, time_offset_s, latency_s)",
    ),
    (
        ("vehicle", "thrusters", 2, "thrust"),
        0.1,
        "schema",
        "vehicle.thrusters[2].thrust: unknown field (known: position_b_m, direction_b, thrust_n, min_on_time_s)",
    ),
    (
        ("extra",),
        1,
        "schema",
        "description.extra: unknown field (known: vehicle, imu, pose_sensor, orbit, segments)",
    ),
    (
        ("vehicle", "inertia_kgm2"),
        [1, 2],
        "schema",
        "vehicle.inertia_kgm2: expected 3 principal moments or a 3x3 matrix [kg m^2], got [1, 2]",
    ),
    (("vehicle", "inertia_kgm2"), [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], "schema", "vehicle.inertia_kgm2: not symmetric"),
    (
        ("vehicle", "inertia_kgm2"),
        [-1.0, 1.0, 1.0],
        "schema",
        "vehicle.inertia_kgm2: not positive definite (eigenvalues [-1.0, 1.0, 1.0])",
    ),
    (
        ("vehicle", "inertia_kgm2"),
        [1e9, 1e9, 1e9],
        "schema",
        "vehicle.inertia_kgm2: principal moments [1000000000.0, 1000000000.0, 1000000000.0] outside 1e-08 to 1e+08 "
        "kg m^2",
    ),
    (
        ("vehicle", "inertia_kgm2"),
        [1.0, 1.0, 3.0],
        "schema",
        "vehicle.inertia_kgm2: breaks the triangle inequality of a rigid body (principal moments [1.0, 1.0, 3.0])",
    ),
    (("vehicle", "thrusters"), [], "schema", "vehicle.thrusters: expected a list of 1 to 32 thrusters"),
    (("vehicle", "thrusters", 1, "direction_b"), DELETE, "schema", "vehicle.thrusters[1].direction_b: missing"),
    (
        ("vehicle", "thrusters", 1, "direction_b"),
        [0.5, 0.5, 0.0],
        "schema",
        "vehicle.thrusters[1].direction_b: not a unit vector (norm 0.707107)",
    ),
    (
        ("imu", "q_body_imu"),
        [1.0, 0.1, 0.0, 0.0],
        "schema",
        "imu.q_body_imu: quaternion [w, x, y, z] norm 1.00498756, expected 1",
    ),
    (
        ("imu", "sample"),
        "point",
        "schema",
        "imu.sample: 'point' not supported: each sample must be the mean over the interval ending at its time stamp "
        "('mean'), as delta-v / delta-angle IMUs report",
    ),
    (("orbit",), {"radius_m": 7e6, "altitude_m": 5e5}, "schema", "orbit: give radius_m or altitude_m, not both"),
    (("segments",), dict(SEGMENT), "schema", "segments: expected a list of segments"),
    (
        ("segments",),
        [],
        "schema",
        "segments: an empty list (leave the field out to have the runs found from the data)",
    ),
    (
        ("segments",),
        [dict(SEGMENT, manoeuvre="dancing")],
        "schema",
        "segments[0].manoeuvre: 'dancing' is not one of docking, characterisation, other",
    ),
    (
        ("segments",),
        [dict(SEGMENT, starts_at_rest="yes")],
        "schema",
        "segments[0].starts_at_rest: expected true or false, got 'yes'",
    ),
    (
        ("segments",),
        [{"t_start_s": 10, "t_end_s": 5}],
        "resolve",
        "segments[0].t_end_s: 5.0 is not after t_start_s 10.0",
    ),
    (
        ("segments",),
        [dict(SEGMENT), {"t_start_s": 5.0, "t_end_s": 20.0}],
        "resolve",
        "segments[1].t_start_s: 5.0 overlaps the previous segment (ends 10.0)",
    ),
    (
        ("imu", "accel_sigma_mps2"),
        0.01,
        "resolve",
        "imu: give accel_sigma_mps2 or accel_noise_density_mps2_rthz, not both",
    ),
    (
        ("imu", "rate_hz"),
        DELETE,
        "resolve",
        "imu.accel_noise_density_mps2_rthz: needs imu.rate_hz (the per-sample sigma is density * sqrt(rate))",
    ),
    (
        ("imu", "accel_noise_density_mps2_rthz"),
        1e3,
        "resolve",
        "imu.accel_noise_density_mps2_rthz: a per-sample sigma of 4472.14 at 20 Hz, outside 1e-20 to 100",
    ),
    (
        ("vehicle", "mass_kg"),
        0.01,
        "resolve",
        "vehicle.mass_kg: 0.01 kg with 1.2 N of thrust accelerates at 120 m/s^2, more than 10",
    ),
    (
        ("vehicle", "inertia_kgm2"),
        [1e-8, 1e-8, 1e-8],
        "resolve",
        "vehicle.thrusters[0]: its torque of 0.00908 N m turns the vehicle at 9.08e+05 rad/s^2 about its weakest "
        "axis (1e-08 kg m^2), more than 10",
    ),
]


def _with(path, value) -> dict:
    d = inspector_12kg()
    node = d
    for key in path[:-1]:
        node = node[key]
    if value is DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = copy.deepcopy(value)
    return d


@pytest.mark.parametrize("path, value, checked_by, message", BAD, ids=[b[3].split(":")[0] for b in BAD])
def test_each_wrong_field_gets_its_one_line_message(path, value, checked_by, message):
    d = _with(path, value)
    with pytest.raises(DescriptionError) as e:
        resolve(d)
    assert str(e.value) == message
    if checked_by == "schema":
        with pytest.raises(pydantic.ValidationError):
            Description.model_validate(d)
    else:  # a check across fields, on what the model accepted
        Description.model_validate(d)


@pytest.mark.parametrize(
    "config, message",
    [
        ({"orbit_radius_m": 1.0}, "config_json.orbit_radius_m: 1.0 must be >= 6478137.0"),
        ({"noise": {"gyro_sigma_rps": "x"}}, "config_json.noise.gyro_sigma_rps: expected a finite number, got 'x'"),
        ({"vehicle": {"mass_kg": "heavy"}}, "vehicle.mass_kg: expected a finite number, got 'heavy'"),
    ],
)
def test_version1_config_values_are_checked_by_the_same_types(config, message):
    with pytest.raises(DescriptionError) as e:
        resolve(None, config)
    assert str(e.value) == message


def _table() -> list:
    """The rows of docs/FLIGHT_LOG.md's table of description fields."""
    lines = DOC.read_text().split("## The description (`description_json`)")[1].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| field"))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            return rows
        rows.append(line)
    return rows


def _model(schema: dict, prop: dict) -> dict:
    ref = prop.get("$ref") or prop.get("items", {}).get("$ref")
    return schema["$defs"][ref.split("/")[-1]]


def test_the_schema_names_every_field_of_the_docs_table_and_no_other():
    schema = Description.model_json_schema()
    sections = {name: _model(schema, p) for name, p in schema["properties"].items() if name != "segments"}
    fields = {f"{name}.{f}" for name, m in sections.items() for f in m["properties"]} | {"segments"}
    rows = _table()
    documented = set(re.findall(r"`([a-z_]+\.[a-z0-9_]+)`", "\n".join(rows)))
    documented |= {n for row in rows for n in re.findall(r"`([a-z_.0-9]+)`", row.split("|")[1])}
    assert fields == documented
    # The thrusters' and the segments' own fields, in their rows.
    for name, model in (
        ("vehicle.thrusters", _model(schema, sections["vehicle"]["properties"]["thrusters"])),
        ("segments", _model(schema, schema["properties"]["segments"])),
    ):
        row = next(r for r in rows if r.split("|")[1].strip() == f"`{name}`")
        assert all(f"`{f}`" in row for f in model["properties"]), (name, row)
    # The bounds are the schema's.
    mass = sections["vehicle"]["properties"]["mass_kg"]
    assert (mass["minimum"], mass["maximum"]) == MASS_KG
    assert sections["vehicle"]["properties"]["thrusters"]["maxItems"] == MAX_THRUSTERS
    assert sections["vehicle"]["additionalProperties"] is False
