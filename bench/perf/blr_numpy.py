"""The flight code's BLR step (fsw/thrusters/blr.hpp) written with numpy, as the
reference point for its timing: the same ring buffer, running sums and
additions-only shadow sums, the same Cholesky-based prediction."""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular


class NumpyBlr:
    def __init__(self, d: int = 9, k: int = 6, window: int = 30, prior_precision: float = 1e-3):
        self.d, self.k, self.w, self.lam = d, k, window, prior_precision
        self.xs = np.zeros((window, d))
        self.ys = np.zeros((window, k))
        self.head = self.count = self.pre_epoch = 0
        self.run = [np.zeros((d, d)), np.zeros((d, k)), np.zeros(k)]
        self.fresh = [np.zeros((d, d)), np.zeros((d, k)), np.zeros(k)]
        self.dirty = True
        self.cf = None
        self.theta = np.zeros((d, k))
        self.sigma2 = np.ones(k)

    @staticmethod
    def _acc(s, x, y, sign):
        s[0] += sign * np.outer(x, x)
        s[1] += sign * np.outer(x, y)
        s[2] += sign * y * y

    def remove_oldest(self):
        slot = self.head
        self.head = (self.head + 1) % self.w
        self.count -= 1
        self.dirty = True
        if self.count == 0:
            for s in (self.run, self.fresh):
                for a in s:
                    a[...] = 0.0
            self.pre_epoch = 0
            return
        self._acc(self.run, self.xs[slot], self.ys[slot], -1.0)
        if self.pre_epoch == 0:
            for a in self.fresh:
                a[...] = 0.0
            self.pre_epoch = self.count
            return
        self.pre_epoch -= 1
        if self.pre_epoch == 0:
            self.run = [a.copy() for a in self.fresh]
            for a in self.fresh:
                a[...] = 0.0
            self.pre_epoch = self.count

    def add(self, x, y):
        if not (np.isfinite(x).all() and np.isfinite(y).all()):
            return False
        if self.count == self.w:
            self.remove_oldest()
        slot = (self.head + self.count) % self.w
        self.xs[slot] = x
        self.ys[slot] = y
        self.count += 1
        self._acc(self.run, x, y, 1.0)
        self._acc(self.fresh, x, y, 1.0)
        self.dirty = True
        return True

    def predict(self, x):
        if self.dirty:
            a = self.run[0] + self.lam * np.eye(self.d)
            self.cf = cho_factor(a, lower=True)
            self.theta = cho_solve(self.cf, self.run[1])
            if self.count > self.d:
                rss = self.run[2] - (self.run[1] * self.theta).sum(axis=0)
                self.sigma2 = np.maximum(rss, 0.0) / (self.count - self.d)
            self.dirty = False
        u = solve_triangular(self.cf[0], x, lower=True)
        lev = u @ u
        return self.theta.T @ x, self.sigma2 * (1.0 + lev)
