"""Sensor models: the paper's noise profile made concrete, noise statistics,
the body-frame attitude-noise convention and the reported covariance."""

import numpy as np

from bench.sim.sensors import Imu, NoiseProfile, PoseSensor
from bench.so3 import boxminus, qexp, qmul, qnormalize


def test_paper_profile_values():
    p = NoiseProfile.paper()
    assert p.accel_sigma_mps2 == 0.25 * 0.020 / 3.0
    assert (p.gyro_sigma_rps, p.pose_pos_frac, p.pose_att_sigma_rad) == (0.005, 0.05, 0.01)
    assert p.accel_bias_mps2 == (0, 0, 0) and p.gyro_scale == (0, 0, 0) and p.pose_latency_s == 0.0


def test_imu_noise_has_profile_sigma_and_zero_mean():
    p = NoiseProfile.paper()
    imu = Imu(p, np.random.default_rng(1))
    f, w = np.array([0.004, -0.002, 0.0]), np.array([0.01, 0.0, -0.02])
    s = [imu.sample(0.1 * k, f, w) for k in range(20000)]
    ea = np.array([x.accel_b_mps2 for x in s]) - f
    eg = np.array([x.omega_bi_b_rps for x in s]) - w
    for e, sig in ((ea, p.accel_sigma_mps2), (eg, p.gyro_sigma_rps)):
        assert np.all(np.abs(e.std(axis=0) / sig - 1) < 0.03)
        assert np.all(np.abs(e.mean(axis=0)) < 4 * sig / np.sqrt(len(e)))


def test_biased_profile_adds_bias_and_scale():
    p = NoiseProfile.biased()
    imu = Imu(p.with_(accel_sigma_mps2=0.0, gyro_sigma_rps=0.0), np.random.default_rng(0))
    f, w = np.array([0.01, 0.02, -0.01]), np.array([0.1, -0.2, 0.05])
    s = imu.sample(0.1, f, w)
    assert np.allclose(s.accel_b_mps2, (1 + np.array(p.accel_scale)) * f + p.accel_bias_mps2, atol=1e-15)
    assert np.allclose(s.omega_bi_b_rps, (1 + np.array(p.gyro_scale)) * w + p.gyro_bias_rps, atol=1e-15)


def test_pose_position_sigma_is_five_percent_of_range_per_axis():
    p = NoiseProfile.paper()
    sen = PoseSensor(p, np.random.default_rng(2))
    r = np.array([0.3, -0.6, 0.2])  # range 0.7 m
    q = qnormalize([0.7, 0.1, -0.5, 0.3])
    e = np.array([sen.measure(1.0, r, q).r_hill_m - r for _ in range(20000)])
    assert np.all(np.abs(e.std(axis=0) / (0.05 * np.linalg.norm(r)) - 1) < 0.03)


def test_pose_attitude_noise_is_body_frame_exp_perturbation():
    p = NoiseProfile.paper()
    q = qnormalize([0.7, 0.1, -0.5, 0.3])
    r = np.array([0.0, -0.75, 0.0])
    m = PoseSensor(p, np.random.default_rng(3)).measure(2.0, r, q)
    rng = np.random.default_rng(3)
    rng.standard_normal(3)  # the position draw comes first
    w = p.pose_att_sigma_rad * rng.standard_normal(3)
    assert np.linalg.norm(boxminus(m.q_hb, qmul(q, qexp(w)))) < 1e-14
    assert np.linalg.norm(boxminus(m.q_hb, qmul(qexp(w), q))) > 1e-4  # not a Hill-frame perturbation


def test_pose_attitude_error_sigma():
    p = NoiseProfile.paper()
    sen = PoseSensor(p, np.random.default_rng(4))
    q = qnormalize([0.2, 0.9, -0.1, 0.3])
    e = np.array([boxminus(sen.measure(0.0, np.array([0.5, 0.5, 0]), q).q_hb, q) for _ in range(20000)])
    assert np.all(np.abs(e.std(axis=0) / p.pose_att_sigma_rad - 1) < 0.03)


def test_reported_covariance_uses_measured_range_and_carries_capture_time():
    p = NoiseProfile.paper().with_(pose_latency_s=0.3)
    m = PoseSensor(p, np.random.default_rng(5)).measure(7.0, np.array([0.0, -0.75, 0.0]), np.array([1.0, 0, 0, 0]))
    assert m.t_capture_s == 7.0 and abs(m.t_deliver_s - 7.3) < 1e-12
    sig = 0.05 * np.linalg.norm(m.r_hill_m)
    assert np.allclose(np.diag(m.R), [sig**2] * 3 + [1e-4] * 3, rtol=1e-12)
    assert np.count_nonzero(m.R - np.diag(np.diag(m.R))) == 0
