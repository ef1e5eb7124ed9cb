"""The confirmed fits' sigmas (bench/gap/attribute.py): a parameter the
bounded fit holds at a physical bound is held there, and the free ones'
covariance comes from their own Jacobian columns."""

import numpy as np
import pytest


def test_a_parameter_within_the_tolerance_of_a_bound_is_at_it():
    from bench.gap.attribute import BOUND_TOL, at_bounds

    lo, hi = np.array([0.0, 0.0, -5.0, -np.inf]), np.array([9.0, 9.0, 5.0, np.inf])
    assert at_bounds([4.45e-14, 2 * BOUND_TOL, 5.0 - 1e-9, -1e9], lo, hi).tolist() == [-1, 0, 1, 0]


def test_the_free_parameters_covariance_leaves_out_the_held_ones():
    """Two columns nearly alike (two valves fired as a couple): with the
    second held at its bound, the first's sigma is its own column's, not
    the pair's."""
    from bench.gap.attribute import fit_sigma

    rng = np.random.default_rng(3)
    a = rng.standard_normal(400)
    J = np.column_stack([a, a + 0.1 * rng.standard_normal(400), rng.standard_normal(400)])
    u = np.array([0.6, 1e-13, 0.2])
    s = fit_sigma(J, u, 0.0, 9.0)
    full = np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    free = np.sqrt(np.diag(np.linalg.inv(J[:, [0, 2]].T @ J[:, [0, 2]])))
    assert np.allclose(s[[0, 2]], free) and s[1] == pytest.approx(full[1])
    assert s[0] < full[0] / 5
    # nothing held: the full covariance, as before
    assert np.allclose(fit_sigma(J, np.array([0.6, 0.3, 0.2]), 0.0, 9.0), full)


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


def test_the_bundled_loss_held_at_zero_leaves_the_others_sigmas_their_own(bundled_fits):
    """The bundled log's thrust loss: valve 4's loss held at 0 (fired in a
    couple with valve 0, their signatures 0.99 alike); the others' sigmas
    from their own columns (valve 3's 0.0063, not the 0.0106 the held one's
    column gave it; redrawing the noise and refitting spreads it by 0.0070)."""
    from copy import copy

    from bench.gap.attribute import candidate, confirm
    from bench.gap.verdict import parameters

    ctx, fits = bundled_fits
    f = confirm(ctx, copy(next(f for f in fits if f.name == "thrust_loss")))
    c = candidate(ctx.d, "thrust_loss")
    p = parameters(ctx, "thrust_loss", f.theta, f.sigma)
    assert [k for k, v in p.items() if v.get("at_bound") == "lower"] == ["loss_4 [1]"]
    assert p["loss_4 [1]"]["sigma"] is None
    J = ctx.ch.jacobian("thrust_loss")[ctx.train_dyn].reshape(-1, c.n_params)
    free = [0, 1, 2, 3, 5, 6, 7]
    own = np.sqrt(np.diag(np.linalg.inv(J[:, free].T @ J[:, free])))
    assert np.allclose(f.sigma[free], own, rtol=1e-6)
    assert p["loss_3 [1]"]["sigma"] == pytest.approx(0.0063, abs=5e-4)
