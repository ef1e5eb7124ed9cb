"""A straightforward numpy implementation of the modal estimator's per-image
work, for the timing comparison with the flight code: decomposition
(eqs. 2-4b with the condition number), then one step of the decoupled bank
(M 4-state UKFs, vectorised over modes) or of the joint 4M-state UKF.
Same equations, same unscented transform (alpha 1, beta 2, kappa 0)."""

from __future__ import annotations

import time

import numpy as np


def decompose(phi, z, sigma_e):
    my = phi.T @ phi
    b = phi.T @ z
    ev = np.linalg.eigvalsh(my)
    cond = ev[-1] / ev[0]
    inv = np.linalg.inv(my)
    return inv @ b, sigma_e**2 * inv, cond


def propagate(x, dt):
    """Eq. 5 on arrays whose first axis is [A, V, omega, alpha]."""
    a, v, w, al = x[0], x[1], x[2], x[3]
    e = np.exp(-dt * al)
    c = np.cos(dt * w)
    sw = dt * np.sinc(dt * w / np.pi)
    return np.stack([e * (a * c + (v + al * a) * sw), e * (v * c - (al * v + (w * w + al * al) * a) * sw), w, al])


class Bank:
    def __init__(self, a0, cov_a, omega, sv, sw, sa, q):
        m = a0.size
        self.x = np.stack([a0, np.zeros(m), omega, np.zeros(m)], axis=1)  # (M, 4)
        self.P = np.zeros((m, 4, 4))
        self.P[:, 0, 0] = np.diag(cov_a)
        self.P[:, 1, 1], self.P[:, 2, 2], self.P[:, 3, 3] = sv**2, sw**2, sa**2
        self.q = q  # (M, 4)

    def step(self, dt, a_meas, cov_a):
        n = 4
        g = np.sqrt(n)
        L = np.linalg.cholesky(self.P)  # (M, 4, 4)
        X = np.concatenate([self.x[:, :, None], self.x[:, :, None] + g * L, self.x[:, :, None] - g * L], axis=2)
        Y = propagate(np.moveaxis(X, 1, 0), dt)  # (4, M, 9)
        Y = np.moveaxis(Y, 0, 1)  # (M, 4, 9)
        xm = Y[:, :, 1:].mean(axis=2)  # wm0 = 0
        D = Y - xm[:, :, None]
        P = 2.0 * np.einsum("mi,mj->mij", D[:, :, 0], D[:, :, 0]) + np.einsum(
            "mik,mjk->mij", D[:, :, 1:], D[:, :, 1:]
        ) / (2 * n)
        P += np.einsum("mi,ij->mij", self.q * dt, np.eye(4))
        s = P[:, 0, 0] + np.diag(cov_a)
        k = P[:, :, 0] / s[:, None]
        nu = a_meas - xm[:, 0]
        self.x = xm + k * nu[:, None]
        self.P = P - np.einsum("mi,mj->mij", k, P[:, :, 0])


class Joint:
    def __init__(self, a0, cov_a, omega, sv, sw, sa, q):
        m = a0.size
        self.m = m
        self.x = np.stack([a0, np.zeros(m), omega, np.zeros(m)], axis=1).ravel()
        self.P = np.zeros((4 * m, 4 * m))
        self.P[0::4, 0::4] = cov_a
        i = np.arange(m) * 4
        self.P[i + 1, i + 1], self.P[i + 2, i + 2], self.P[i + 3, i + 3] = sv**2, sw**2, sa**2
        self.q = q.ravel()

    def step(self, dt, a_meas, cov_a):
        N = 4 * self.m
        L = np.linalg.cholesky(self.P)
        g = np.sqrt(N)
        X = np.concatenate([self.x[:, None], self.x[:, None] + g * L, self.x[:, None] - g * L], axis=1)
        Y = propagate(X.reshape(self.m, 4, -1).transpose(1, 0, 2), dt).transpose(1, 0, 2).reshape(N, -1)
        xm = Y[:, 1:].mean(axis=1)
        D = Y - xm[:, None]
        P = 2.0 * np.outer(D[:, 0], D[:, 0]) + (D[:, 1:] @ D[:, 1:].T) / (2 * N)
        P[np.diag_indices(N)] += self.q * dt
        pxa = P[:, 0::4]
        s = pxa[0::4] + cov_a
        kt = np.linalg.solve(s, pxa.T)
        self.x = xm + kt.T @ (a_meas - xm[0::4])
        self.P = P - pxa @ kt


def time_cell(m, n, kind, repeats=9, seed=1, min_time=0.05):
    """Median seconds per image (decomposition + one filter step)."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(size=n), rng.uniform(size=n)
    p = 1 + np.arange(m) % 7
    q = 1 + np.arange(m) // 7
    phi = np.sin(p * np.pi * x[:, None]) * np.sin(q * np.pi * y[:, None])
    z = phi @ (0.1 * np.cos(np.arange(m))) + 0.01 * rng.standard_normal(n)
    omega = 0.01 * (1 + np.arange(m))
    a, cov, _ = decompose(phi, z, 0.01)
    qv = np.tile([1e-8, 1e-10, 0.0, 0.0], (m, 1))
    f = (Bank if kind == "bank" else Joint)(a, cov, omega, omega, 0.1 * omega, 1e-5, qv)
    times = []
    for _ in range(repeats):
        k, t0 = 0, time.perf_counter()
        while True:
            a, cov, _ = decompose(phi, z, 0.01)
            f.step(60.0, a, cov)
            k += 1
            if time.perf_counter() - t0 >= min_time:
                break
        times.append((time.perf_counter() - t0) / k)
    return float(np.median(times))
