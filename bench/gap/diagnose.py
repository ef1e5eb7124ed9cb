"""The diagnosis of one flight log, stage by stage (``proxops diagnose``).

Each stage is a module of bench/gap, called once, in this order, by
``diagnose``; on the right, what it hands to the next (docs/ARCHITECTURE.md
draws the same):

  1 load        load.py         the log resolved: time from its own start,
                                its description (defaults for what it does
                                not state), the IMU on its ticks, the poses
                                on the nearest tick, the valves as open
                                fractions; a log too short refused -> LogData d
    thresholds  log_null.py,    the null calibration the log is judged by:
                null.py         the committed one for the bench's own
                                flights, else one made for the log -> cal
  2 replay      replay.py       the flight navigation filter re-run over d
                                                        -> Pass nominal
  3 channels    dyn.py          the IMU against the commanded valves (None
                                without valves)         -> ch
                quantify.py     training and held-out time blocks of both
                                channels (split_context) -> Context ctx
  4 map         detection.py,   the gap map of both channels: stream, axis,
                localise.py     regime, frequency, lag  -> cells
  5 screen      attribute.py,   every in-library candidate fitted on its
                candidates.py   linearised signature    -> fits
    detect      detection.py    the map's largest |z| and the screen's
                                smallest p against cal's thresholds
                                                        -> Detection det
  6 quantify    quantify.py     the held-out scores every answer is judged
                                by: shrink, log-likelihood gain, each
                                channel's gain          -> HeldOut scores
  7 confirm     verdict.py      the first screened candidates refitted with
                                the full filter and judged on the held-out
                                data (rank)             -> ranking
    and select  verdict.py,     the verdict (decide): one effect, a set
                select.py,      (forward selection, joint refit) or a part,
                alternatives.py and the sets the data cannot tell from it
                                -> verdict, effect_set, ambiguous_with
  8 answer      answers.py      the answer as JSON: where, which, how far,
                                what was examined (result); in words
                                (answer_lines)          -> result
  9 report      report.py,      the Markdown page and its figures, written by
                report_plots.py the command from ``result`` and its
                                ``_internal`` arrays (write_report)
"""

from __future__ import annotations

import time

import numpy as np

from bench.gap.answers import result
from bench.gap.attribute import screen
from bench.gap.candidates import CANDIDATES
from bench.gap.detection import gap_map, pass_from, statistics
from bench.gap.dyn import build
from bench.gap.load import resolve
from bench.gap.log_null import thresholds_for
from bench.gap.quantify import HeldOut, split_context
from bench.gap.replay import reference
from bench.gap.verdict import N_CONFIRM, decide, rank
from bench.runner.progress import ProgressBar


def diagnose(
    log,
    calibration: dict | None = None,
    progress: bool = False,
    n_confirm: int = N_CONFIRM,
    confirm_always: bool = False,
    make_calibration: bool = True,
    calibration_source: str | None = None,
    calibration_runs: int | None = None,
) -> dict:
    """Diagnose one log. Returns a JSON-ready dict; ``result["_internal"]``
    holds arrays for the report (drop it before writing JSON: ``public``).

    ``calibration``: a null calibration (checked against the log; refused
    with log_null.CalibrationMismatch when it does not hold), ``{}`` for no
    thresholds (the null runs themselves), or None: the committed one when
    the log is the bench's vehicle and manoeuvres, else one made for the log
    (``make_calibration``; bench/gap/log_null.py). A log too short to
    diagnose is refused (FlightLogError, load.check_enough)."""
    t_start = time.time()
    log, d = resolve(log)  # 1
    cal, cal_info = thresholds_for(
        log, d, calibration, make_calibration, calibration_source, calibration_runs, progress
    )
    prog = ProgressBar("diagnose", 1 + sum(c.n_params for c in CANDIDATES.values() if c.nav), progress, unit="replay")
    ctx = split_context(d, pass_from(reference(d), d), build(d))  # 2, 3
    prog()
    cells = gap_map(ctx)  # 4
    det = statistics(ctx, cells, screen(ctx, progress=prog))  # 5
    fits = det.fits
    thr = cal.get("thresholds", {})
    thr_map, thr_glr = float(thr.get("map_max_abs_z", np.inf)), float(thr.get("screen_logp", np.inf))
    detected = bool(det.map_max_abs_z > thr_map or det.screen_logp_max > thr_glr)
    scores = HeldOut(ctx)  # 6
    ranking = []
    if detected or confirm_always:  # 7
        prog.total += n_confirm * 10
        ranking = rank(ctx, fits, scores, n_confirm, prog, thr_map, det.map_max_abs_z)
    prog.close()
    verdict, effect_set, ambiguous_with = "no_gap", None, []
    if detected:
        verdict, effect_set, ambiguous_with, ranking = decide(ctx, fits, scores, cal, ranking, det.map_max_abs_z)
    out = result(d, ctx, det, cal, cal_info, fits, ranking, verdict, ambiguous_with, effect_set, detected)  # 8
    out["log"]["time_origin_s"] = float(log.time_origin_s)
    out["elapsed_s"] = time.time() - t_start
    out["_internal"] = {
        "d": d,
        "nominal": ctx.nominal,
        "fits": fits,
        "train": ctx.train_nav,
        "held": ctx.held_nav,
        "cells": det.cells,
        "ctx": ctx,
        "held_shrink": scores.shrink,
    }
    return out


def public(result: dict) -> dict:
    out = {k: v for k, v in result.items() if not k.startswith("_")}
    if isinstance(out.get("effect_set"), dict):
        out["effect_set"] = {k: v for k, v in out["effect_set"].items() if not k.startswith("_")}
    return out
