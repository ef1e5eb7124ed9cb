"""How big the gap is, before and after a candidate is added, on data the fit
never saw.

Split: the pose updates are cut by capture time into ``N_BLOCKS`` equal
blocks; even blocks train, odd blocks are held out. The filter still runs
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
    n = ch.F.shape[0]
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
