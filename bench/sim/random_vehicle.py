"""Random vehicle descriptions (format version 2, bench/sim/log_description.py):
vehicles unlike the bench's inspectors, for checking that nothing in the
diagnosis leans on the vehicles it was developed on.

``random_description(seed)`` draws

  - a mass of 2 to 50 kg and a box of about the density of a small
    spacecraft, with a full inertia tensor (the box's principal moments,
    perturbed, turned by a random rotation: products of inertia);
  - the centre of mass up to 3 % of the box's size off the body origin;
  - 6 to 16 valves on the box's faces, each pointing into the body from
    its face's normal by up to 35 degrees, thrust 0.02 to 1 N scaled with
    the mass, minimum on-time 0 to 20 ms; redrawn until the valves' forces
    and torques span all six axes (the wrench matrix has full rank and is
    not nearly singular), so every valve's effect can be told apart;
  - an IMU at 10 to 50 Hz, turned by a random rotation and 2 to 20 cm off
    the centre of mass, with noise densities of small MEMS parts, its
    biases calibrated on the ground (any constant bias in flight is a gap);
  - a pose sensor whose reference point is on a face, off the centre of
    mass, on its own clock (an offset of up to 0.5 s) with a known latency;
  - a circular orbit at 400 to 800 km.

``random_clocks(seed)`` draws the time stamps as real logs have them: IMU
jitter (up to 10 % of the interval) and drops, pose captures on their own
phase and jitter, and a Unix epoch (about 1.7e9 s).
"""

from __future__ import annotations

import numpy as np

from bench.sim.vehicle_sim import Clocks
from bench.so3 import qexp, qnormalize, rotmat

UNIX_EPOCH_S = 1.7e9  # about 2023-11 in Unix time
DENSITY_KGPM3 = 600.0  # a small spacecraft's mean density
MAX_CANT_RAD = np.deg2rad(35.0)


def _rotation(rng) -> np.ndarray:
    """A uniformly random unit quaternion [w, x, y, z]."""
    q = rng.standard_normal(4)
    q = q / np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _inertia(rng, mass: float, half: np.ndarray) -> np.ndarray:
    a, b, c = 2 * half
    moments = mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    moments = moments * rng.uniform(0.85, 1.15, 3)
    s = np.sort(moments)
    if s[0] + s[1] < 1.02 * s[2]:  # keep a rigid body's triangle inequality
        moments = moments + (1.02 * s[2] - s[0] - s[1])
    # Principal axes turned by up to ~25 degrees: products of inertia.
    R = rotmat(qexp(rng.normal(0.0, 0.25, 3)))
    J = R @ np.diag(moments) @ R.T
    return 0.5 * (J + J.T)


def _valve(rng, half: np.ndarray, thrust: float) -> dict:
    face = int(rng.integers(0, 3))
    sign = float(rng.choice([-1.0, 1.0]))
    p = rng.uniform(-0.8, 0.8, 3) * half
    p[face] = sign * half[face]
    # Thrust points into the body (the plume leaves the face), canted.
    n = np.zeros(3)
    n[face] = -sign
    tilt = rng.standard_normal(3)
    tilt -= tilt.dot(n) * n
    tilt /= np.linalg.norm(tilt)
    ang = rng.uniform(0.0, MAX_CANT_RAD)
    d = np.cos(ang) * n + np.sin(ang) * tilt
    return {
        "position_b_m": p.round(5).tolist(),
        "direction_b": (d / np.linalg.norm(d)).tolist(),
        "thrust_n": round(float(thrust * rng.uniform(0.8, 1.2)), 5),
        "min_on_time_s": round(float(rng.uniform(0.0, 0.02)), 4),
    }


def wrench_matrix(thrusters: list, com: np.ndarray) -> np.ndarray:
    """(6, K): each valve's force and torque about ``com`` at full thrust."""
    cols = []
    for t in thrusters:
        f = np.asarray(t["direction_b"]) * t["thrust_n"]
        r = np.asarray(t["position_b_m"]) - com
        cols.append(np.concatenate([f, np.cross(r, f)]))
    return np.array(cols).T


def _spans(thrusters: list, com: np.ndarray, half: np.ndarray) -> bool:
    W = wrench_matrix(thrusters, com)
    W = W / np.r_[np.ones(3), np.full(3, float(np.linalg.norm(half)))][:, None]  # torques in force units
    s = np.linalg.svd(W, compute_uv=False)
    return s.size == 6 and s[-1] > 0.08 * s[0]


def random_description(seed: int) -> dict:
    """A random vehicle and its sensors as a flight-log description."""
    rng = np.random.default_rng([int(seed), 0x5EED7E4])
    mass = float(np.exp(rng.uniform(np.log(2.0), np.log(50.0))))
    side = (mass / DENSITY_KGPM3) ** (1.0 / 3.0)
    half = 0.5 * side * rng.uniform(0.6, 1.6, 3)
    com = rng.uniform(-0.03, 0.03, 3) * 2 * half
    thrust = float(np.clip(0.02 * mass, 0.02, 1.0))
    k = int(rng.integers(6, 17))
    for _ in range(200):
        thrusters = [_valve(rng, half, thrust) for _ in range(k)]
        if _spans(thrusters, com, half):
            break
    else:  # pragma: no cover - a layout spanning all axes is drawn long before
        raise RuntimeError(f"no spanning valve layout drawn for seed {seed}")
    rate = float(rng.choice([10.0, 20.0, 25.0, 40.0, 50.0]))
    offset = rng.standard_normal(3)
    offset = offset / np.linalg.norm(offset) * rng.uniform(0.02, 0.2)
    face = int(rng.integers(0, 3))
    pref = rng.uniform(-0.5, 0.5, 3) * half
    pref[face] = float(rng.choice([-1.0, 1.0])) * half[face]
    return {
        "vehicle": {
            "mass_kg": round(mass, 4),
            "inertia_kgm2": _inertia(rng, mass, half).tolist(),
            "com_b_m": com.round(5).tolist(),
            "thrusters": thrusters,
            "envelope_m": round(float(np.linalg.norm(2 * half)) + 0.1, 3),
        },
        "imu": {
            "rate_hz": rate,
            "sample": "mean",
            "q_body_imu": qnormalize(_rotation(rng)).tolist(),
            "position_b_m": (com + offset).round(5).tolist(),
            "accel_noise_density_mps2_rthz": float(rng.uniform(1e-4, 6e-4)),
            "gyro_noise_density_rps_rthz": float(rng.uniform(2e-4, 1.5e-3)),
            "accel_bias_stability_mps2": 0.0,
            "gyro_bias_stability_rps": 0.0,
        },
        "pose_sensor": {
            "reference_point_b_m": pref.round(5).tolist(),
            "time_offset_s": round(float(rng.uniform(-0.5, 0.5)), 4),
            "latency_s": round(float(rng.uniform(0.0, 0.1)), 4),
        },
        "orbit": {"altitude_m": round(float(rng.uniform(400e3, 800e3)), 0)},
    }


def random_clocks(seed: int, imu_rate_hz: float, epoch_s: float = UNIX_EPOCH_S) -> Clocks:
    """Time stamps as a real flight computer writes them, on a Unix epoch."""
    rng = np.random.default_rng([int(seed), 0xC10C])
    return Clocks(
        imu_jitter_s=float(rng.uniform(0.0, 0.1)) / imu_rate_hz,
        imu_drop_frac=float(rng.uniform(0.0, 0.02)),
        pose_period_s=1.0,
        pose_phase_s=float(rng.uniform(0.2, 0.9)),
        pose_jitter_s=float(rng.uniform(0.0, 0.02)),
        pose_delay_s=float(rng.uniform(0.05, 0.3)),
        gap_s=float(rng.uniform(1.0, 5.0)),
        epoch_s=float(epoch_s + rng.uniform(0.0, 3e7)),
    )
