"""Thruster geometry authority and the docking controller (with perfect
navigation, so the controller is tested alone)."""

import numpy as np
from scipy.optimize import linprog

from bench.sim.controller import DOCK_HILL_M, ControllerParams, DockingController
from bench.sim.plant import N_RADPS
from bench.sim.scenario_docking import ScenarioConfig, run_docking
from bench.sim.vehicle import ALL_VALVES, Vehicle, config_valves
from bench.so3 import rotmat


def test_thruster_wrenches_positively_span_six_dof():
    veh = Vehicle()
    b = np.vstack([veh.thruster_forces_b_n().T, veh.thruster_torques_b_nm().T / 0.1])  # (6, 8)
    assert np.linalg.matrix_rank(b) == 6
    # Positive span <=> B lam = 0 has a solution with every lam >= 1.
    res = linprog(np.ones(8), A_eq=b, b_eq=np.zeros(6), bounds=[(1, None)] * 8)
    assert res.status == 0


def test_every_body_axis_translation_has_a_configuration_with_little_torque():
    veh = Vehicle()
    f, tau = veh.config_table()
    for axis in np.vstack([np.eye(3), -np.eye(3)]):
        ok = (f @ axis >= 0.99 * veh.thrust_n) & (np.linalg.norm(tau, axis=1) < 1e-12)
        assert ok.any(), axis


def test_config_bits_are_valves():
    assert np.array_equal(config_valves(0b10000101), [1, 0, 1, 0, 0, 0, 0, 1])
    assert ALL_VALVES.shape == (256, 8) and len({tuple(v) for v in ALL_VALVES}) == 256


def test_at_rest_on_the_dock_point_with_hill_rate_no_valve_fires():
    c = DockingController(params=ControllerParams(v_min_mps=0.0))
    q = np.array([1.0, 0, 0, 0])
    d = c.step(DOCK_HILL_M, np.zeros(3), q, np.array([0.0, 0.0, N_RADPS]))
    assert d.config == 0


def test_lateral_offset_outside_cone_aligns_before_closing():
    c = DockingController()
    r = DOCK_HILL_M + np.array([0.2, -0.1, 0.0])  # 0.2 m lateral at 0.1 m axial distance
    v_des, behaviour = c.desired_velocity(r)
    assert behaviour == "align" and v_des[1] == 0.0 and v_des[0] < 0.0


def test_closing_speed_is_capped():
    c = DockingController()
    v_des, behaviour = c.desired_velocity(DOCK_HILL_M + np.array([0.0, -5.0, 0.0]))
    assert behaviour == "approach" and abs(np.linalg.norm(v_des) - c.params.v_max_mps) < 1e-15


def test_velocity_error_fires_toward_it_in_body_frame():
    c = DockingController()
    q = np.array([np.cos(0.4), 0.0, 0.0, np.sin(0.4)])  # body turned 0.8 rad about z
    r = DOCK_HILL_M + np.array([0.0, -0.3, 0.0])
    v = np.array([0.0, -0.02, 0.0])  # moving away while the controller wants to close
    w = rotmat(q).T @ np.array([0.0, 0.0, N_RADPS])
    d = c.step(r, v, q, w)
    f, _ = c.vehicle.wrench(d.valves)
    assert (rotmat(q) @ f)[1] > 0.5 * c.vehicle.thrust_n


def test_docks_with_perfect_navigation():
    run = run_docking(3, ScenarioConfig(nav="truth", t_max_s=150.0))
    s = run.summary
    assert s.docked
    assert 0.0 < s.contact_speed_mps <= 0.01
    assert s.lateral_miss_m <= 0.03
    assert s.attitude_miss_rad <= 0.05


def test_open_loop_replay_of_a_runs_valves_reproduces_it():
    # The same seed (same sensor noise) firing the closed-loop run's valve
    # sequence open loop retraces that run exactly: what the minimum
    # detectable size's probes rely on.
    cfg = ScenarioConfig(t_max_s=30.0)
    closed = run_docking(8, cfg)
    replay = run_docking(8, ScenarioConfig(t_max_s=30.0, valve_script=tuple(int(c) for c in closed.config)))
    assert np.array_equal(replay.config, closed.config)
    for k in ("r_true", "q_true", "imu_accel", "imu_gyro"):
        assert np.array_equal(getattr(replay, k), getattr(closed, k)), k
    # A script shorter than the run ends it there; nothing past it is fired.
    short = run_docking(8, ScenarioConfig(t_max_s=30.0, valve_script=tuple(int(c) for c in closed.config[:50])))
    assert short.config.size == 50
