"""The batch maximum-likelihood reference for the modal filter: it recovers
known frequencies from synthetic coarse estimates (starting 7-9 % off), skips
images without an estimate, refuses too little data, and on a plate run sits
beside the flight filter."""

import numpy as np
import pytest

from bench.campaigns import modal_batch_ml


def _synthetic(seed, k=100, dt=60.0):
    rng = np.random.default_rng(seed)
    w = np.array([0.0030, 0.0061, 0.0112])
    c, s = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
    t = np.arange(k) * dt
    truth = np.cos(np.outer(t, w)) * c + np.sin(np.outer(t, w)) * s
    b = 0.05 * rng.standard_normal((3, 3))
    cov = np.broadcast_to(b @ b.T + 0.03**2 * np.eye(3), (k, 3, 3)).copy()
    noise = np.einsum("ij,kj->ki", np.linalg.cholesky(cov[0]), rng.standard_normal((k, 3)))
    return t, w, truth, truth + noise, cov, np.hypot(c, s)


def _omega_tol(cov, amp, n, dt):
    """Four times the Cramer-Rao bound of one sinusoid's frequency from n
    evenly spaced samples: sqrt(12) sigma / (A n^1.5 dt)."""
    return 4 * np.sqrt(12) * np.sqrt(np.diag(cov[0])) / (amp * n**1.5 * dt)


def test_recovers_frequencies_and_final_amplitude():
    t, w, truth, coarse, cov, amp = _synthetic(1)
    prior = w * np.array([1.08, 0.91, 1.07])
    ml = modal_batch_ml.fit(coarse, cov, t, prior, 0.1 * prior)
    assert np.all(np.abs(ml["omega"] - w) < _omega_tol(cov, amp, len(t), 60.0))
    sigma = np.sqrt(np.diag(cov[0]))
    assert np.all(np.abs(ml["amplitude_end"] - truth[-1]) < 3 * sigma)
    # the fit is a least-squares optimum: its cost is no more than at the truth
    assert (
        ml["cost"] <= modal_batch_ml.fit(coarse, cov, t, prior, 0.1 * prior, extra_starts=[("truth", w)])["cost"] + 1e-6
    )


def test_images_without_an_estimate_are_left_out_and_too_few_refused():
    t, w, truth, coarse, cov, amp = _synthetic(2)
    coarse[10] = np.nan
    cov[20, 0, 0] = np.inf
    ml = modal_batch_ml.fit(coarse, cov, t, w, 0.1 * w)
    assert ml["n_images"] == len(t) - 2
    assert np.all(np.abs(ml["omega"] - w) < _omega_tol(cov, amp, len(t) - 2, 60.0))
    with pytest.raises(ValueError, match="at least 3 images"):
        modal_batch_ml.fit(coarse[:2], cov[:2], t[:2], w, 0.1 * w)


fb = pytest.importorskip("fsw_bindings")


@pytest.mark.skipif(not hasattr(fb, "ModalDecomposition10"), reason="bindings built without the modal estimator")
def test_plate_run_compares_filter_with_batch_ml():
    from bench.campaigns import modal_campaign as mc

    tr = mc.plate_trial(0, n_modes=10, kind="joint", n_images=41, batch_ml_periods=(1.0,))
    (row,) = tr["batch_ml"]
    assert row["images"] == 41 and row["periods"] == pytest.approx(1.0)
    # the same data and prior: neither is far from the other after one period
    assert 0.5 < row["shape_rms_filter_m"] / row["shape_rms_batch_ml_m"] < 2.0
    assert row["freq_rel_err_max_excited_batch_ml"] < 0.05
    with pytest.raises(ValueError, match="needs 81 images; the run has 41"):
        mc.plate_trial(0, n_modes=10, kind="joint", n_images=41, batch_ml_periods=(2.0,))


def test_cli_structure_with_range_noise_and_batch_ml(tmp_path, capsys):
    import json

    from bench import cli

    out = tmp_path / "s.json"
    assert (
        cli.main(
            [
                "modal",
                "--scenario",
                "structure",
                "--modes",
                "10",
                "--trials",
                "1",
                "--images",
                "41",
                "--filter",
                "joint",
                "--range-noise",
                "0.01",
                "--batch-ml-at",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    d = json.loads(out.read_text())
    assert d["range_noise"] == 0.01
    (row,) = d["batch_ml_summary"]
    assert row["trials"] == 1 and row["images"] == 41
    assert "filter / batch ML" in capsys.readouterr().out
    assert cli.main(["modal", "--scenario", "structure", "--range-noise", "0"]) == 2
    assert "argument --range-noise: must be a finite number > 0 and < 1" in capsys.readouterr().err


def test_end_error_ratio_is_near_the_cramer_rao_ratio():
    # One mode, 80 samples: the batch fit without the frequency against least
    # squares with it, at the last sample. sqrt(2.5) = 1.58 for large n (1.55
    # over 4000 runs); 400 runs have a sampling spread of about 0.08.
    r = modal_batch_ml.end_error_ratio(runs=400, seed=1)
    assert 1.3 < r["ratio"] < 1.8


def test_analytic_jacobian_equals_finite_differences():
    from scipy.optimize._numdiff import approx_derivative

    t, w, truth, coarse, cov, amp = _synthetic(2, k=30)
    wh = modal_batch_ml.whiteners(cov)
    residual, jacobian = modal_batch_ml._residual_and_jacobian(wh, coarse, t, w, 0.1 * w)
    x = np.concatenate([w * 1.03, [0.3, -0.2, 0.5], [0.1, 0.4, -0.6]])
    # absolute steps: the frequency's default step (relative to max(1, |x|))
    # would be 1e3 times the frequency's own scale
    num = approx_derivative(residual, x, method="3-point", abs_step=np.r_[1e-9 * np.ones(3), 1e-6 * np.ones(6)])
    np.testing.assert_allclose(jacobian(x), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


def test_relax_start_uses_the_coupled_weights_where_a_per_mode_grid_cannot():
    # Three modes whose coarse errors share one large common component (an
    # ill-conditioned M_Y): each mode's own series is mostly that component,
    # but conditioned on the others its noise is 0.01.
    rng = np.random.default_rng(7)
    k, dt = 100, 60.0
    w = np.array([0.0030, 0.0061, 0.0112])
    c, s = np.array([0.6, -0.5, 0.4]), np.array([0.3, 0.7, -0.5])
    t = np.arange(k) * dt
    u = np.ones(3) / np.sqrt(3)
    cov1 = 30.0**2 * np.outer(u, u) + 0.01**2 * np.eye(3)
    cov = np.broadcast_to(cov1, (k, 3, 3)).copy()
    truth = np.cos(np.outer(t, w)) * c + np.sin(np.outer(t, w)) * s
    coarse = truth + rng.standard_normal((k, 3)) @ np.linalg.cholesky(cov1).T
    w_prior = w * np.array([1.08, 0.93, 1.06])
    sigma_w = 0.1 * w_prior
    var = np.diagonal(cov, axis1=1, axis2=2)
    w_grid = modal_batch_ml.grid_start(coarse, var, t, w_prior, sigma_w, 201)
    w_relax = modal_batch_ml.relax_start(coarse, np.linalg.inv(cov), t, w_prior, sigma_w, w_grid, 201)
    assert np.max(np.abs(w_grid / w - 1)) > 0.02  # the per-mode grid is lost in the common component
    assert np.max(np.abs(w_relax / w - 1)) < 0.005  # one grid step is 0.3 % of the prior
    # the coupled weights are what does it: with the diagonal alone RELAX is as lost as the grid
    diag_info = np.broadcast_to(np.diag(1.0 / np.diag(cov1)), (k, 3, 3))
    w_relax_diag = modal_batch_ml.relax_start(coarse, diag_info, t, w_prior, sigma_w, w_grid, 201)
    assert np.max(np.abs(w_relax_diag / w - 1)) > 0.02
    ml = modal_batch_ml.fit(coarse, cov, t, w_prior, sigma_w, reference_starts=[("truth", w)])
    assert np.max(np.abs(ml["omega"] / w - 1)) < 1e-3
    # from the truth the descent reaches the same optimum (no lower one was missed)
    assert ml["reference"]["truth"]["cost"] == pytest.approx(ml["cost"], rel=1e-6)
