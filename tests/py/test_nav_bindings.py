"""The navigation filter through the bindings: the Python API contract
(names, shapes, status strings), boundary validation, delayed poses and
gating."""

import fsw_bindings as fb
import numpy as np
import pytest

Q_ID = np.array([1.0, 0.0, 0.0, 0.0])
R_POSE = np.diag([0.0375**2] * 3 + [0.01**2] * 3)
P0 = np.diag([0.05**2] * 3 + [0.01**2] * 3 + [0.05**2] * 3)


def make_filter(t0=0.0):
    cfg = fb.NavConfig()
    cfg.n_radps = fb.orbit_rate(fb.EARTH_RADIUS + 500e3)
    cfg.dt_imu_s = 0.1
    cfg.accel_sigma_mps2 = 0.25 * 0.020 / 3.0
    cfg.gyro_sigma_rps = 0.005
    cfg.gate_chi2 = 22.46
    cfg.max_delay_s = 0.5
    ukf = fb.NavUkf(cfg)
    ukf.init(t0, np.array([0.75, 0.0, 0.0]), np.zeros(3), Q_ID, P0)
    return ukf


def imu(k):
    rng = np.random.default_rng(k)
    return 1e-3 * rng.standard_normal(3), 0.01 * rng.standard_normal(3)


def test_config_defaults_and_fields_are_read_write():
    cfg = fb.NavConfig()
    assert cfg.dt_imu_s == pytest.approx(0.1)
    assert cfg.gate_chi2 == pytest.approx(22.46)
    assert cfg.max_delay_s == pytest.approx(0.5)
    assert cfg.n_radps == pytest.approx(fb.orbit_rate(fb.EARTH_RADIUS + 500e3))
    cfg.accel_sigma_mps2 = 2e-3
    cfg.gyro_sigma_rps = 1e-3
    assert cfg.accel_sigma_mps2 == 2e-3 and cfg.gyro_sigma_rps == 1e-3


def test_state_accessors_have_contract_shapes():
    ukf = make_filter()
    assert ukf.t_s == 0.0
    assert ukf.r_hill_m.shape == (3,) and ukf.v_hill_mps.shape == (3,)
    np.testing.assert_array_equal(ukf.q_hb, Q_ID)
    assert ukf.P.shape == (9, 9)
    np.testing.assert_allclose(ukf.P, P0)
    s = ukf.state()
    assert s.shape == (10,)
    np.testing.assert_array_equal(s[6:], Q_ID)


def test_predict_record_is_ok_with_zero_innovation_and_grows_covariance():
    ukf = make_filter()
    tr = np.trace(ukf.P)
    rec = ukf.predict(0.1, *imu(1))
    assert rec.status == "ok" and rec.fused is False
    assert rec.innovation.shape == (6,) and not rec.innovation.any()
    assert rec.innovation_cov.shape == (6, 6)
    assert ukf.t_s == pytest.approx(0.1)
    assert np.trace(ukf.P) > tr


def test_pose_update_fuses_and_reports_nis_and_likelihood():
    ukf = make_filter()
    for k in range(1, 11):
        ukf.predict(0.1 * k, *imu(k))
    tr = np.trace(ukf.P)
    r_meas = ukf.r_hill_m + np.array([0.02, -0.01, 0.0])
    rec = ukf.update_pose(1.0, r_meas, ukf.q_hb, R_POSE)
    assert rec.status == "ok" and rec.fused is True
    np.testing.assert_allclose(rec.innovation[:3], [0.02, -0.01, 0.0], atol=1e-12)
    S = rec.innovation_cov
    y = rec.innovation
    assert rec.nis == pytest.approx(y @ np.linalg.solve(S, y), rel=1e-9)
    _, logdet = np.linalg.slogdet(2 * np.pi * S)
    assert rec.log_likelihood == pytest.approx(-0.5 * (rec.nis + logdet), rel=1e-9)
    assert np.trace(ukf.P) < tr


def test_delayed_pose_equals_on_time_pose_and_replay():
    a, b = make_filter(), make_filter()
    for k in range(1, 11):
        a.predict(0.1 * k, *imu(k))
        b.predict(0.1 * k, *imu(k))
    r_meas = a.r_hill_m + np.array([0.03, 0.02, -0.01])
    q_meas = fb.boxplus(a.q_hb, np.array([0.01, 0.0, -0.005]))
    assert a.update_pose(1.0, r_meas, q_meas, R_POSE).status == "ok"
    for k in range(11, 16):
        a.predict(0.1 * k, *imu(k))
        b.predict(0.1 * k, *imu(k))
    rec = b.update_pose(1.0, r_meas, q_meas, R_POSE)  # 0.5 s late
    assert rec.status == "ok" and rec.fused
    np.testing.assert_allclose(b.state(), a.state(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.P, a.P, rtol=0, atol=1e-9)


def test_pose_older_than_max_delay_is_bad_input_and_state_untouched():
    ukf = make_filter()
    for k in range(1, 21):
        ukf.predict(0.1 * k, *imu(k))
    s, P = ukf.state(), ukf.P
    rec = ukf.update_pose(1.4, ukf.r_hill_m, ukf.q_hb, R_POSE)
    assert rec.status == "bad_input" and rec.detail == "too_old" and not rec.fused
    np.testing.assert_array_equal(ukf.state(), s)
    np.testing.assert_array_equal(ukf.P, P)


def test_one_metre_outlier_is_gated():
    ukf = make_filter()
    for s in range(1, 6):
        for k in range(1, 11):
            ukf.predict(s - 1 + 0.1 * k, *imu(k))
        ukf.update_pose(float(s), ukf.r_hill_m, ukf.q_hb, R_POSE)
    state = ukf.state()
    rec = ukf.update_pose(5.0, ukf.r_hill_m + np.array([1.0, 0.0, 0.0]), ukf.q_hb, R_POSE)
    assert rec.status == "gated" and not rec.fused and rec.nis > 22.46
    np.testing.assert_array_equal(ukf.state(), state)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda u: u.predict(0.1, np.array([np.nan, 0, 0]), np.zeros(3)), "accel_b_mps2"),
        (lambda u: u.predict(0.1, np.zeros(3), np.array([0, np.inf, 0])), "omega_bi_b_rps"),
        (lambda u: u.predict(np.nan, np.zeros(3), np.zeros(3)), "t_s"),
        (lambda u: u.predict(0.1, np.zeros(4), np.zeros(3)), "accel_b_mps2"),
        (lambda u: u.update_pose(0.0, np.array([0, 0, np.nan]), Q_ID, R_POSE), "r_hill_m"),
        (lambda u: u.update_pose(0.0, np.zeros(3), np.array([1.0, 0.1, 0, 0]), R_POSE), "q_hb_wxyz"),
        (lambda u: u.update_pose(0.0, np.zeros(3), Q_ID, np.eye(3)), "R"),
        (lambda u: u.update_pose(np.inf, np.zeros(3), Q_ID, R_POSE), "t_capture_s"),
        (lambda u: u.init(0.0, np.zeros(3), np.zeros(3), Q_ID, -np.eye(9)), "P0"),
        (lambda u: u.init(0.0, np.zeros(3), np.zeros(2), Q_ID, P0), "v_hill_mps"),
    ],
)
def test_bad_arrays_raise_value_error_naming_the_argument(call, name):
    ukf = make_filter()
    s = ukf.state()
    with pytest.raises(ValueError, match=name):
        call(ukf)
    np.testing.assert_array_equal(ukf.state(), s)


def test_invalid_config_raises_value_error_naming_the_field():
    cfg = fb.NavConfig()
    cfg.max_delay_s = 5.0  # does not fit the fixed history at 10 Hz
    with pytest.raises(ValueError, match="max_delay_s"):
        fb.NavUkf(cfg)
    cfg = fb.NavConfig()
    cfg.dt_imu_s = -0.1
    with pytest.raises(ValueError, match="dt_imu_s"):
        fb.NavUkf(cfg)


def _cfg():
    cfg = fb.NavConfig()
    cfg.accel_sigma_mps2 = 0.25 * 0.020 / 3.0
    cfg.gyro_sigma_rps = 0.005
    return cfg


@pytest.mark.parametrize(
    "cls, n, scalar",
    [("NavUkf", 9, "double"), ("NavUkfFloat", 9, "float"), ("NavUkf15", 15, "double"), ("NavUkf15Float", 15, "float")],
)
def test_every_variant_is_bound_and_follows_the_double_filter(cls, n, scalar):
    """The float and bias variants step the same way: with the biases known
    (variance at the floor, no random walk), after 20 s with poses the
    position agrees with the 9-state double filter to well inside its sigma."""
    c = getattr(fb, cls)
    assert c.error_size == n and c.scalar == scalar
    P0n = np.eye(n) * 1e-12
    P0n[:9, :9] = P0
    cfg = _cfg()
    cfg.gyro_bias_walk = cfg.accel_bias_walk = 0.0
    f, ref = c(cfg), make_filter()
    f.init(0.0, np.array([0.75, 0.0, 0.0]), np.zeros(3), Q_ID, P0n)
    for k in range(1, 201):
        a, w = imu(k)
        assert f.predict(0.1 * k, a, w).status == "ok"
        ref.predict(0.1 * k, a, w)
        if k % 10 == 0:
            r = np.array([0.75, 0.01 * np.sin(k), 0.0])
            assert f.update_pose(0.1 * k, r, Q_ID, R_POSE).fused
            ref.update_pose(0.1 * k, r, Q_ID, R_POSE)
    assert f.P.shape == (n, n) and f.state().shape == (n + 1,)
    sigma = np.sqrt(np.diag(ref.P)[:3])
    assert np.all(np.abs(f.r_hill_m - ref.r_hill_m) < 0.1 * sigma)


def test_bias_arguments_only_where_there_are_bias_states():
    f = fb.NavUkf15(_cfg())
    f.init(0.0, np.array([0.75, 0, 0]), np.zeros(3), Q_ID, np.eye(15) * 1e-4, gyro_bias_rps=np.array([1e-3, 0, 0]))
    assert f.state()[10] == pytest.approx(1e-3)
    with pytest.raises(ValueError, match="no bias states"):
        make_filter().init(0.0, np.zeros(3), np.zeros(3), Q_ID, P0, gyro_bias_rps=np.zeros(3))


def test_pose_ahead_of_the_filter_waits_for_its_tick_as_in_the_flight_app():
    """A pose captured at the next tick, given before that tick's IMU sample:
    'from_future' now, fused by the predict that reaches the tick, with the
    same result as the pose given after that predict."""
    early, late = make_filter(), make_filter()
    for f in (early, late):
        f.predict(0.1, *imu(1))
    r = np.array([0.76, 0.01, 0.0])
    rec = early.update_pose(0.2, r, Q_ID, R_POSE)
    assert (rec.status, rec.detail) == ("bad_input", "from_future") and early.pose_pending
    assert early.deferred_record is None
    early.predict(0.2, *imu(2))
    assert not early.pose_pending and early.deferred_record.fused
    late.predict(0.2, *imu(2))
    assert late.update_pose(0.2, r, Q_ID, R_POSE).fused
    np.testing.assert_array_equal(early.state(), late.state())
    np.testing.assert_array_equal(early.P, late.P)
    early.predict(0.3, *imu(3))
    assert early.deferred_record is None  # one predict's record only


def test_pose_further_ahead_than_max_dt_is_refused_and_not_kept():
    f = make_filter()
    rec = f.update_pose(5.0, np.array([0.75, 0.0, 0.0]), Q_ID, R_POSE)
    assert rec.detail == "from_future" and not f.pose_pending


def test_whole_log_in_one_call_in_float_follows_double():
    """nav_replay(scalar='float') runs the float build over a docking run's
    log: same poses fused, states within a small fraction of the pose noise."""
    from bench.sim.scenario_docking import ScenarioConfig, run_docking

    run = run_docking(1000, ScenarioConfig())
    u = run.updates
    m = len(u.t_capture) + 1
    r = np.vstack([run.est[0, 0:3], u.r_meas])
    q = np.vstack([run.est[0, 6:10], u.q_meas])
    R = np.array([np.diag([(0.05 * np.linalg.norm(ri)) ** 2] * 3 + [0.01**2] * 3) for ri in r])
    tc = np.concatenate([[0.0], u.t_capture])
    args = (run.imu_t, run.imu_accel, run.imu_gyro, tc, tc, r, q, R, np.zeros(m, bool), np.full(m, 0.003), 0.0)
    d = fb.nav_replay(_cfg(), *args, record_states=True)
    f = fb.nav_replay(_cfg(), *args, record_states=True, scalar="float")
    assert d["fused"][1:].all() and np.array_equal(d["fused"], f["fused"])
    assert np.abs(f["states"][:, 0:3] - d["states"][:, 0:3]).max() < 1e-4
    assert np.abs(f["nis"] - d["nis"]).max() < 1e-2
    with pytest.raises(ValueError, match="scalar"):
        fb.nav_replay(_cfg(), *args, scalar="half")
