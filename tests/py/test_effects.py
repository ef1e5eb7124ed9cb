"""The effect library: each effect is a switch in the plant's or the sensors'
physics that changes what it should and nothing else; with no effect the
docking run is unchanged bit for bit; reality logs are valid flight logs
whose configuration does not reveal the effects."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bench.sim import orbit
from bench.sim.effects import EFFECTS, PENDING, EffectSet, canonical, realise, true_anomaly_after
from bench.sim.plant import N_RADPS, ORBIT_RADIUS_M, Plant, PlantEffects, PlantState
from bench.sim.scenario_docking import ScenarioConfig, run_docking
from bench.sim.sensors import Imu, NoiseProfile
from bench.sim.vehicle import DIRECTIONS_B, POSITIONS_B_M, Vehicle
from bench.so3 import boxminus, qexp, rotmat

fb = pytest.importorskip("fsw_bindings")

LIBRARY = {
    "thruster_misalignment",
    "thrust_loss",
    "com_offset",
    "mass_depletion",
    "accel_bias",
    "gyro_bias",
    "gyro_scale",
    "imu_misalignment",
    "camera_latency",
    "camera_lever_arm",
    "host_eccentricity",
    "differential_j2",
    "differential_drag",
    "clock_drift",
}
# flex_mode is simulated but has no diagnoser candidate: it tests "unexplained" too;
# lens_distortion exists only with pose from rendered images.
OUT_OF_LIBRARY = {"fuel_slosh", "led_occlusion", "flex_mode", "lens_distortion"}


def hill_fixed(r=(0.0, -0.75, 0.0), v=(0.0, 0.0, 0.0)):
    return PlantState(
        0.0, np.array(r, float), np.array(v, float), np.array([1.0, 0, 0, 0]), np.array([0.0, 0.0, N_RADPS])
    )


def assert_runs_equal(a, b):
    for k in ("t", "r_true", "v_true", "q_true", "w_true", "est", "P", "imu_t", "imu_accel", "imu_gyro", "config"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    for k in ("nis", "innovation", "r_meas", "q_meas", "t_capture"):
        assert np.array_equal(getattr(a.updates, k), getattr(b.updates, k)), k


# --- contract ---------------------------------------------------------------


def test_library_membership_and_lens_distortion_joined_with_the_image_pipeline():
    assert {n for n, s in EFFECTS.items() if s.in_library} == LIBRARY
    assert {n for n, s in EFFECTS.items() if not s.in_library} == OUT_OF_LIBRARY
    assert PENDING == {} and {n for n, s in EFFECTS.items() if s.needs_images} == {"lens_distortion"}


def test_campaign_draws_only_effects_the_synthetic_pose_logs_can_carry():
    from bench.campaigns.gap.validate import draw_campaign

    drawn = {k["effect"] for k in draw_campaign(200, seed=3)} - {None}
    assert "lens_distortion" not in drawn and drawn == (LIBRARY | OUT_OF_LIBRARY) - {"lens_distortion"}


def test_every_spec_draws_its_size_at_scale_times_min_detectable():
    rng = np.random.default_rng(0)
    for name, spec in EFFECTS.items():
        assert spec.kind in ("dynamics", "sensor") and spec.typical > 0 and spec.min_detectable > 0
        assert len(spec.param_names) == spec.n_params
        assert spec.min_detectable <= spec.max_size, name
        assert spec.detectable or not spec.needs_truth, name
        for scale in (0.5, 2.0):
            p = spec.draw(rng, scale)
            assert p.shape == (spec.n_params,)
            assert spec.size(p) == pytest.approx(scale * spec.min_detectable, rel=1e-12), name


def test_at_scales_a_unit_draw_to_any_size_and_keeps_its_direction():
    rng = np.random.default_rng(4)
    for name, spec in EFFECTS.items():
        unit = spec.draw_fn(rng, 1.0)
        a, b = spec.at(unit, 0.3 * spec.max_size), spec.at(unit, 0.6 * spec.max_size)
        assert spec.size(a) == pytest.approx(0.3 * spec.max_size, rel=1e-12), name
        assert spec.size(b) == pytest.approx(2.0 * spec.size(a), rel=1e-12), name
        moved = np.abs(b - a) > 0
        # Frequencies, phases and fractions stay where the draw put them.
        fixed = {"host_eccentricity": [1], "flex_mode": [0], "led_occlusion": [1]}.get(name, [])
        assert not np.any(moved[fixed]), name


def test_draw_directions_are_random():
    rng = np.random.default_rng(1)
    a, b = EFFECTS["accel_bias"].draw(rng, 1.0), EFFECTS["accel_bias"].draw(rng, 1.0)
    assert not np.allclose(a, b)


def test_effect_set_rejects_unknown_names_and_wrong_sizes():
    with pytest.raises(KeyError):
        EffectSet(warp_drive=[1.0])
    with pytest.raises(ValueError):
        EffectSet(accel_bias=[1.0, 2.0])
    with pytest.raises(ValueError):
        EffectSet(gyro_bias=[np.nan, 0, 0])
    assert np.array_equal(canonical("thrust_loss", 0.1), np.full(8, 0.1))


# --- off means off ------------------------------------------------------------


def test_empty_effect_set_run_is_bit_identical_to_run_without_effects():
    cfg = ScenarioConfig(t_max_s=12.0)
    a = run_docking(11, cfg)
    b = run_docking(11, ScenarioConfig(t_max_s=12.0, effects=EffectSet()))
    assert_runs_equal(a, b)


def test_effects_integrator_with_zero_effects_matches_rigid_plant():
    s0 = PlantState(
        0.0,
        np.array([0.3, -0.7, 0.1]),
        np.array([1e-3, 2e-3, -1e-3]),
        qexp([0.1, -0.2, 0.3]),
        np.array([0.01, -0.02, 0.015]),
    )
    a = Plant(s0.copy(), substep_s=0.02)
    b = Plant(s0.copy(), substep_s=0.02, effects=PlantEffects())
    for k in range(50):
        valves = np.array([(k >> i) & 1 for i in range(8)], float)
        ra, rb = a.step(valves, 0.1), b.step(valves, 0.1)
        assert np.allclose(ra.specific_force_b_mps2, rb.specific_force_b_mps2, rtol=0, atol=1e-15)
        # The rigid plant integrates on Python floats, the effects integrator
        # with numpy: the attitudes agree to about an ulp (1e-16) and the interval
        # rate is 2 Log(dq) / dt, which scales that by 20.
        assert np.allclose(ra.omega_mean_bi_b_rps, rb.omega_mean_bi_b_rps, rtol=0, atol=20 * 2.3e-16)
    assert np.allclose(a.state.r_hill_m, b.state.r_hill_m, rtol=0, atol=1e-13)
    assert np.allclose(a.state.omega_bi_b_rps, b.state.omega_bi_b_rps, rtol=0, atol=1e-15)


# --- sensor effects -----------------------------------------------------------


def test_accel_bias_shifts_every_accel_sample_by_exactly_the_bias():
    bias = np.array([3e-4, -2e-4, 1e-4])
    cfg = dict(t_max_s=8.0, nav="truth")
    a = run_docking(12, ScenarioConfig(**cfg))
    b = run_docking(12, ScenarioConfig(**cfg, effects=EffectSet(accel_bias=bias)))
    assert np.array_equal(a.r_true, b.r_true)  # the controller steers on the truth: same path
    assert np.allclose(b.imu_accel - a.imu_accel, bias, rtol=0, atol=1e-16)
    assert np.array_equal(a.imu_gyro, b.imu_gyro)


def test_gyro_bias_shifts_the_first_gyro_sample_by_exactly_the_bias():
    bias = np.array([1e-3, -5e-4, 2e-4])
    a = run_docking(13, ScenarioConfig(t_max_s=1.0))
    b = run_docking(13, ScenarioConfig(t_max_s=1.0, effects=EffectSet(gyro_bias=bias)))
    assert np.allclose(b.imu_gyro[0] - a.imu_gyro[0], bias, rtol=0, atol=1e-16)
    assert np.array_equal(a.imu_accel[0], b.imu_accel[0])


def quiet_imu(effects):
    fx = realise(EffectSet(effects), Vehicle(), NoiseProfile.paper().with_(accel_sigma_mps2=0.0, gyro_sigma_rps=0.0), 0)
    return Imu(fx.profile, np.random.default_rng(0), c_imu_b=fx.c_imu_b)


def test_gyro_scale_multiplies_each_axis_and_leaves_accel():
    s = np.array([0.01, -0.02, 0.03])
    f, w = np.array([0.004, -0.002, 0.001]), np.array([0.1, 0.2, -0.3])
    out = quiet_imu({"gyro_scale": s}).sample(0.1, f, w)
    assert np.allclose(out.omega_bi_b_rps, (1 + s) * w, rtol=0, atol=1e-17)
    assert np.array_equal(out.accel_b_mps2, f)


def test_imu_misalignment_rotates_both_sensors_into_the_turned_axes():
    phi = np.array([0.02, -0.01, 0.03])
    f, w = np.array([0.004, -0.002, 0.001]), np.array([0.1, 0.2, -0.3])
    out = quiet_imu({"imu_misalignment": phi}).sample(0.1, f, w)
    c = rotmat(qexp(phi))  # IMU axes -> body axes
    assert np.allclose(c @ out.accel_b_mps2, f, rtol=0, atol=1e-17)
    assert np.allclose(c @ out.omega_bi_b_rps, w, rtol=0, atol=1e-16)
    assert np.linalg.norm(out.omega_bi_b_rps - w) == pytest.approx(np.linalg.norm(np.cross(phi, w)), rel=0.05)


def first_pose(seed, effects):
    """The pose captured at t = 1 s (the path up to then does not depend on
    pose-side effects) and the run."""
    run = run_docking(seed, ScenarioConfig(t_max_s=1.0, effects=EffectSet(effects) if effects else None))
    return run.updates.r_meas[0], run


def test_camera_latency_shows_the_truth_from_latency_earlier():
    lat = 0.3
    r_nom, a = first_pose(14, None)
    r_lat, b = first_pose(14, {"camera_latency": [lat]})
    assert np.array_equal(a.r_true, b.r_true)
    r1, r07 = a.r_true[10], a.r_true[7]  # truth at 1.0 s and at 0.7 s
    z = (r_nom - r1) / (0.05 * np.linalg.norm(r1))  # the noise draw both runs share
    assert np.allclose(r_lat, r07 + 0.05 * np.linalg.norm(r07) * z, rtol=0, atol=1e-12)
    assert np.linalg.norm(r07 - r1) > 1e-4  # the motion over the latency is visible


def test_camera_lever_arm_adds_the_rotated_offset():
    d = np.array([0.02, -0.03, 0.05])
    r_nom, a = first_pose(15, None)
    r_arm, b = first_pose(15, {"camera_lever_arm": d})  # the t = 0 pose differs: so does the path
    r1 = a.r_true[10]
    z = (r_nom - r1) / (0.05 * np.linalg.norm(r1))  # the noise draw both runs share
    seen = b.r_true[10] + rotmat(b.q_true[10]) @ d
    assert np.allclose(r_arm, seen + 0.05 * np.linalg.norm(seen) * z, rtol=0, atol=1e-12)


def test_led_occlusion_on_every_frame_shifts_along_the_line_of_sight():
    r_nom, a = first_pose(16, None)
    r_occ, b = first_pose(16, {"led_occlusion": [0.04, 1.0]})  # the t = 0 pose is shifted too
    r1a, r1b = a.r_true[10], b.r_true[10]
    z = (r_nom - r1a) / (0.05 * np.linalg.norm(r1a))
    expected = r1b + 0.05 * np.linalg.norm(r1b) * z + 0.04 * r1b / np.linalg.norm(r1b)
    assert np.allclose(r_occ, expected, rtol=0, atol=1e-12)


def test_led_occlusion_hits_the_frames_its_own_generator_picks():
    a = run_docking(17, ScenarioConfig(t_max_s=30.0))
    b = run_docking(17, ScenarioConfig(t_max_s=30.0, effects=EffectSet(led_occlusion=[0.05, 0.3])))
    picks = np.random.default_rng([17, 0x0CC1]).uniform(size=31) < 0.3  # frame at t = k s draws k-th
    j = int(np.argmax(picks[1:])) + 1  # first occluded fused frame (t = j s)
    assert 1 < j < 30
    ua, ub = a.updates.r_meas, b.updates.r_meas
    assert np.array_equal(ua[: j - 1], ub[: j - 1])
    r = a.r_true[10 * j]
    assert np.allclose(ub[j - 1] - ua[j - 1], 0.05 * r / np.linalg.norm(r), rtol=0, atol=1e-15)


def test_clock_drift_scales_imu_time_tags_and_updates_still_fuse():
    eps = 1e-3
    run = run_docking(18, ScenarioConfig(t_max_s=10.0, effects=EffectSet(clock_drift=[eps])))
    t = np.arange(1, len(run.imu_t) + 1) * 0.1
    assert np.allclose(run.imu_t, t * (1 + eps), rtol=0, atol=1e-12)
    assert np.allclose(run.updates.t_capture, np.arange(1, 11) * (1 + eps), rtol=0, atol=1e-12)
    assert np.all(run.updates.status != "bad_input")


# --- dynamics effects -------------------------------------------------------------


def test_thrust_loss_and_misalignment_change_only_the_truth_vehicle():
    loss = np.linspace(0.0, 0.07, 8)
    phi = EFFECTS["thruster_misalignment"].draw(np.random.default_rng(3), 1.0).reshape(8, 3)
    fx = realise(EffectSet(thrust_loss=loss, thruster_misalignment=phi.ravel()), Vehicle(), NoiseProfile.paper(), 0)
    f = fx.vehicle.thruster_forces_b_n()
    assert np.allclose(np.linalg.norm(f, axis=1), 0.020 * (1 - loss), rtol=1e-14)
    ang = np.arccos(np.clip(np.sum(fx.vehicle.directions_b * DIRECTIONS_B, axis=1), -1, 1))
    assert np.allclose(ang, np.linalg.norm(phi, axis=1), rtol=1e-6)
    assert np.array_equal(Vehicle().directions_b, DIRECTIONS_B)  # the nominal model is untouched
    assert fx.plant is None


def test_com_offset_moves_torques_and_gives_the_accelerometer_a_lever_arm():
    c = np.array([0.01, -0.005, 0.008])
    fx = realise(EffectSet(com_offset=c), Vehicle(), NoiseProfile.paper(), 0)
    v = fx.vehicle
    assert np.allclose(v.thruster_torques_b_nm(), np.cross(POSITIONS_B_M - c, v.thruster_forces_b_n()), atol=1e-18)
    p = Plant(hill_fixed(), vehicle=v, effects=fx.plant, substep_s=0.01)
    w0 = p.state.omega_bi_b_rps.copy()
    valves = np.eye(8)[0]
    res = p.step(valves, 0.1)
    alpha = (p.state.omega_bi_b_rps - w0) / 0.1
    wm = 0.5 * (w0 + p.state.omega_bi_b_rps)
    lever = np.cross(alpha, -c) + np.cross(wm, np.cross(wm, -c))
    assert np.linalg.norm(lever) > 1e-4  # comparable to the accelerometer noise (1.7e-3)
    assert np.allclose(res.specific_force_b_mps2, v.thruster_forces_b_n()[0] / 3.0 + lever, rtol=0, atol=1e-12)


def test_mass_depletion_lowers_mass_by_flow_times_valve_seconds():
    flow = 1e-3
    fx = realise(EffectSet(mass_depletion=[flow]), Vehicle(), NoiseProfile.paper(), 0)
    p = Plant(hill_fixed(), effects=fx.plant)
    valves = np.array([1, 1, 0, 0, 1, 0, 0, 0], float)
    for _ in range(10):
        p.step(valves, 0.1)
    assert p.mass_kg == pytest.approx(3.0 - flow * 3 * 1.0, rel=1e-14)
    res = p.step(valves, 0.1)
    f, _ = Vehicle().wrench(valves)
    # The interval flies at the mass of its midpoint: half its propellant used.
    assert np.allclose(res.specific_force_b_mps2, f / (3.0 - 3e-3 - 0.5 * flow * 3 * 0.1), rtol=1e-12)


def test_mass_depletion_follows_the_rocket_equation_without_a_half_interval_lag():
    # A long firing at a large flow: the velocity the accelerometer integrates
    # is (F / mdot) ln(m0 / m1). Mass held at each interval's start (lowered
    # after it) understates it by about mdot dt / (2 m) = 5e-4 here; flown at
    # each interval's midpoint mass the error is second order (~1e-7).
    flow, dt, n = 1e-2, 0.1, 20
    fx = realise(EffectSet(mass_depletion=[flow]), Vehicle(), NoiseProfile.paper(), 0)
    p = Plant(hill_fixed(), effects=fx.plant)
    valves = np.array([1, 1, 0, 0, 1, 0, 0, 0], float)
    dv = sum(p.step(valves, dt).specific_force_b_mps2 * dt for _ in range(n))
    f, _ = Vehicle().wrench(valves)
    mdot = flow * valves.sum()
    m0, m1 = 3.0, 3.0 - mdot * dt * n
    assert p.mass_kg == pytest.approx(m1, rel=1e-14)
    rocket = f / mdot * np.log(m0 / m1)
    assert np.allclose(dv, rocket, rtol=1e-6, atol=0.0)


def _kepler_state(a, e, f, mu):
    p = a * (1 - e * e)
    rr = p / (1 + e * np.cos(f))
    r = rr * np.array([np.cos(f), np.sin(f), 0.0])
    v = np.sqrt(mu / p) * np.array([-np.sin(f), e + np.cos(f), 0.0])
    return r, v


def test_eccentric_host_relative_motion_matches_inertial_two_body_integration():
    e, f0, mu, a = 0.02, 0.7, orbit.MU_EARTH, ORBIT_RADIUS_M
    rho0, rhod0 = np.array([0.5, -0.75, 0.2]), np.array([1e-3, -2e-3, 5e-4])
    p = Plant(
        hill_fixed(rho0, rhod0), effects=PlantEffects(host_eccentricity=e, host_true_anomaly0_rad=f0), substep_s=0.5
    )
    for _ in range(30):
        p.step_wrench(np.zeros(3), np.zeros(3), 10.0)

    def frame(rc, vc):
        x = rc / np.linalg.norm(rc)
        z = np.cross(rc, vc)
        z /= np.linalg.norm(z)
        return np.column_stack([x, np.cross(z, x), z]), np.linalg.norm(np.cross(rc, vc)) / (rc @ rc)

    rc, vc = _kepler_state(a, e, f0, mu)
    c, thd = frame(rc, vc)
    w = np.array([0.0, 0.0, thd])
    y0 = np.concatenate([rc, vc, rc + c @ rho0, vc + c @ (rhod0 + np.cross(w, rho0))])

    def two_body(_, y):
        return np.concatenate(
            [y[3:6], -mu * y[0:3] / np.linalg.norm(y[0:3]) ** 3, y[9:12], -mu * y[6:9] / np.linalg.norm(y[6:9]) ** 3]
        )

    y1 = solve_ivp(two_body, (0, 300.0), y0, rtol=1e-13, atol=1e-9, method="DOP853").y[:, -1]
    c1, _ = frame(y1[0:3], y1[3:6])
    rho1 = c1.T @ (y1[6:9] - y1[0:3])
    assert np.max(np.abs(p.state.r_hill_m - rho1)) < 2e-5
    # and the eccentricity is visible at that level: the circular plant differs by far more
    q = Plant(hill_fixed(rho0, rhod0), substep_s=0.5)
    for _ in range(30):
        q.step_wrench(np.zeros(3), np.zeros(3), 10.0)
    assert np.max(np.abs(q.state.r_hill_m - rho1)) > 100 * np.max(np.abs(p.state.r_hill_m - rho1))


def test_eccentric_host_turns_an_inertially_fixed_body_at_the_true_anomaly_rate():
    e, f0 = 0.05, 0.3
    p = Plant(
        PlantState(0.0, np.array([0.0, -0.75, 0.0]), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)),
        effects=PlantEffects(host_eccentricity=e, host_true_anomaly0_rad=f0),
        substep_s=2.0,
    )
    for _ in range(60):
        p.step_wrench(np.zeros(3), np.zeros(3), 10.0)
    f1 = true_anomaly_after(e, f0, N_RADPS * 600.0)
    assert np.linalg.norm(boxminus(p.state.q_hb, qexp([0.0, 0.0, -(f1 - f0)]))) < 1e-9


def test_differential_j2_is_zero_at_the_host_and_linear_and_small_nearby():
    p = Plant(hill_fixed(), effects=PlantEffects(j2=1.08263e-3))
    r = np.array([0.3, -0.7, 0.2])
    a1, a2 = p._j2_accel_hill(100.0, r), p._j2_accel_hill(100.0, 2 * r)
    assert np.allclose(p._j2_accel_hill(100.0, np.zeros(3)), 0.0, atol=1e-20)
    assert np.allclose(a2, 2 * a1, rtol=1e-5, atol=0)
    # gradient of the J2 acceleration ~ J2 mu Re^2 / a^5 (times a few): 1e-9 .. 1e-7 1/s^2
    assert 1e-9 < np.linalg.norm(a1) / np.linalg.norm(r) < 1e-7


def test_differential_drag_decelerates_along_track():
    db = 0.5
    a = Plant(hill_fixed(), substep_s=0.5)
    b = Plant(hill_fixed(), effects=PlantEffects(diff_ballistic_m2pkg=db), substep_s=0.5)
    for _ in range(10):
        a.step_wrench(np.zeros(3), np.zeros(3), 1.0)
        b.step_wrench(np.zeros(3), np.zeros(3), 1.0)
    acc = -0.5 * 5e-13 * (N_RADPS * ORBIT_RADIUS_M) ** 2 * db
    dy = b.state.r_hill_m[1] - a.state.r_hill_m[1]
    assert dy == pytest.approx(0.5 * acc * 10.0**2, rel=1e-3)
    # and the Coriolis term turns it radial: x'' = 2 n y' = 2 n acc t, x = n acc t^3 / 3
    dx = b.state.r_hill_m[0] - a.state.r_hill_m[0]
    assert dx == pytest.approx(N_RADPS * acc * 10.0**3 / 3.0, rel=0.03)
    assert np.allclose(b.state.r_hill_m[2], a.state.r_hill_m[2], rtol=0, atol=1e-15)


def test_the_accelerometer_senses_the_inspectors_own_drag_not_the_hosts():
    # dB = B_i - B_h moves the relative motion; B_i (dB + B_host) is a
    # non-gravitational force on the inspector, so its accelerometer reads it
    # (body axes; here body = Hill axes turning at n about z).
    db, bh = 0.5, 0.2
    q_dyn = 0.5 * 5e-13 * (N_RADPS * ORBIT_RADIUS_M) ** 2
    b = Plant(hill_fixed(), effects=PlantEffects(diff_ballistic_m2pkg=db, host_ballistic_m2pkg=bh), substep_s=0.5)
    res = b.step_wrench(np.zeros(3), np.zeros(3), 1.0)
    assert res.specific_force_b_mps2 == pytest.approx([0.0, -q_dyn * (db + bh), 0.0], abs=1e-9 * q_dyn)
    # the host's drag alone is not sensed: the same relative motion as before
    c = Plant(hill_fixed(), effects=PlantEffects(diff_ballistic_m2pkg=db), substep_s=0.5)
    c.step_wrench(np.zeros(3), np.zeros(3), 1.0)
    assert np.allclose(b.state.r_hill_m, c.state.r_hill_m, rtol=0, atol=1e-15)
    # the effect's two parameters reach the plant; one value keeps B_inspector >= 0
    assert canonical("differential_drag", [-0.3]).tolist() == [-0.3, 0.3]


def test_flex_mode_swings_the_body_at_its_frequency_and_amplitude_and_keeps_momentum():
    f, amp = 0.25, 0.01
    s0 = PlantState(0.0, np.array([0.0, -0.75, 0.0]), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3))
    p = Plant(s0, effects=PlantEffects(flex_freq_hz=f, flex_amplitude_rad=amp, flex_damping=0.0), substep_s=0.02)
    delta = np.sqrt(PlantEffects().flex_participation * 0.020) * np.array([0.0, 0.0, 1.0])
    h0 = p._j @ p.state.omega_bi_b_rps + delta * p.internal_state[1]
    ang, t = [], []
    for _k in range(200):
        p.step_wrench(np.zeros(3), np.zeros(3), 0.05)
        q_ib = p.q_ib(p.state.t_s, p.state.q_hb)
        ang.append(2 * q_ib[3] / q_ib[0])
        t.append(p.state.t_s)
    ang = np.array(ang)
    h1 = p._j @ p.state.omega_bi_b_rps + delta * p.internal_state[1]
    assert np.allclose(h0, h1, atol=1e-12)
    assert (ang.max() - ang.min()) / 2 == pytest.approx(amp, rel=0.02)
    spec = np.abs(np.fft.rfft(ang - ang.mean()))
    freqs = np.fft.rfftfreq(ang.size, 0.05)
    assert freqs[np.argmax(spec)] == pytest.approx(f, abs=0.1)


def test_fuel_slosh_mean_specific_force_is_total_thrust_over_total_mass_and_oscillates():
    s0 = hill_fixed()
    p = Plant(s0, effects=PlantEffects(slosh_mass_kg=0.3, slosh_damping=0.0), substep_s=0.02)
    f = np.array([0.02, 0.0, 0.0])
    sf = np.array([p.step_wrench(f, np.zeros(3), 0.1).specific_force_b_mps2 for _ in range(200)])
    # the slosh mass swings from rest at 0.3 Hz: the accelerometer sees F / m_rigid
    # at first and F / m on average over whole periods (20 s = 6 periods)
    assert sf[0, 0] > f[0] / 3.0 * 1.05
    assert sf[:, 0].mean() == pytest.approx(f[0] / 3.0, rel=0.02)
    assert np.allclose(sf[:, 1:], 0.0, atol=1e-15)


# --- reality logs --------------------------------------------------------------


def test_simulate_log_is_valid_and_hides_the_effects():
    from bench.sim.flight_log import validate_log
    from bench.sim.reality import simulate_log, simulate_log_with_key

    eff = {"gyro_bias": [1e-3, 0.0, -5e-4], "camera_latency": [0.2]}
    log, key = simulate_log_with_key(21, eff, duration_s=15.0)
    assert validate_log(log) == []
    assert set(log.streams) == {"imu", "pose", "valves", "estimate", "update", "truth"}
    text = json.dumps(log.config)
    for name in EFFECTS:
        assert name not in text
    assert key["effects"] == {"gyro_bias": [1e-3, 0.0, -5e-4], "camera_latency": [0.2]} and len(key["sha256"]) == 64
    nominal = simulate_log(21, None, duration_s=15.0, with_truth=False)
    assert nominal.config == log.config and "truth" not in nominal.streams
    assert validate_log(nominal) == []


def test_simulate_log_chains_runs_to_fill_the_duration_with_the_host_orbit_phase_carried_on():
    from bench.sim.flight_log import validate_log
    from bench.sim.reality import _effects_at, simulate_log_with_key

    log, _ = simulate_log_with_key(22, {"clock_drift": [2e-3]}, duration_s=25.0, scenario=ScenarioConfig(t_max_s=10.0))
    assert validate_log(log) == []
    assert log["imu"]["t_s"][-1] == pytest.approx(25.0 * (1 + 2e-3), abs=0.3)
    e = _effects_at(EffectSet(host_eccentricity=[0.01, 0.5]), 100.0)
    assert e["host_eccentricity"][1] == pytest.approx(true_anomaly_after(0.01, 0.5, N_RADPS * 100.0), abs=0)
    assert e["host_eccentricity"][1] > 0.5
