"""Batch maximum-likelihood reference for the modal filter.

Given the coarse modal estimates of every image so far (eq. 4) and their
covariances, fit each mode's frequency and its cosine and sine amplitudes
over all images at once: one weighted nonlinear least squares whose weights
are the coarse covariances (modes coupled exactly, as in the joint filter),
with the filter's a priori frequencies as a Gaussian penalty. The amplitude
at the last image follows from the fit.

This is the estimator a recursive filter approximates: it sees the same data
and the same prior but keeps the whole history instead of a Gaussian summary.
Where the filter's shape error is within run-to-run noise of this one, the
filter is not what limits convergence; the data are.

Undamped modes (the plate's): a(t) = c cos(w t) + s sin(w t).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares


def _whiteners(cov):
    """W_k with W_k^T W_k = cov_k^-1, so ||W_k r||^2 = r^T cov_k^-1 r."""
    info = np.linalg.inv(np.asarray(cov, float))
    return np.swapaxes(np.linalg.cholesky(info), 1, 2)


def _grid_start(coarse, var, t, w_prior, sigma_w, n_grid):
    """Per mode, the frequency on a grid over +-3 sigma that best explains that
    mode's coarse series alone (cosine and sine solved linearly): a global
    start, since the modes are only weakly coupled through the covariance."""
    m = coarse.shape[1]
    w0 = np.empty(m)
    for i in range(m):
        grid = w_prior[i] + sigma_w[i] * np.linspace(-3.0, 3.0, n_grid)
        wt = np.sqrt(1.0 / var[:, i])
        best = np.inf
        for w in grid:
            basis = np.c_[np.cos(w * t), np.sin(w * t)] * wt[:, None]
            y = coarse[:, i] * wt
            sol, *_ = np.linalg.lstsq(basis, y, rcond=None)
            cost = np.sum((basis @ sol - y) ** 2) + ((w - w_prior[i]) / sigma_w[i]) ** 2
            if cost < best:
                best, w0[i] = cost, w
    return w0


def fit(coarse, cov, t, w_prior, sigma_w, extra_starts=(), n_grid=201):
    """Batch ML fit. coarse (K, m), cov (K, m, m), t (K,) [s]; w_prior and
    sigma_w (m,) [rad/s]. Images whose coarse estimate is not finite are left
    out. Returns dict with omega (m,), amplitude at t[-1] (m,), cost (half the
    weighted sum of squares) and the start that won."""
    coarse = np.asarray(coarse, float)
    cov = np.asarray(cov, float)
    t = np.asarray(t, float)
    w_prior = np.asarray(w_prior, float)
    sigma_w = np.asarray(sigma_w, float)
    t_end = float(t[-1])
    ok = np.all(np.isfinite(coarse), axis=1) & np.all(np.isfinite(cov), axis=(1, 2))
    coarse, cov, t = coarse[ok], cov[ok], t[ok]
    if coarse.shape[0] < 3:
        raise ValueError("batch ML needs at least 3 images with a coarse estimate")
    m = coarse.shape[1]
    wh = _whiteners(cov)

    def residual(x):
        w, c, s = x[:m], x[m:2 * m], x[2 * m:]
        pred = np.cos(np.outer(t, w)) * c + np.sin(np.outer(t, w)) * s
        r = np.einsum("kij,kj->ki", wh, pred - coarse)
        return np.concatenate([r.ravel(), (w - w_prior) / sigma_w])

    def linear_amplitudes(w):
        # cosine and sine amplitudes for fixed frequencies: weighted linear LS
        basis = np.concatenate([np.cos(np.outer(t, w))[:, None, :] * np.eye(m)[None],
                                np.sin(np.outer(t, w))[:, None, :] * np.eye(m)[None]], axis=2)
        a = np.einsum("kij,kjl->kil", wh, basis).reshape(-1, 2 * m)
        y = np.einsum("kij,kj->ki", wh, coarse).ravel()
        sol, *_ = np.linalg.lstsq(a, y, rcond=None)
        return sol

    var = np.diagonal(cov, axis1=1, axis2=2)
    starts = [("grid", _grid_start(coarse, var, t, w_prior, sigma_w, n_grid)), ("prior", w_prior)]
    starts += [(name, np.asarray(w, float)) for name, w in extra_starts]
    best = None
    for name, w0 in starts:
        x = least_squares(residual, np.concatenate([w0, linear_amplitudes(w0)]), method="trf").x
        cost = 0.5 * float(np.sum(residual(x) ** 2))
        if best is None or cost < best[0]:
            best = (cost, x, name)
    cost, x, name = best
    w, c, s = x[:m], x[m:2 * m], x[2 * m:]
    return {"omega": w, "amplitude_end": c * np.cos(w * t_end) + s * np.sin(w * t_end),
            "cost": cost, "start": name, "n_images": int(coarse.shape[0])}
