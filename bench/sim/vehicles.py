"""The vehicles the bench flies, as flight-log descriptions (format version
2, bench/sim/log_description.py).

``inspector_3kg``: the bench's own 3 kg inspector (bench/sim/vehicle.py), its
10 Hz IMU at the centre of mass and a pose sensor on one clock with it.

``inspector_12kg``: a 12 kg, 6U-class inspector (0.10 x 0.226 x 0.366 m)
with another layout and other sensors, for checking that nothing in the
diagnosis leans on the first vehicle:
  - twelve 0.1 N thrusters, two per direction of each body axis; each pair
    sits on one face, 0.09 m either side of the centre line, so the pair
    together is a pure force and one alone adds a torque about a second
    axis (x-thrusters turn about z, y about x, z about y). Nozzles are canted
    5 degrees, so no thrust is along an axis; minimum on-time 10 ms;
  - its largest dimension (the box's diagonal, 0.44 m) stated, so no lever
    arm longer than that is considered;
  - the centre of mass 3 to 12 mm off the body origin (the geometric
    centre); principal moments of a uniform box with a small product term;
  - a 20 Hz IMU turned 90 degrees about body z, 6 cm from the centre of mass;
  - a pose sensor that reports the docking face (+z, 0.18 m out), on its own
    clock 0.25 s ahead of the IMU's, with a known 50 ms latency.
"""

from __future__ import annotations

import numpy as np

from bench.sim.log_description import bench_description


def inspector_3kg() -> dict:
    return bench_description()


def _canted(axis: int, sign: float, lever_axis: int, lever_sign: float, cant_rad: float) -> np.ndarray:
    d = np.zeros(3)
    d[axis] = sign
    d[lever_axis] = -lever_sign * np.tan(cant_rad)  # towards the centre line
    return d / np.linalg.norm(d)


def inspector_12kg() -> dict:
    half = np.array([0.05, 0.113, 0.183])
    # (force axis, lever axis): x-thrusters offset along y, y along z, z along x.
    pairs = ((0, 1), (1, 2), (2, 0))
    thrusters = []
    for axis, lever in pairs:
        for sign in (+1.0, -1.0):
            for lsign in (+1.0, -1.0):
                p = np.zeros(3)
                p[axis] = -sign * half[axis]  # on the face opposite the force
                p[lever] = lsign * 0.09 * (half[lever] / max(half[lever], 0.09))
                thrusters.append(
                    {
                        "position_b_m": p.round(4).tolist(),
                        "direction_b": _canted(axis, sign, lever, lsign, np.deg2rad(5.0)).tolist(),
                        "thrust_n": 0.1,
                        "min_on_time_s": 0.01,
                    }
                )
    m = 12.0
    a, b, c = 2 * half
    inertia = m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    inertia[0, 1] = inertia[1, 0] = 0.004
    s = np.sqrt(0.5)
    return {
        "vehicle": {
            "mass_kg": m,
            "inertia_kgm2": inertia.round(5).tolist(),
            "com_b_m": [0.003, -0.005, 0.012],
            "thrusters": thrusters,
            "envelope_m": round(float(np.linalg.norm(2 * half)), 3),
        },
        "imu": {
            "rate_hz": 20.0,
            "sample": "mean",
            "q_body_imu": [s, 0.0, 0.0, s],
            "position_b_m": [0.02, 0.03, -0.04],
            "accel_noise_density_mps2_rthz": 4.0e-4,
            "gyro_noise_density_rps_rthz": 1.0e-3,
            # Biases calibrated on the ground: any constant bias in flight is a gap.
            "accel_bias_stability_mps2": 0.0,
            "gyro_bias_stability_rps": 0.0,
        },
        "pose_sensor": {"reference_point_b_m": [0.0, 0.0, 0.18], "time_offset_s": -0.25, "latency_s": 0.05},
        "orbit": {"altitude_m": 550e3},
    }


VEHICLES = {"3kg": inspector_3kg, "12kg": inspector_12kg}
