"""The dynamics channel's noise model on a vehicle that turns fast.

A gyro row differences two samples and subtracts the gyroscopic term
computed from those same noisy samples, so its noise is not only the
difference of white noise. Whitened as if it were, the gyroscopic term's
share integrates along a run and reads as a gyro bias, scale factor or IMU
misalignment on effect-free logs of a fast-turning vehicle. Here, on
random vehicle 30 (rates up to 0.17 rad/s rms, jittered and dropped
stamps): the gyro rows' statistic of each IMU-error candidate, over 40
noise draws on one noise-free flight, has the chi-square distribution the
screening assumes (a mean of 12 with the plain differences' model).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.gap import dyn
from bench.gap.load import prepare
from bench.sim.flight_log import relative_to_start
from bench.sim.vehicle_sim import simulate

DRAWS = 40


def _noise_free_channel(vehicle_seed: int):
    from bench.campaigns.gap.log_null_far import random_flight

    desc, clocks, plan = random_flight(vehicle_seed)
    log, _ = simulate(desc, plan, {}, seed=433590181, clocks=clocks, with_truth=False, noise_scale=0.0)
    return dyn.build(prepare(relative_to_start(log)))


def _gyro_statistic(ch, name: str) -> float:
    """The chi-square (k dof) of the candidate's least-squares fit to the
    gyro rows alone."""
    gy = ch.kind == 1
    J = ch.jacobian(name)[gy].reshape(-1, ch.jacobian(name).shape[2])
    e = ch.e0[gy].ravel()
    u = np.linalg.lstsq(J, -e, rcond=None)[0]
    return float(e @ e - np.sum((e + J @ u) ** 2))


def test_gyro_rows_are_white_under_the_gyroscopic_term():
    clean = _noise_free_channel(30)
    rng = np.random.default_rng(5)
    stats = {n: [] for n in ("gyro_bias", "gyro_scale", "imu_misalignment")}
    for _ in range(DRAWS):
        noisy = replace(
            clean, gyro_raw=clean.gyro_raw + clean.sig_g * rng.standard_normal(clean.gyro_raw.shape), _jac={}
        )
        noisy.accel_whiten = dyn.accel_whitener(noisy)
        noisy.chol = dyn.gyro_whiteners(noisy)
        noisy.e0 = noisy.residual()
        for n in stats:
            stats[n].append(_gyro_statistic(noisy, n))
    for n, v in stats.items():
        # chi-square, 3 dof: mean 3, the mean of 40 within 3 +- 0.9 (3.5 sigma)
        assert 2.1 < np.mean(v) < 3.9, (n, np.mean(v))
