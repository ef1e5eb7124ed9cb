"""Every candidate is exact for any described vehicle: on a noise-free log
of a random vehicle (IMU turned and off the centre of mass, the centre of
mass off the body origin, a full inertia tensor, valves at odd angles,
jittered and dropped samples, pulse-width-modulated valves), the effect
flown by the truth plant and corrected by its own candidate at the true
parameters leaves, in every channel, less than 1e-3 of the effect's signal.

The signal is the change the effect makes to the whitened residuals of both
channels (navigation replay and dynamics channel) against the same flight
without it (same commands, same time stamps, no noise); what is left is the
change after the correction. The orbital candidates (host eccentricity,
differential J2 and drag) are first-order models with parameters of their
own, and a drifting clock is not flown by this simulator
(tests/py/test_gap.py checks its candidate on the bench's logs).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.gap import dyn
from bench.gap.attribute import run_pass
from bench.gap.candidates import candidates_of
from bench.gap.load import prepare
from bench.gap.replay import reference
from bench.sim.log_description import resolve
from bench.sim.plans import characterisation_plan
from bench.sim.random_vehicle import random_clocks, random_description
from bench.sim.vehicle_sim import simulate

EXACT = 1e-3
VEHICLE_SEEDS = (1, 2)


def _effects(desc: dict, seed: int, plan_valve_seconds: float) -> dict:
    """One effect of each candidate the simulator flies, at a size that
    shows well above the numerical floor of a noise-free log."""
    r = resolve(desc)
    k = r.n_thrusters
    rng = np.random.default_rng([seed, 0xE1])
    return {
        "accel_bias": rng.normal(0.0, 2e-3, 3),
        "gyro_bias": rng.normal(0.0, 2e-3, 3),
        "gyro_scale": rng.normal(0.0, 0.02, 3),
        "imu_misalignment": rng.normal(0.0, 0.015, 3),
        "thrust_loss": rng.uniform(0.0, 0.3, k),
        "thruster_misalignment": rng.normal(0.0, 0.03, 3 * k),
        "com_offset": rng.normal(0.0, 0.01, 3),
        # Far beyond what a valve can expel (20 % of the mass over the plan), so
        # that the mass's change shows well above a noise-free log's floor.
        "mass_depletion": [0.2 * r.mass_kg / plan_valve_seconds],
        "camera_latency": [rng.uniform(0.1, 0.5)],
        "camera_lever_arm": rng.normal(0.0, 0.06, 3),
    }


class _Flight:
    """A random vehicle's short characterisation, flown noise-free."""

    def __init__(self, seed: int):
        self.desc = random_description(seed)
        r = resolve(self.desc)
        self.clocks = random_clocks(seed, r.imu_rate_hz, epoch_s=0.0)
        self.plan = characterisation_plan(self.desc, seed=seed, fire_s=0.6, coast_s=2.0, per_run=6, passes=2)
        self.null = self.fly({})
        self.null_nav = run_pass(self.null).white
        self.null_dyn = dyn.build(self.null).e0

    def fly(self, effects: dict, clocks=None):
        clocks = clocks or self.clocks
        log, _ = simulate(self.desc, self.plan, effects, seed=3, clocks=clocks, noise_scale=0.0, with_truth=False)
        d = prepare(log)
        reference(d)
        return d

    def null_of(self, name: str, theta) -> tuple:
        """The flight without the effect: (prepared log, whitened navigation
        rows, dynamics rows). A late pose stamp is compared with poses
        captured at the same instants (stamped right), not with poses
        stamped at the same times."""
        if name != "camera_latency":
            return self.null, self.null_nav, self.null_dyn
        d = self.fly({}, replace(self.clocks, pose_phase_s=self.clocks.pose_phase_s - float(theta[0])))
        return d, run_pass(d).white, dyn.build(d).e0


def _same_captures(d, d0, latency_s: float) -> tuple:
    """Indices of the poses of ``d`` and ``d0`` captured at the same instant."""
    tc = d.pose_tc - d.pose_align_s - latency_s
    tc0 = d0.pose_tc - d0.pose_align_s
    j = np.clip(np.searchsorted(tc0, tc), 0, tc0.size - 1)
    same = np.abs(tc0[j] - tc) < 1e-6
    return np.flatnonzero(same), j[same]


@pytest.fixture(scope="module", params=VEHICLE_SEEDS)
def flight(request):
    return _Flight(request.param)


def _channels(flight: _Flight, name: str, theta) -> dict:
    """{channel: (signal, left)}: the norms of the effect's change of the
    whitened rows and of what its corrected log leaves."""
    d = flight.fly({name: theta})
    c = candidates_of(d)[name]
    theta = np.asarray(theta, float)
    nav_eff = run_pass(d).white
    nav_corr = run_pass(d, c.corrections(theta, d)).white if c.nav else nav_eff
    ch = dyn.build(d)
    d0, null_nav, null_dyn = flight.null_of(name, theta)
    i, i0 = _same_captures(d, d0, float(theta[0]) if name == "camera_latency" else 0.0)
    assert i.size > 0.9 * d.pose_tc.size  # the same captures in both logs
    n0, eff, corr = null_nav[i0], nav_eff[i], nav_corr[i]
    ok = np.isfinite(n0).all(1) & np.isfinite(eff).all(1) & np.isfinite(corr).all(1)
    assert ok.sum() > 0.9 * ok.size  # fused in both
    return {
        "navigation": (np.linalg.norm(eff[ok] - n0[ok]), np.linalg.norm(corr[ok] - n0[ok])),
        "dynamics": (np.linalg.norm(ch.e0 - null_dyn), np.linalg.norm(ch.residual({name: theta}) - null_dyn)),
    }


@pytest.mark.parametrize(
    "name",
    [
        "accel_bias",
        "gyro_bias",
        "gyro_scale",
        "imu_misalignment",
        "thrust_loss",
        "thruster_misalignment",
        "com_offset",
        "mass_depletion",
        "camera_latency",
        "camera_lever_arm",
    ],
)
def test_a_candidate_at_the_true_parameters_undoes_its_effect_in_every_channel(flight, name):
    theta = _effects(flight.desc, 7, sum(float(p.cmd_on_s.sum()) for p in flight.plan))[name]
    ch = _channels(flight, name, theta)
    signal = np.hypot(*(s for s, _ in ch.values()))
    assert signal > 1.0  # the effect shows: over one noise sigma summed over the log
    for channel, (_, left) in ch.items():
        assert left < EXACT * signal, f"{name}: {channel} keeps {left / signal:.1e} of the effect's signal"


def test_the_vehicles_are_unlike_the_bench_inspectors():
    for seed in VEHICLE_SEEDS:
        r = resolve(random_description(seed))
        assert abs(r.imu_q_body_imu[0]) < 0.99  # the IMU turned
        assert np.linalg.norm(r.imu_position_b_m - r.com_b_m) >= 0.02  # and off the centre of mass
        assert np.any(r.com_b_m != 0.0) and np.count_nonzero(r.inertia_kgm2 - np.diag(np.diag(r.inertia_kgm2)))
        assert np.linalg.norm(r.pose_reference_b_m - r.com_b_m) > 0.0


def test_a_misaligned_gyro_enters_the_gyroscopic_term():
    """The sensor candidates reach the gyroscopic term w x J w: with a gyro
    bias the channel's gyro rows change even though a bias cancels in the
    differences of the rate, and the candidate's exact correction, not a
    first-order one on the gyro rows alone, takes that change away."""
    flight = _Flight(VEHICLE_SEEDS[0])
    d = flight.fly({"gyro_bias": [0.02, -0.01, 0.015]})
    ch = dyn.build(d)
    gyro = ch.kind == 1
    change = ch.e0[gyro] - flight.null_dyn[gyro]
    assert np.linalg.norm(change) > 1.0
    left = ch.residual({"gyro_bias": [0.02, -0.01, 0.015]})[gyro] - flight.null_dyn[gyro]
    assert np.linalg.norm(left) < EXACT * np.linalg.norm(change)
