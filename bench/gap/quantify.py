"""How big the gap is, before and after a candidate is added, on data the fit
never saw.

Split: time is cut into blocks, alternate blocks train and the others are
held out: ``N_BLOCKS`` equal blocks, even ones training, unless that leaves
a valve the log fires without firing in one half; then the blocking
(``excitation_split``: another number of blocks, edges shifted, the other
parity) that excites every fired valve in both halves. A valve no blocking
can give to both (fired only in one short window) is named: its
parameters are not identifiable from the log. The filter still runs
over the whole log (it is sequential), but the parameters are fitted only on
training innovations, and held-out innovations are one-step predictions the
fit never used.

Deficit against the null: for a consistent model E[NIS] = 6 per update, so
    D = 1/2 sum_held-out (NIS_k - 6)
is the log-likelihood the model loses to a perfect one beyond the noise
(it is 0 on average for simulated-on-simulated logs). The shrink of a
candidate is 1 - D_after / D_before, with a bootstrap interval over 5 s
chunks of held-out time. D has a null spread of sqrt(k n / 2) (k residuals
per row, n rows): when D_before is within two of those the gap is too small
for a shrink to be measured on the held-out data ("measurable": false), and
the held-out log-likelihood gain is the evidence that remains.

Where the gap lies: the deficit is summed over the cells (pose updates;
accelerometer while firing; accelerometer while coasting; gyro) whose
training-block deficit under the nominal model stands out of its null
spread (gap_cells). A thrust effect leaves the coasting accelerometer rows
and the pose updates at the null; summing them would only add their noise
(a null spread of 30 to the deficit of a gap of 20 near the detection
limit). The cells are chosen on the training blocks, before any candidate is
fitted, and are the same for every candidate, right or wrong.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

N_BLOCKS = 6
BOOT = 400
BOOT_BLOCK = 5


def block_edges(t0: float, t1: float, n_blocks: int = N_BLOCKS) -> np.ndarray:
    return np.linspace(t0, t1 + 1e-9, n_blocks + 1)


def split_blocks(t: np.ndarray, n_blocks: int = N_BLOCKS, edges: np.ndarray | None = None):
    """(train mask, held-out mask) over rows with times t: even blocks train."""
    if t.size == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    if edges is None:
        edges = block_edges(t[0], t[-1], n_blocks)
    n_blocks = edges.size - 1
    b = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, n_blocks - 1)
    return b % 2 == 0, b % 2 == 1


@dataclass
class Split:
    """The training / held-out split of a log's time: blocks between
    ``edges``, those of parity ``train_parity`` train. ``unexcited``: the
    valves that fire but not in both halves, each with why (their
    parameters cannot be fitted on one half and checked on the other)."""

    edges: np.ndarray
    train_parity: int = 0
    unexcited: list = field(default_factory=list)
    fired_s: np.ndarray | None = None  # (K, 2) each valve's open seconds in training and held-out time

    def masks(self, t: np.ndarray) -> tuple:
        """(train mask, held-out mask) over rows with times t."""
        if t.size == 0:
            return np.zeros(0, bool), np.zeros(0, bool)
        n = self.edges.size - 1
        b = np.clip(np.searchsorted(self.edges, t, side="right") - 1, 0, n - 1)
        return b % 2 == self.train_parity, b % 2 != self.train_parity


# The blockings tried: so many blocks, their inner edges shifted by this
# share of a block, either parity training. The first (six even blocks)
# is kept whenever it excites every fired valve in both halves.
SPLIT_BLOCKS = (6, 4, 8, 10, 12, 5, 7, 9, 14, 16)
SPLIT_PHASES = (0.0, 0.5, 0.25, 0.75)
MIN_SHARE = 0.2  # each fired valve: at least this share of its open time in each half, if any blocking gives it


def _blocking(t0: float, t1: float, n: int, phase: float) -> np.ndarray:
    inner = t0 + (np.arange(1, n) - phase) * (t1 - t0) / n
    return np.concatenate([[t0], inner[inner > t0], [t1 + 1e-9]])


def excitation_split(t: np.ndarray, fired_s: np.ndarray | None) -> Split:
    """The split of time (IMU sample times ``t``, ``fired_s`` (N, K) each
    valve's open seconds in each sample's interval, or None) whose halves
    both excite every valve the log fires: of the blockings tried, the one
    that excites the most valves in both halves, then has the largest
    smallest share of a valve's firing in either half (up to MIN_SHARE),
    then the fewest blocks, then the most even halves. A valve fired only inside one short window stays unexcited in
    one half whatever the blocking; it is named, with its firing times."""
    t0, t1 = float(t[0]), float(t[-1])
    if fired_s is None or not np.any(fired_s > 0.0):
        return Split(block_edges(t0, t1))
    total = fired_s.sum(axis=0)
    fired = total > 0.0

    def scored(edges, parity) -> tuple:
        sp = Split(edges, parity)
        tr, ho = sp.masks(t)
        sp.fired_s = np.stack([fired_s[tr].sum(axis=0), fired_s[ho].sum(axis=0)], axis=1)
        share = (sp.fired_s.min(axis=1) / np.where(fired, total, 1.0))[fired]
        # Fewer blocks first: a long block keeps a firing with the coast
        # after it, where a rate change shows held.
        return (
            int(np.sum(share > 0.0)),
            float(min(share.min(), MIN_SHARE)),
            -(edges.size - 1),
            -abs(tr.mean() - 0.5),
        ), sp

    key, best = scored(block_edges(t0, t1), 0)
    if key[0] < fired.sum() or key[1] < MIN_SHARE:
        for n in SPLIT_BLOCKS:
            for phase in SPLIT_PHASES:
                for parity in (0, 1):
                    k, sp = scored(_blocking(t0, t1, n, phase), parity)
                    if k > key:
                        key, best = k, sp
    for i in np.flatnonzero(fired & (best.fired_s.min(axis=1) <= 0.0)):
        on = np.flatnonzero(fired_s[:, i] > 0.0)
        a, b = f"{t[on[0]] - t0:.0f}", f"{t[on[-1]] - t0:.0f}"
        side = "held-out" if best.fired_s[i, 0] > 0.0 else "training"
        when = f"at {a} s" if a == b else f"at {a}-{b} s"
        best.unexcited.append({"valve": int(i), "why": f"thruster {i} fired only {when}, never in the {side} time"})
    return best


def deficit(nis: np.ndarray) -> float:
    return float(0.5 * np.sum(nis - 6.0))


def _block_indices(n: int, rng: np.random.Generator, block: int = BOOT_BLOCK) -> np.ndarray:
    nb = int(np.ceil(n / block))
    starts = rng.integers(0, max(1, n - block + 1), nb)
    return (starts[:, None] + np.arange(block)[None, :]).ravel()[:n]


def shrink(nis_before: np.ndarray, nis_after: np.ndarray, seed: int = 0) -> dict:
    """Shrink fraction of the held-out deficit with a 95 % bootstrap interval."""
    d0, d1 = deficit(nis_before), deficit(nis_after)
    frac = 1.0 - d1 / d0 if d0 > 0 else float("nan")
    rng = np.random.default_rng(seed)
    n = nis_before.size
    boots = []
    for _ in range(BOOT if n >= BOOT_BLOCK else 0):
        i = _block_indices(n, rng)
        b0 = deficit(nis_before[i])
        if b0 > 0:
            boots.append(1.0 - deficit(nis_after[i]) / b0)
    lo, hi = np.percentile(boots, [2.5, 97.5]) if len(boots) > 20 else (float("nan"), float("nan"))
    return {
        "fraction": float(frac),
        "ci95": [float(lo), float(hi)],
        "deficit_before": d0,
        "deficit_after": d1,
        "n_heldout": int(n),
    }


CHUNK_S = 5.0
MAX_CI_WIDTH = 1.0  # a shrink interval wider than this (100 points) is no measurement


def shrink_combined(
    t_nav,
    nis_before,
    nis_after,
    t_dyn=None,
    q_before=None,
    q_after=None,
    seed: int = 0,
    cells: list | None = None,
    lab_dyn=None,
) -> dict:
    """Shrink of the held-out deficit over both channels, the navigation
    updates (1/2 (NIS - 6)) and the dynamics rows (1/2 (|e|^2 - 3)), with a
    95 % bootstrap interval over 5 s chunks of held-out time. ``cells``
    (from gap_cells, with ``lab_dyn`` the held-out dynamics rows' cells):
    only those cells count; None or empty: all."""
    if cells:
        if CELL_NAV not in cells:
            t_nav, nis_before, nis_after = t_nav[:0], nis_before[:0], nis_after[:0]
        if t_dyn is not None and q_before is not None:
            keep = np.isin(lab_dyn, cells)
            t_dyn, q_before, q_after = t_dyn[keep], q_before[keep], q_after[keep]
    parts_t = [np.asarray(t_nav, float)]
    b = [0.5 * (np.asarray(nis_before) - 6.0)]
    a = [0.5 * (np.asarray(nis_after) - 6.0)]
    if t_dyn is not None and q_before is not None:
        parts_t.append(np.asarray(t_dyn, float))
        b.append(0.5 * (np.asarray(q_before) - 3.0))
        a.append(0.5 * (np.asarray(q_after) - 3.0))
    t = np.concatenate(parts_t)
    cb, ca = np.concatenate(b), np.concatenate(a)
    ok = np.isfinite(cb) & np.isfinite(ca)
    t, cb, ca = t[ok], cb[ok], ca[ok]
    d0, d1 = float(cb.sum()), float(ca.sum())
    frac = 1.0 - d1 / d0 if d0 > 0 else float("nan")
    # The deficit's spread under the null: var(1/2 (chi2_k - k)) = k / 2 per row.
    dof = np.concatenate(
        [np.full(np.asarray(nis_before).size, 6.0)]
        + ([np.full(np.asarray(q_before).size, 3.0)] if (t_dyn is not None and q_before is not None) else [])
    )[ok]
    sd0 = float(np.sqrt(0.5 * dof.sum()))
    base = {
        "deficit_before": d0,
        "deficit_after": d1,
        "deficit_null_sd": sd0,
        "measurable": bool(d0 > 2.0 * sd0),
        "cells": [CELL_NAMES[c] for c in cells] if cells else "all",
    }
    if t.size == 0:
        return {"fraction": frac, "ci95": [float("nan")] * 2, **base, "n_chunks": 0}
    chunk = np.floor((t - t.min()) / CHUNK_S).astype(int)
    ids, inv = np.unique(chunk, return_inverse=True)
    sb = np.bincount(inv, cb, ids.size)
    sa = np.bincount(inv, ca, ids.size)
    rng = np.random.default_rng(seed)
    boots = []
    if ids.size >= 4:
        idx = rng.integers(0, ids.size, (BOOT, ids.size))
        B0, B1 = sb[idx].sum(axis=1), sa[idx].sum(axis=1)
        good = B0 > 0
        boots = 1.0 - B1[good] / B0[good]
    lo, hi = np.percentile(boots, [2.5, 97.5]) if len(boots) > 20 else (float("nan"), float("nan"))
    if np.isfinite(lo) and (hi - lo > MAX_CI_WIDTH or lo < -1.0):
        # An interval wider than a shrink can mean ([-490, 105] %): the held-out
        # deficit is too small or too uneven over time to be measured.
        base["measurable"] = False
    return {"fraction": float(frac), "ci95": [float(lo), float(hi)], **base, "n_chunks": int(ids.size)}


# Deficit cells: the navigation updates, the accelerometer rows while a valve
# is open and while none is, and the gyro rows. (Whitened gyro rows are not
# split by regime: whitening the differenced gyro integrates it back, so a
# torque error made while firing stays in the coasting rows after.)
CELL_NAV, CELL_ACCEL_COAST, CELL_ACCEL_FIRE, CELL_GYRO = 0, 1, 2, 3
CELL_NAMES = {
    CELL_NAV: "pose updates",
    CELL_ACCEL_COAST: "accelerometer, coasting",
    CELL_ACCEL_FIRE: "accelerometer, firing",
    CELL_GYRO: "gyro",
}


def dyn_cell_labels(ch) -> np.ndarray:
    """The deficit cell of each row of the dynamics channel."""
    n = ch.open_.shape[0]
    lab = np.full(ch.rows, CELL_GYRO)
    lab[:n] = np.where(ch.open_.any(axis=1), CELL_ACCEL_FIRE, CELL_ACCEL_COAST)
    return lab


def gap_cells(nis_train, q_train=None, lab_train=None) -> list:
    """The cells where the nominal model's training-block deficit stands out
    of its null spread (over 2 sd): where the gap lies. The held-out shrink is
    measured over these cells only, so channels that carry nothing of the gap
    add no noise to it; they are chosen on the training blocks, before and
    independently of any candidate, and the same cells serve every candidate.
    Empty when no cell stands out (then every cell counts)."""
    out = []
    nis = np.asarray(nis_train, float)
    nis = nis[np.isfinite(nis)]
    if nis.size and 0.5 * np.sum(nis - 6.0) > 2.0 * np.sqrt(0.5 * 6.0 * nis.size):
        out.append(CELL_NAV)
    if q_train is not None:
        for c in (CELL_ACCEL_COAST, CELL_ACCEL_FIRE, CELL_GYRO):
            q = np.asarray(q_train)[lab_train == c]
            if q.size and 0.5 * np.sum(q - 3.0) > 2.0 * np.sqrt(0.5 * 3.0 * q.size):
                out.append(c)
    return out


def channel_rms(innov: np.ndarray) -> dict:
    names = ("r_x_m", "r_y_m", "r_z_m", "th_x_rad", "th_y_rad", "th_z_rad")
    return {k: float(np.sqrt(np.mean(innov[:, i] ** 2))) if innov.size else float("nan") for i, k in enumerate(names)}
