"""Sensor models: a 10 Hz IMU and the 1 Hz LED pose from the vision system.

IMU (integrating, like a MEMS part that reports delta-v and delta-angle):
the sample stamped t_k reports the mean over the interval (t_k - dt, t_k],
    accel_b_mps2    = (1 + s_a) * thrust_b / m + b_a + w_a,   w_a ~ N(0, accel_sigma^2 I)
    omega_bi_b_rps  = (1 + s_g) * omega_mean_bi_b + b_g + w_g, w_g ~ N(0, gyro_sigma^2 I)
where omega_mean = Log(q_IB(t_k - dt)^-1 q_IB(t_k)) / dt, so the noise-free
sample held over the step reproduces the attitude change exactly. This is
the "sample taken at t_s, held over the step that ends at t_s" convention of
NavUkf.predict. The accelerometer sits at the centre of mass and senses only
thrust (gravity and the relative orbital terms are not specific force).

LED pose (captured at t_c, may be delivered later):
    r_meas = r_true + w_r,   w_r ~ N(0, (pose_pos_frac * |r_true|)^2 I)   (Hill, m)
    q_meas = q_true (x) Exp(w_q), w_q ~ N(0, pose_att_sigma^2 I)          (body frame)
with the covariance the vision system reports built from the measured range.

The paper's profile (Bandit, "accelerometer 25 %, gyroscope 5 %, ImageNav
position 5 %, attitude 1 %"), made concrete in :meth:`NoiseProfile.paper`:
accelerometer 1-sigma = 25 % of one 20 mN valve's acceleration on 3 kg
(1.667e-3 m/s^2), gyro 0.005 rad/s, position 5 % of range per axis,
attitude 0.01 rad per axis. Biases and scale factors are off in that profile
and available as options.

Physical effects (docs/EFFECTS.md), off unless set: an IMU mounted with its
axes rotated from the body axes (``Imu.c_imu_b``), a pose solution that refers
to a point offset from the centre of mass (``PoseSensor.lever_arm_b_m``:
r_meas = r + C(q) d), and LED occlusion that shifts the position along the
line of sight on a random subset of frames (``PoseSensor.occlusion``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.sim.vehicle import MASS_KG, THRUST_N
from bench.so3 import qexp, qmul, qnormalize, rotmat


@dataclass(frozen=True)
class NoiseProfile:
    accel_sigma_mps2: float = 0.25 * THRUST_N / MASS_KG
    gyro_sigma_rps: float = 0.005
    pose_pos_frac: float = 0.05
    pose_att_sigma_rad: float = 0.01
    accel_bias_mps2: tuple = (0.0, 0.0, 0.0)
    gyro_bias_rps: tuple = (0.0, 0.0, 0.0)
    accel_scale: tuple = (0.0, 0.0, 0.0)  # fractional scale-factor error per axis
    gyro_scale: tuple = (0.0, 0.0, 0.0)
    pose_latency_s: float = 0.0  # delivery delay of each pose after its capture

    @classmethod
    def paper(cls) -> "NoiseProfile":
        return cls()

    @classmethod
    def biased(cls) -> "NoiseProfile":
        """The paper's profile plus constant biases and scale factors that a
        9-state filter does not model (for robustness studies)."""
        return cls(
            accel_bias_mps2=(3e-4, -2e-4, 1e-4),
            gyro_bias_rps=(2e-3, -1e-3, 1.5e-3),
            accel_scale=(0.03, -0.02, 0.01),
            gyro_scale=(0.01, 0.01, -0.01),
        )

    def with_(self, **kw) -> "NoiseProfile":
        return replace(self, **kw)


@dataclass
class ImuSample:
    t_s: float
    accel_b_mps2: np.ndarray
    omega_bi_b_rps: np.ndarray


@dataclass
class PoseMeasurement:
    t_capture_s: float
    t_deliver_s: float
    r_hill_m: np.ndarray
    q_hb: np.ndarray
    R: np.ndarray  # (6, 6): position (Hill, m^2) then attitude error (body, rad^2)


@dataclass
class Imu:
    profile: NoiseProfile
    rng: np.random.Generator
    c_imu_b: np.ndarray | None = None  # body -> IMU axes (None: aligned)

    def sample(self, t_s: float, specific_force_b_mps2, omega_mean_bi_b_rps) -> ImuSample:
        p = self.profile
        if self.c_imu_b is not None:
            specific_force_b_mps2 = self.c_imu_b @ np.asarray(specific_force_b_mps2, float)
            omega_mean_bi_b_rps = self.c_imu_b @ np.asarray(omega_mean_bi_b_rps, float)
        a = (1.0 + np.asarray(p.accel_scale)) * np.asarray(specific_force_b_mps2, float)
        a = a + np.asarray(p.accel_bias_mps2) + p.accel_sigma_mps2 * self.rng.standard_normal(3)
        w = (1.0 + np.asarray(p.gyro_scale)) * np.asarray(omega_mean_bi_b_rps, float)
        w = w + np.asarray(p.gyro_bias_rps) + p.gyro_sigma_rps * self.rng.standard_normal(3)
        return ImuSample(t_s, a, w)


@dataclass
class PoseSensor:
    profile: NoiseProfile
    rng: np.random.Generator
    min_range_m: float = 0.05  # floor on the range used for the noise level
    lever_arm_b_m: np.ndarray | None = None  # measured point relative to the centre of mass, body
    # (bias_m, fraction, rng): on that fraction of frames the position is
    # shifted by bias_m along the line of sight from the host (positive: farther).
    occlusion: tuple | None = None

    def measure(self, t_s: float, r_hill_m, q_hb) -> PoseMeasurement:
        p = self.profile
        r_true = np.asarray(r_hill_m, float)
        if self.lever_arm_b_m is not None:
            r_true = r_true + rotmat(q_hb) @ np.asarray(self.lever_arm_b_m, float)
        sig_r = p.pose_pos_frac * max(np.linalg.norm(r_true), self.min_range_m)
        r_meas = r_true + sig_r * self.rng.standard_normal(3)
        if self.occlusion is not None:
            bias_m, fraction, rng = self.occlusion
            if rng.uniform() < fraction:
                r_meas = r_meas + bias_m * r_true / max(np.linalg.norm(r_true), self.min_range_m)
        q_meas = qnormalize(qmul(q_hb, qexp(p.pose_att_sigma_rad * self.rng.standard_normal(3))))
        return PoseMeasurement(t_s, t_s + p.pose_latency_s, r_meas, q_meas, self.covariance(r_meas))

    def covariance(self, r_meas_hill_m) -> np.ndarray:
        """The covariance the vision system reports, from its measured range."""
        p = self.profile
        sig_r = p.pose_pos_frac * max(np.linalg.norm(r_meas_hill_m), self.min_range_m)
        return np.diag([sig_r**2] * 3 + [p.pose_att_sigma_rad**2] * 3)
