"""Stage 4 of the diagnosis (bench/gap/diagnose.py), detect and map: the
gap map and the two statistics that say whether a log holds a gap, computed
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
from bench.gap.load import LogData, prepare
from bench.gap.replay import ReplayResult, reference


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
    """Stages 2 and 3 over a prepared log: the nominal pass (replay), its
    dynamics channel (dyn.build), and the training / held-out split of both
    (quantify.split_context)."""
    return quantify.split_context(d, pass_from(reference(d), d), dyn.build(d))


def gap_map(ctx: Context) -> list:
    """The gap map's cells of both channels under the nominal model."""
    return map_cells(ctx.d, ctx.nominal) + localise.dyn_cells(ctx.d, ctx.ch)


@dataclass
class Detection:
    ctx: Context
    cells: list  # the gap map of both channels
    map_max_abs_z: float
    fits: list  # the screening fit of every candidate (bench/gap/attribute.py)
    screen_logp_max: float


def statistics(ctx: Context, cells: list, fits: list) -> Detection:
    """Both detection statistics: the gap map's largest |z| and the
    screening's smallest p-value (as -log10 p)."""
    return Detection(ctx, cells, localise.map_statistic(cells), fits, max(f.screen_logp for f in fits))


def detect(d: LogData, progress=None, given: dict | None = None) -> Detection:
    """Both detection statistics of a prepared log (the diagnosis's stages 2
    to 5, as a null calibration runs them). ``progress(n)`` is called after
    the nominal pass and after each screening replay. ``given``: the
    candidates' Jacobians to screen with (attribute.screen)."""
    ctx = context(d)
    if progress is not None:
        progress()
    cells = gap_map(ctx)
    return statistics(ctx, cells, screen(ctx, progress=progress, given=given))


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
