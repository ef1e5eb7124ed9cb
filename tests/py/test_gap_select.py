"""The joint refit of a selected set (bench/gap/select.py confirm_set): a set
of dynamics-only members is refitted as one such candidate alone is, so one
effect has the same angles and sigmas ranked alone and as a one-member set,
and a nozzle tilt's turn about its own thrust axis, which the data do not
see, stays where it starts."""

from copy import copy

import numpy as np
import pytest


@pytest.fixture(scope="module")
def bundled_fits():
    from bench.gap import bundled
    from bench.gap.attribute import screen
    from bench.gap.detection import pass_from
    from bench.gap.dyn import build
    from bench.gap.load import resolve
    from bench.gap.quantify import split_context
    from bench.gap.replay import reference
    from bench.sim.flight_log import read_flight_log

    _, d = resolve(read_flight_log(bundled.LOG, relative_time=True))
    ctx = split_context(d, pass_from(reference(d), d), build(d))
    return ctx, screen(ctx)


def _alone(ctx, fits, name):
    from bench.gap.attribute import confirm

    return confirm(ctx, copy(next(f for f in fits if f.name == name)))


def test_a_nozzle_tilt_as_a_one_member_set_is_the_tilt_alone(bundled_fits):
    """The bundled log's nozzle tilt refitted as a set drifted along the
    turns about the thrust axes to the 0.5 rad bound, with sigmas up to
    1.6e3 rad from the finite differences' residue there."""
    from bench.gap import select
    from bench.gap.verdict import parameters

    ctx, fits = bundled_fits
    name = "thruster_misalignment"
    f = _alone(ctx, fits, name)
    sf = select.confirm_set(ctx, [name], fits)
    assert np.allclose(sf.theta[name], f.theta, atol=1e-8)
    assert np.allclose(sf.sigma[name], f.sigma, rtol=1e-6)
    assert np.abs(sf.theta[name]).max() < 0.1 and sf.sigma[name].max() < 0.05
    assert all(v["identified"] for v in parameters(ctx, name, sf.theta[name], sf.sigma[name]).values())


def test_a_loss_beside_a_tilt_keeps_its_bound_and_the_tilt_its_place(bundled_fits):
    """A thrust loss and a nozzle tilt together: the losses stay >= 0 by
    bounded steps (clipped minimum-norm steps stopped at a training
    log-likelihood gain of 2223, below the loss's 2846 alone), and the tilt
    does not drift to its bound."""
    from bench.gap import select
    from bench.gap.verdict import parameters

    ctx, fits = bundled_fits
    sf = select.confirm_set(ctx, ["thrust_loss", "thruster_misalignment"], fits)
    assert sf.dll_train >= _alone(ctx, fits, "thrust_loss").dll_train
    assert sf.theta["thrust_loss"].min() >= 0.0 and np.abs(sf.theta["thruster_misalignment"]).max() < 0.1
    tilt = parameters(
        ctx, "thruster_misalignment", sf.theta["thruster_misalignment"], sf.sigma["thruster_misalignment"]
    )
    assert all(v["identified"] for v in tilt.values())
