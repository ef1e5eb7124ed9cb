"""Where the diagnosis is known to hold: the vehicles and IMUs it has been
validated on, and what to say when a log lies outside them.

The diagnosis's statistics are calibrated by flying the log's own flight
again with nothing unmodelled (bench/gap/log_null.py). When even those
flights give a statistic that is not finite, the diagnosis cannot judge
the log: its vehicle or IMU is outside what the replay models well enough.
The refusal then names the described fields that lie outside the envelope
of the validated vehicles (random vehicles of bench/sim/random_vehicle.py,
300 seeds, and the bench's two inspectors), so the user knows what to
check, instead of "a tail needs at least 2 finite null values".
"""

from __future__ import annotations

import numpy as np

# The validated envelope (random_vehicle.random_description, seeds 0-299).
MIN_ACCEL_SIGMA_MPS2 = 3.4e-4  # per-sample white noise
MIN_GYRO_SIGMA_RPS = 6.3e-4
MAX_THRUST_ACCEL_MPS2 = 0.34  # all thrusters together, over the mass
MAX_THRUSTER_ANGULAR_ACCEL_RPS2 = 0.91  # one thruster, about the weakest axis


def outside_envelope(desc) -> list:
    """The described fields of ``desc`` (a resolved description) outside the
    validated envelope, each as "field value (validated: bound)"."""
    out = []
    if desc.accel_sigma_mps2 < MIN_ACCEL_SIGMA_MPS2:
        out.append(f"imu.accel_sigma_mps2 {desc.accel_sigma_mps2:.3g} (validated: >= {MIN_ACCEL_SIGMA_MPS2:g})")
    if desc.gyro_sigma_rps < MIN_GYRO_SIGMA_RPS:
        out.append(f"imu.gyro_sigma_rps {desc.gyro_sigma_rps:.3g} (validated: >= {MIN_GYRO_SIGMA_RPS:g})")
    accel = sum(t.thrust_n for t in desc.thrusters) / desc.mass_kg
    if accel > MAX_THRUST_ACCEL_MPS2:
        out.append(f"vehicle.mass_kg: thrust over mass {accel:.3g} m/s^2 (validated: <= {MAX_THRUST_ACCEL_MPS2:g})")
    weakest = float(np.linalg.eigvalsh(desc.inertia_kgm2)[0])
    turn = max(
        float(np.linalg.norm(np.cross(t.position_b_m - desc.com_b_m, t.direction_b))) * t.thrust_n / weakest
        for t in desc.thrusters
    )
    if turn > MAX_THRUSTER_ANGULAR_ACCEL_RPS2:
        out.append(
            f"vehicle.inertia_kgm2: a thruster turns it at {turn:.3g} rad/s^2 "
            f"(validated: <= {MAX_THRUSTER_ANGULAR_ACCEL_RPS2:g})"
        )
    return out


def not_judgeable(desc, statistics: list, runs: int) -> str:
    """The refusal of a log whose own null flights give a statistic that is
    not finite: one line naming the statistic and the fields to check."""
    fields = outside_envelope(desc)
    where = "; ".join(fields) if fields else "no described field outside the validated envelope"
    return (
        f"/description_json: {where}: the diagnosis cannot judge this log ({', '.join(statistics)} not finite "
        f"on {runs} simulated flights of it with nothing unmodelled)"
    )
