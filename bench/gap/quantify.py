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

from bench.gap.attribute import Context, Pass, confirm, screen
from bench.gap.candidates import candidates_of
from bench.gap.load import LogData

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
    e_before=None,
    e_after=None,
    seed: int = 0,
    cells: list | None = None,
    lab_dyn=None,
    seg_dyn=None,
) -> dict:
    """Shrink of the held-out deficit over both channels, the navigation
    updates (1/2 (NIS - 6)) and the dynamics rows ((R, 3) whitened residual
    rows ``e_before``/``e_after``, averaged over their segments ``seg_dyn``
    (dyn_segments; None: each row its own): 1/2 (|m|^2 - 3) per segment
    mean m), with a 95 % bootstrap interval over 5 s chunks of held-out time.
    ``cells`` (from gap_cells, with ``lab_dyn`` the held-out dynamics rows'
    cells): only those cells count; None or empty: all."""
    if cells:
        if CELL_NAV not in cells:
            t_nav, nis_before, nis_after = t_nav[:0], nis_before[:0], nis_after[:0]
        if t_dyn is not None and e_before is not None:
            keep = np.isin(lab_dyn, cells)
            t_dyn, e_before, e_after = t_dyn[keep], e_before[keep], e_after[keep]
            seg_dyn = None if seg_dyn is None else np.asarray(seg_dyn)[keep]
    parts_t = [np.asarray(t_nav, float)]
    b = [0.5 * (np.asarray(nis_before) - 6.0)]
    a = [0.5 * (np.asarray(nis_after) - 6.0)]
    dof = [np.full(np.asarray(nis_before).size, 6.0)]
    if t_dyn is not None and e_before is not None:
        t_dyn = np.asarray(t_dyn, float)
        seg = np.arange(t_dyn.size) if seg_dyn is None else np.asarray(seg_dyn)
        mb, first = segment_means(np.asarray(e_before, float), seg)
        ma, _ = segment_means(np.asarray(e_after, float), seg)
        parts_t.append(t_dyn[first])
        b.append(0.5 * (np.sum(mb**2, axis=1) - mb.shape[1]))
        a.append(0.5 * (np.sum(ma**2, axis=1) - ma.shape[1]))
        dof.append(np.full(first.size, float(mb.shape[1])))
    t = np.concatenate(parts_t)
    cb, ca = np.concatenate(b), np.concatenate(a)
    ok = np.isfinite(cb) & np.isfinite(ca)
    t, cb, ca = t[ok], cb[ok], ca[ok]
    d0, d1 = float(cb.sum()), float(ca.sum())
    frac = 1.0 - d1 / d0 if d0 > 0 else float("nan")
    # The deficit's spread under the null: var(1/2 (chi2_k - k)) = k / 2 per term.
    sd0 = float(np.sqrt(0.5 * np.concatenate(dof)[ok].sum()))
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
    if np.isfinite(lo) and (min(hi, 1.0) - lo > MAX_CI_WIDTH or lo < -1.0):
        # An interval wider than a shrink can mean ([-490, 105] %): the held-out
        # deficit is too small or too uneven over time to be measured. Above 1
        # (more than the whole deficit) the interval says no more than 1 does.
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


SEGMENT_S = 1.0  # longest stretch of dynamics rows averaged into one deficit term
OPEN_MIN = 1e-6  # an open fraction below this is a stamp's rounding, not a valve open


def dyn_segments(ch) -> np.ndarray:
    """The segment of each dynamics row: consecutive rows of one kind, in one
    run, with the same valves open, inside one SEGMENT_S window. A gap is
    slow beside the IMU's rate: within a segment a bias, a thrust error or
    a torque error's trace in the whitened gyro rows is nearly constant, so
    the deficit of the segment's mean row, sum(e) / sqrt(n) ~ N(0, I) under
    the null, keeps the gap's energy while the noise's spread falls by the
    segment's length (up to 10 to 50 rows): at the detection limit the deficit of
    single rows is mostly noise (a held-out accelerometer bias read 8 %
    shrink where the segments read 70 %)."""
    n = ch.open_.shape[0]
    k_valves = ch.open_.shape[1]
    weights = np.left_shift(1, np.arange(k_valves, dtype=np.int64) % 62)
    # Gyro rows are not cut at valve changes: whitening the differenced gyro
    # integrates it back, so a torque error stays in the rows after it.
    state = np.concatenate([(ch.open_ > OPEN_MIN) @ weights, np.zeros(ch.rows - n, np.int64)])
    run = np.empty(ch.rows, np.int64)
    run[:n] = np.concatenate([[0], np.cumsum(np.diff(ch.t[:n]) > 1.5 * ch.dt)])
    for j, (a, b) in enumerate(ch.seg_bounds):
        run[n + a : n + b] = j
    # Window edges half a sample off the ticks: a stamp's rounding (a log on a
    # Unix epoch) never moves a row across one.
    window = np.floor((ch.t - ch.t.min() + 0.5 * ch.dt) / SEGMENT_S).astype(np.int64)
    new = np.ones(ch.rows, bool)
    new[1:] = (np.diff(ch.kind) != 0) | (np.diff(state) != 0) | (np.diff(run) != 0) | (np.diff(window) != 0)
    return np.cumsum(new) - 1


def segment_means(e: np.ndarray, seg: np.ndarray) -> tuple:
    """(mean rows sum(e) / sqrt(n) per segment, (n_seg, 3); the index of each
    segment's first row)."""
    ids, first, inv, cnt = np.unique(seg, return_index=True, return_inverse=True, return_counts=True)
    sums = np.stack([np.bincount(inv, e[:, a], ids.size) for a in range(e.shape[1])], axis=1)
    return sums / np.sqrt(cnt)[:, None], first


def gap_cells(nis_train, e_train=None, lab_train=None, seg_train=None) -> list:
    """The cells where the nominal model's training-block deficit stands out
    of its null spread (over 2 sd): where the gap lies. The dynamics rows
    ``e_train`` (R, 3) count by their segments' means (``seg_train``, as in
    shrink_combined). The held-out shrink is measured over these cells only,
    so channels that carry nothing of the gap add no noise to it; they are
    chosen on the training blocks, before and independently of any
    candidate, and the same cells serve every candidate. Empty when no cell
    stands out (then every cell counts)."""
    out = []
    nis = np.asarray(nis_train, float)
    nis = nis[np.isfinite(nis)]
    if nis.size and 0.5 * np.sum(nis - 6.0) > 2.0 * np.sqrt(0.5 * 6.0 * nis.size):
        out.append(CELL_NAV)
    if e_train is not None:
        e_train = np.asarray(e_train, float)
        seg = np.arange(e_train.shape[0]) if seg_train is None else np.asarray(seg_train)
        for c in (CELL_ACCEL_COAST, CELL_ACCEL_FIRE, CELL_GYRO):
            m = np.asarray(lab_train) == c
            if not m.any():
                continue
            mean, _ = segment_means(e_train[m], seg[m])
            if 0.5 * np.sum(mean**2 - 1.0) > 2.0 * np.sqrt(0.5 * mean.size):
                out.append(c)
    return out


def channel_rms(innov: np.ndarray) -> dict:
    names = ("r_x_m", "r_y_m", "r_z_m", "th_x_rad", "th_y_rad", "th_z_rad")
    return {k: float(np.sqrt(np.mean(innov[:, i] ** 2))) if innov.size else float("nan") for i, k in enumerate(names)}


def split_context(d: LogData, nominal: Pass, ch) -> Context:
    """The training / held-out split of both channels, the nominal pass
    and the dynamics channel ``ch`` (None without valves): alternate time
    blocks that excite every fired valve in both halves (excitation_split),
    the navigation rows where the nominal pass fused a pose."""
    split = excitation_split(d.imu_t, d.valves * d.dt_s if d.valves is not None else None)
    train, held = split.masks(d.pose_tc)
    ok = np.isfinite(nominal.nis)
    train_dyn, held_dyn = split.masks(ch.t) if ch is not None else (None, None)
    return Context(d, nominal, ch, train & ok, held & ok, train_dyn, held_dyn, split)


# --- the scores every answer is judged by (stage 7) ---------------------------


def channel_gain(e0: np.ndarray, e1: np.ndarray) -> dict:
    """What a candidate's fit did to one channel's training rows: e0, e1 its
    whitened residuals before and after (rows with NaN dropped). g is the
    channel's log-likelihood gain, 1/2 (|e0|^2 - |e1|^2), and q = |e1 - e0|^2
    the size of the correction there. A right candidate gains in every
    channel it touches on average (its signal is there, and the fit's own
    noise-fitting only adds to a training gain); noise moves g by about
    sqrt(q). A look-alike that buys one channel at another's cost corrects
    where the data show nothing, and there g is about -q / 2. z = g / sqrt(q)
    below -Z_CONTRADICT says the channel contradicts the candidate."""
    ok = np.isfinite(e0) & np.isfinite(e1)
    a, b = e0[ok], e1[ok]
    d = b - a
    q = float(d @ d)
    g = 0.5 * float(a @ a - b @ b)
    return {"gain": g, "q": q, "z": g / np.sqrt(q) if q > 0.0 else 0.0}


def segment_of(d: LogData, t: np.ndarray) -> np.ndarray:
    """Which chained run (segment) each time falls in."""
    brk = np.flatnonzero(np.diff(d.imu_seg) != 0) + 1
    return np.searchsorted(d.imu_t[brk], np.asarray(t, float), side="right")


def gap_cells_of(ctx: Context):
    """The deficit cells where the nominal model's gap lies on the training
    rows (gap_cells), every dynamics row's cell and its segment
    (dyn_segments)."""
    ch = ctx.ch
    if ch is None:
        return gap_cells(ctx.nominal.nis[ctx.train_nav]), None, None
    lab, seg = dyn_cell_labels(ch), dyn_segments(ch)
    tr = ctx.train_dyn
    return gap_cells(ctx.nominal.nis[ctx.train_nav], ch.e0[tr], lab[tr], seg[tr]), lab, seg


def heldout_runs_shrink(ctx: Context, name: str) -> dict:
    """Fit ``name`` on the even-numbered runs of a chained log and measure
    the shrink on the odd-numbered ones (every time block of them)."""
    d, ch, nominal = ctx.d, ctx.ch, ctx.nominal
    seg_nav = segment_of(d, d.pose_tc)
    n_runs = int(segment_of(d, d.imu_t[-1:])[0]) + 1
    if n_runs < 2:
        return {"runs": n_runs, "fraction": None, "reason": "the log holds one run"}
    ok = np.isfinite(nominal.nis)
    train, held = ok & (seg_nav % 2 == 0), ok & (seg_nav % 2 == 1)
    td = hd = None
    if ch is not None:
        seg_dyn = segment_of(d, ch.t)
        td, hd = seg_dyn % 2 == 0, seg_dyn % 2 == 1
    c2 = Context(d, nominal, ch, train, held, td, hd)
    f = screen(c2, names=[name])[0]
    if not np.isfinite(f.screen_bic):
        return {"runs": n_runs, "fraction": None, "reason": "no signature on the training runs"}
    confirm(c2, f)
    e0 = e1 = t_d = None
    if ch is not None:
        t_d = ch.t[hd]
        e0, e1 = ch.e0[hd], (f.after_dyn if f.after_dyn is not None else ch.e0)[hd]
    cells, lab, seg = gap_cells_of(c2)
    sh = shrink_combined(
        d.pose_tc[held],
        nominal.nis[held],
        f.after_nav.nis[held],
        t_d,
        e0,
        e1,
        cells=cells,
        lab_dyn=None if lab is None else lab[hd],
        seg_dyn=None if seg is None else seg[hd],
    )
    return {
        "runs": n_runs,
        "train_runs": int((n_runs + 1) // 2),
        "heldout_runs": int(n_runs // 2),
        **sh,
        "parameters": {p: float(v) for p, v in zip(candidates_of(d)[name].params, f.theta)},
    }


class HeldOut:
    """The scores every answer is judged by: the held-out shrink and
    log-likelihood gain, and each channel's gain on the training rows, of a
    replay with the candidate's corrections (after_nav, after_dyn) against
    the nominal one. The shrink counts the gap's cells only (gap_cells_of)."""

    def __init__(self, ctx: Context):
        self.ctx = ctx
        self.cells, self.lab_dyn, self.seg_dyn = gap_cells_of(ctx)

    def shrink(self, after_nav: Pass, after_dyn) -> dict:
        ctx, ch, hd = self.ctx, self.ctx.ch, self.ctx.held_dyn
        e0 = e1 = td = None
        if ch is not None:
            td = ch.t[hd]
            e0, e1 = ch.e0[hd], (after_dyn if after_dyn is not None else ch.e0)[hd]
        held = ctx.held_nav
        return shrink_combined(
            ctx.d.pose_tc[held],
            ctx.nominal.nis[held],
            after_nav.nis[held],
            td,
            e0,
            e1,
            cells=self.cells,
            lab_dyn=None if self.lab_dyn is None else self.lab_dyn[hd],
            seg_dyn=None if self.seg_dyn is None else self.seg_dyn[hd],
        )

    def train_channels(self, after_nav: Pass, after_dyn) -> dict:
        ctx, ch, train = self.ctx, self.ctx.ch, self.ctx.train_nav
        out = {"pose": channel_gain(ctx.nominal.white[train].ravel(), after_nav.white[train].ravel())}
        if ch is not None and after_dyn is not None:
            for name, kind in (("accelerometer", 0), ("gyro", 1)):
                m = ctx.train_dyn & (ch.kind == kind)
                out[name] = channel_gain(ch.e0[m].ravel(), after_dyn[m].ravel())
        return out

    def dll(self, after_nav: Pass, after_dyn) -> float:
        ctx, ch, held = self.ctx, self.ctx.ch, self.ctx.held_nav
        v = float(np.nansum(after_nav.loglik[held]) - np.nansum(ctx.nominal.loglik[held]))
        if ch is not None and after_dyn is not None:
            e0, e1 = ch.e0[ctx.held_dyn].ravel(), after_dyn[ctx.held_dyn].ravel()
            v += 0.5 * float(e0 @ e0 - e1 @ e1)
        return v
