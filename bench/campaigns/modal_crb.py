"""Cramer-Rao bounds for the modal filter's problem, run by run.

The filter's measurements are the coarse modal estimates of eq. 4, one per
image, with their covariances C_k (exact, coupled across modes). For
undamped modes a_i(t) = c_i cos(w_i t) + s_i sin(w_i t), the Fisher
information of theta = (w, c, s) (3m parameters) in those estimates is

    J = sum_k D_k^T C_k^-1 D_k,   D_k = d a(t_k) / d theta   (m x 3m),

plus the a priori frequency information diag(1 / sigma_w^2) the filter is
given. J^-1 bounds the covariance of any unbiased estimator (with the prior:
of any estimator, to the extent the information at the true parameters
stands for its average over the prior). From it:

- per mode, the smallest frequency standard deviation the data allow, and
  the chance that an estimator at that bound has the frequency within 1 %;
- the smallest shape RMS error at the last image over a grid of points,
  through the amplitude a(t_end) = G theta (G = d a(t_end) / d theta), with
  the frequencies unknown (the filter's problem) and known (the floor's).

So a run's shortfall can be read against what its own data permit.
"""

from __future__ import annotations

import numpy as np
from scipy.special import erf


def _derivatives(t, omega, c, s):
    """d a_i(t_k) / d(w_i, c_i, s_i): three (K, m) arrays."""
    wt = np.outer(t, omega)
    cw, sw = np.cos(wt), np.sin(wt)
    return t[:, None] * (-c * sw + s * cw), cw, sw


def fisher(t, omega, c, s, cov, sigma_w_prior=None):
    """Fisher information (3m x 3m) of (w, c, s) in coarse estimates at times
    t (K,) [s] with covariances cov (K, m, m); sigma_w_prior (m,) [rad/s] adds
    the prior's information on the frequencies (None: no prior)."""
    t = np.asarray(t, float)
    omega, c, s = (np.asarray(v, float) for v in (omega, c, s))
    cov = np.asarray(cov, float)
    m = omega.size
    if cov.shape != (t.size, m, m):
        raise ValueError(f"cov has shape {cov.shape}; expected ({t.size}, {m}, {m})")
    info = np.linalg.inv(cov)
    d = _derivatives(t, omega, c, s)
    j = np.empty((3 * m, 3 * m))
    for a in range(3):
        for b in range(a, 3):
            blk = np.einsum("ki,kij,kj->ij", d[a], info, d[b])
            j[a * m : (a + 1) * m, b * m : (b + 1) * m] = blk
            j[b * m : (b + 1) * m, a * m : (a + 1) * m] = blk.T
    if sigma_w_prior is not None:
        j[:m, :m] += np.diag(1.0 / np.asarray(sigma_w_prior, float) ** 2)
    return j


def amplitude_jacobian(t_end, omega, c, s):
    """G = d a(t_end) / d(w, c, s), (m, 3m)."""
    d = _derivatives(np.array([float(t_end)]), np.asarray(omega, float), np.asarray(c, float), np.asarray(s, float))
    return np.concatenate([np.diag(v[0]) for v in d], axis=1)


def bound(t, omega, c, s, cov, sigma_w_prior, phi_grid, strong=None, rel_band=0.01, samples=20000, seed=0):
    """Bounds at the last image t[-1]. phi_grid (G, m): mode shapes at the
    points where the shape RMS is taken; strong (m,) bool: the modes whose
    frequencies are scored together (default: all).

    Returns the frequency bound per mode (absolute and relative), the chance
    each is within rel_band, the expected number of scored modes within it,
    the chance all of them are (Gaussian at the bound, correlations kept, by
    sampling), and the shape RMS bound with the frequencies unknown and known."""
    omega = np.asarray(omega, float)
    m = omega.size
    strong = np.ones(m, bool) if strong is None else np.asarray(strong, bool)
    j = fisher(t, omega, c, s, cov, sigma_w_prior)
    p_all = np.linalg.inv(j)
    p_all = 0.5 * (p_all + p_all.T)
    sd_w = np.sqrt(np.diag(p_all)[:m])
    p_in = erf(rel_band * omega / (sd_w * np.sqrt(2.0)))
    g = amplitude_jacobian(t[-1], omega, c, s)
    cov_a = g @ p_all @ g.T
    j_cs = j[m:, m:]
    g_cs = g[:, m:]
    cov_a_known = g_cs @ np.linalg.solve(j_cs, g_cs.T)
    phi_grid = np.asarray(phi_grid, float)

    def shape_rms(p):
        return float(np.sqrt(np.mean(np.einsum("gi,ij,gj->g", phi_grid, p, phi_grid))))

    rng = np.random.default_rng(seed)
    pw = p_all[:m, :m][np.ix_(strong, strong)]
    draws = rng.multivariate_normal(np.zeros(int(strong.sum())), pw, size=samples, method="cholesky")
    all_in = np.all(np.abs(draws) <= rel_band * omega[strong], axis=1)
    return {
        "sd_omega_radps": sd_w,
        "sd_omega_rel": sd_w / omega,
        "p_within_band": p_in,
        "expected_within_band_scored": float(np.sum(p_in[strong])),
        "n_scored": int(strong.sum()),
        "p_all_scored_within_band": float(np.mean(all_in)),
        "shape_rms_bound_m": shape_rms(cov_a),
        "shape_rms_bound_known_omega_m": shape_rms(cov_a_known),
    }
