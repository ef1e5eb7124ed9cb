"""Detection: the two statistics that say whether a log holds a gap, computed
under the nominal model.

``detect(d)`` runs the nominal replay of a prepared log (bench/gap/replay.py)
and its dynamics channel (bench/gap/dyn.py), splits both into training and
held-out time blocks, and returns the gap map's largest |z| and the
screening GLR's smallest p-value over the candidates (as -log10 p). The
diagnosis (bench/gap/diagnose.py) compares them with the null calibration's
thresholds; the null calibrations (bench/gap/null.py, bench/gap/log_null.py)
compute the same two numbers on simulated logs without any effect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.gap import dyn, localise, quantify
from bench.gap.attribute import Context, Pass, screen
from bench.gap.replay import LogData, ReplayResult, prepare, reference


def pass_from(res: ReplayResult, d: LogData) -> Pass:
    """A replay's per-pose-update arrays, NaN where an update was not fused."""
    m = d.pose_tc.size
    white = np.full((m, 6), np.nan)
    nis, ll = np.full(m, np.nan), np.full(m, np.nan)
    inn = np.full((m, 6), np.nan)
    white[res.index] = res.whitened()
    nis[res.index], ll[res.index], inn[res.index] = res.nis, res.loglik, res.innovation
    return Pass(white, nis, ll, inn, res)


def map_cells(d: LogData, p: Pass) -> list:
    """The gap map's cells of the navigation replay ``p``."""
    ok = np.isfinite(p.nis)
    res = p.res
    if res is None:
        idx = np.flatnonzero(ok)
        res = ReplayResult(
            d.pose_tc[idx],
            idx,
            p.innovation[idx],
            np.zeros((idx.size, 6, 6)),
            p.nis[idx],
            p.loglik[idx],
            np.ones(idx.size, bool),
        )
    return localise.gap_map(d, res, white=p.white[ok])


def context(d: LogData) -> Context:
    """The nominal pass over a prepared log, its dynamics channel, and the
    training / held-out split of both channels (alternate time blocks that
    excite every fired valve in both halves, quantify.excitation_split)."""
    nominal = pass_from(reference(d), d)
    ch = dyn.build(d)
    split = quantify.excitation_split(d.imu_t, d.valves * d.dt_s if d.valves is not None else None)
    train, held = split.masks(d.pose_tc)
    ok = np.isfinite(nominal.nis)
    train_dyn, held_dyn = split.masks(ch.t) if ch is not None else (None, None)
    return Context(d, nominal, ch, train & ok, held & ok, train_dyn, held_dyn, split)


@dataclass
class Detection:
    ctx: Context
    cells: list  # the gap map of both channels
    map_max_abs_z: float
    fits: list  # the screening fit of every candidate (bench/gap/attribute.py)
    screen_logp_max: float


def detect(d: LogData, progress=None, given: dict | None = None) -> Detection:
    """Both detection statistics of a prepared log. ``progress(n)`` is called
    after the nominal pass and after each screening replay. ``given``: the
    candidates' Jacobians to screen with (attribute.screen)."""
    ctx = context(d)
    if progress is not None:
        progress()
    cells = map_cells(d, ctx.nominal) + localise.dyn_cells(d, ctx.ch)
    fits = screen(ctx, progress=progress, given=given)
    return Detection(ctx, cells, localise.map_statistic(cells), fits, max(f.screen_logp for f in fits))


def null_statistics(log, given: dict | None = None) -> dict:
    """The two statistics of one log, as a null calibration records them;
    ``given``: the candidates' Jacobians of the log the null runs stand for
    (log_signatures)."""
    det = detect(prepare(log), given=given)
    return {"map_max_abs_z": det.map_max_abs_z, "screen_logp": det.screen_logp_max}


def log_signatures(d: LogData) -> dict:
    """Every candidate's Jacobians on a prepared log (attribute.signatures)."""
    from bench.gap.attribute import signatures

    return signatures(context(d))
