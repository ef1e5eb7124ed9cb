"""The flight log's description (format version 2): every field checked and
named when wrong, defaults named when taken, the vehicle built from it."""

import numpy as np
import pytest

from bench.sim.log_description import DescriptionError, resolve
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
