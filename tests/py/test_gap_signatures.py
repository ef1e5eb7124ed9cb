"""The candidates' Jacobians a calibration's null runs share with their
flight (attribute.signatures, log_null.shared_signatures): only those that
read no measurement, the statistics they give within a few hundredths of
each run's own, and never used on a log of another shape."""

import pytest

from bench.gap import log_null
from bench.gap.attribute import NAV_READINGS_FREE, signatures
from bench.gap.detection import context, null_statistics
from bench.gap.dyn import READINGS_FREE
from bench.gap.load import prepare


@pytest.fixture(scope="module")
def flight():
    """A random vehicle's short characterisation, with its clocks' jitter
    and drops, as a calibration prepares it."""
    from bench.sim.flight_log import relative_to_start
    from bench.sim.plans import characterisation_plan
    from bench.sim.random_vehicle import random_clocks, random_description
    from bench.sim.vehicle_sim import simulate

    desc = random_description(5)
    plan = characterisation_plan(desc, 5)[:3]
    log, _ = simulate(desc, plan, {}, seed=3, clocks=random_clocks(5, desc["imu"]["rate_hz"]), with_truth=False)
    log = relative_to_start(log)
    return log, log_null.plan_of(log)


def test_only_jacobians_that_read_no_measurement_are_shared(flight):
    log, _ = flight
    sig = signatures(context(prepare(log)))
    for name, s in sig.items():
        assert (s["nav"] is not None) == (name in NAV_READINGS_FREE), name
        assert (s["dyn"] is not None) == (name in READINGS_FREE), name
    # A gyro scale's signature is the measured rate: each draw's own noise.
    assert sig["gyro_scale"]["nav"] is None and sig["gyro_scale"]["dyn"] is None
    assert sig["thrust_loss"]["dyn"].shape[2] == prepare(log).valves.shape[1]


def test_null_runs_with_the_shared_jacobians_keep_their_statistics(flight):
    log, prepared = flight
    shared = log_null.shared_signatures(log, prepared, 99)
    for seed in (1, 2, 3):
        null = log_null.null_log_like(log, seed, prepared)
        own, with_shared = null_statistics(null), null_statistics(null, shared)
        assert with_shared["map_max_abs_z"] == own["map_max_abs_z"]  # the map needs no Jacobian
        assert with_shared["screen_logp"] == pytest.approx(own["screen_logp"], abs=0.1)
        assert log_null.null_run(seed, (log, prepared, 99)) == {"seed": seed, **with_shared}


def test_jacobians_of_another_shape_are_not_used(flight):
    log, prepared = flight
    shared = log_null.shared_signatures(log, prepared, 99)
    shorter = {n: {k: (None if v is None else v[:-1]) for k, v in s.items()} for n, s in shared.items()}
    null = log_null.null_log_like(log, 1, prepared)
    assert null_statistics(null, shorter) == null_statistics(null)
