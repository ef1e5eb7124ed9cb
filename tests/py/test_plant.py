"""Truth plant: translation against independent solutions, rotation against
conservation laws, the Hill-frame kinematics and the IMU-facing interval means."""

import numpy as np
import pytest
from scipy.linalg import expm

from bench.sim import orbit
from bench.sim.plant import N_RADPS, ORBIT_RADIUS_M, Plant, PlantState
from bench.sim.vehicle import Vehicle
from bench.so3 import boxminus, qexp, qmul, qnormalize, rotmat

N = N_RADPS


def hill_fixed_state(r, v):
    """Body axes held on the Hill axes: q = 1 and omega_BI_B = (0, 0, n)."""
    return PlantState(0.0, np.array(r, float), np.array(v, float), np.array([1.0, 0, 0, 0]), np.array([0.0, 0.0, N]))


def run(plant, force_b, t_end, dt=1.0):
    for _ in range(int(round(t_end / dt))):
        plant.step_wrench(force_b, np.zeros(3), dt)
    return plant.state


def test_nonlinear_free_drift_matches_two_body_integration():
    s0 = [10.0, -5.0, 3.0, 0.01, -0.02, 0.005]
    p = Plant(hill_fixed_state(s0[:3], s0[3:]), dynamics="nonlinear", substep_s=0.5)
    s = run(p, np.zeros(3), 600.0, dt=10.0)
    ref = orbit.propagate_two_body(np.array(s0), ORBIT_RADIUS_M, [0.0, 600.0])[-1]
    assert np.max(np.abs(s.r_hill_m - ref[:3])) < 1e-6
    assert np.max(np.abs(s.v_hill_mps - ref[3:])) < 1e-8


def test_nonlinear_with_constant_thrust_matches_two_body_integration():
    s0 = [0.5, -0.75, 0.1, 0.0, 0.0, 0.0]
    f_b = np.array([0.02, -0.01, 0.015])  # body = Hill axes here
    veh = Vehicle()
    p = Plant(hill_fixed_state(s0[:3], s0[3:]), vehicle=veh, dynamics="nonlinear", substep_s=0.1)
    s = run(p, f_b, 100.0)
    ref = orbit.propagate_two_body(
        np.array(s0), ORBIT_RADIUS_M, [0.0, 100.0], accel_hill=lambda t, x: f_b / veh.mass_kg
    )[-1]
    assert np.max(np.abs(s.r_hill_m - ref[:3])) < 1e-7
    assert np.max(np.abs(s.q_hb - [1, 0, 0, 0])) < 1e-12  # the body really stayed on the Hill axes


def test_cw_mode_matches_matrix_exponential():
    a = np.zeros((9, 9))
    a[0:3, 3:6] = np.eye(3)
    a[3, 0], a[3, 4], a[4, 3], a[5, 2] = 3 * N * N, 2 * N, -2 * N, -N * N
    a[3:6, 6:9] = np.eye(3)  # constant acceleration carried as extra states
    f_b = np.array([0.01, 0.02, -0.01])
    veh = Vehicle()
    x0 = np.concatenate([[2.0, -3.0, 1.0, 0.01, 0.0, -0.01], f_b / veh.mass_kg])
    p = Plant(hill_fixed_state(x0[:3], x0[3:6]), vehicle=veh, dynamics="cw", substep_s=1.0)
    s = run(p, f_b, 300.0, dt=5.0)
    ref = expm(a * 300.0) @ x0
    assert np.max(np.abs(s.r_hill_m - ref[:3])) < 1e-9
    assert np.max(np.abs(s.v_hill_mps - ref[3:6])) < 1e-11


def test_cw_and_nonlinear_agree_at_one_metre():
    st = hill_fixed_state([0.5, -0.75, 0.0], [0.001, 0.0, 0.0])
    a = Plant(st.copy(), dynamics="cw", substep_s=0.5)
    b = Plant(st.copy(), dynamics="nonlinear", substep_s=0.5)
    ra, rb = run(a, np.zeros(3), 200.0).r_hill_m, run(b, np.zeros(3), 200.0).r_hill_m
    assert 0.0 < np.max(np.abs(ra - rb)) < 1e-6  # second-order terms only: ~12 mu rho^2 / a^4 * t^2


def test_torque_free_body_conserves_inertial_angular_momentum_and_energy():
    veh = Vehicle()
    w0 = np.array([0.3, -0.2, 0.25])
    p = Plant(
        PlantState(0.0, np.zeros(3), np.zeros(3), qnormalize([0.9, 0.1, -0.3, 0.2]), w0), vehicle=veh, substep_s=0.01
    )
    j = veh.inertia_kgm2

    def momentum_inertial(s):
        return rotmat(p.q_ib(s.t_s, s.q_hb)) @ (j @ s.omega_bi_b_rps)

    h0, e0 = momentum_inertial(p.state), w0 @ j @ w0
    s = run(p, np.zeros(3), 20.0, dt=0.1)
    assert np.max(np.abs(momentum_inertial(s) - h0)) < 1e-10
    assert abs(s.omega_bi_b_rps @ j @ s.omega_bi_b_rps - e0) < 1e-12
    assert np.linalg.norm(s.omega_bi_b_rps - w0) > 1e-3  # the rate did precess


def test_inertially_fixed_body_turns_backwards_in_hill_frame_at_orbit_rate():
    q0 = qnormalize([0.8, 0.2, 0.4, -0.1])
    p = Plant(PlantState(0.0, np.zeros(3), np.zeros(3), q0, np.zeros(3)), substep_s=2.0)
    s = run(p, np.zeros(3), 500.0, dt=10.0)
    expected = qmul(qexp([0.0, 0.0, -N * 500.0]), q0)
    assert np.linalg.norm(boxminus(s.q_hb, expected)) < 1e-12


def test_interval_mean_rate_reproduces_attitude_step_exactly():
    veh = Vehicle()
    p = Plant(
        PlantState(0.0, np.zeros(3), np.zeros(3), qnormalize([0.9, -0.1, 0.3, 0.2]), np.array([0.02, -0.01, 0.03])),
        vehicle=veh,
    )
    q0 = p.state.q_hb
    valves = np.array([1, 0, 0, 1, 0, 1, 0, 0])
    res = p.step(valves, 0.1)
    q1 = qmul(qmul(qexp([0, 0, -N * 0.1]), q0), qexp(res.omega_mean_bi_b_rps * 0.1))
    assert np.linalg.norm(boxminus(p.state.q_hb, q1)) < 1e-13
    f, _ = veh.wrench(valves)
    assert np.allclose(res.specific_force_b_mps2, f / veh.mass_kg, atol=0)


def test_single_valve_changes_rate_by_inertia_inverse_torque():
    veh = Vehicle()
    p = Plant(PlantState(0.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)), vehicle=veh)
    p.step(np.eye(8)[2], 0.1)
    _, tau = veh.wrench(np.eye(8)[2])
    assert np.allclose(p.state.omega_bi_b_rps, np.linalg.solve(veh.inertia_kgm2, tau) * 0.1, rtol=1e-4, atol=0)


def test_rejects_unknown_dynamics_name():
    with pytest.raises(ValueError, match="dynamics"):
        Plant(hill_fixed_state([1, 0, 0], [0, 0, 0]), dynamics="keplerian")


@pytest.mark.parametrize("dynamics", ["nonlinear", "cw"])
def test_float_rk4_matches_numpy_reference(dynamics):
    # The hot-loop integrator on Python floats must be the readable numpy
    # version, step for step: tumbling body, thrust and torque, 50 substeps.
    rng = np.random.default_rng(3)
    plant = Plant(PlantState(0.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)), dynamics=dynamics)
    y = np.concatenate(
        [rng.normal(0, 2, 3), rng.normal(0, 0.05, 3), qnormalize(rng.normal(size=4)), rng.normal(0, 0.2, 3)]
    )
    f, tau = rng.normal(0, 0.02, 3), rng.normal(0, 1e-3, 3)
    ref = plant.rk4_reference(y, f, tau, 0.02, 50)
    fast = np.array(plant._rk4_floats(y.tolist(), f.tolist(), tau.tolist(), 0.02, 50))
    assert np.max(np.abs(fast - ref)) < 1e-13
    assert np.max(np.abs(ref - y)) > 1e-3  # the state did move
