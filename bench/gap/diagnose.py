"""The whole diagnosis of one flight log: localise, attribute, quantify, verdict.

Detection uses two statistics, each with a threshold from the null
calibration (bench/gap/null.py): the largest |z| of the gap map, and the
smallest p-value of the screening GLR over the candidates (as -log10 p).

Verdict when a gap is detected (the confirmed candidate with the largest
Bayes factor among those that explain the held-out data):
  explained    it wins the held-out data: held-out log-likelihood gain
               > HELDOUT_DLL_MIN, shrink >= SHRINK_MIN (or its bootstrap
               interval reaching it) or a remaining
               deficit within twice its null spread (when the held-out
               deficit stands out of that spread at all), and the gap map
               after the fix is below the null threshold; and its
               fit made no channel (pose, accelerometer, gyro) worse on the
               training rows by more than Z_CONTRADICT noise deviations;
  ambiguous    it does, but a second confirmed candidate also explains the
               held-out data and either is within BF_AMBIGUOUS of its ln
               Bayes factor (a factor below 20) or reproduces its fitted
               signature to within DELTA2_95 noise variances (the data
               cannot tell the two apart; their Bayes factor is then only
               the priors' Occam factors);
  explained    (a set) forward selection's set (bench/gap/select.py), refitted
               jointly, passes the same tests, every member adds more than
               HELDOUT_DLL_MIN of held-out log-likelihood beside the others,
               and the set beats the best single answer there by as much;
  partly_explained
               no single effect or set explains the gap, but the selected
               members each earn their place on the held-out data (as above)
               and contradict no channel, and what is left after their joint
               fit is still a gap (the gap map above its threshold, or the
               shrink short of SHRINK_MIN): the members are named with their
               shares and the remainder is located;
  unexplained  otherwise (nothing in the library accounts for the gap).
Without a detected gap the verdict is "no_gap".
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bench.gap import localise, quantify
from bench.gap import null as nullmod
from bench.gap.attribute import BF_AMBIGUOUS, DELTA2_95, Context, Pass, bounded_fit, confirm, screen
from bench.gap.candidates import CANDIDATES, NOT_MODELLED, candidates_of
from bench.gap.detection import detect, map_cells
from bench.gap.replay import LogData, prepare
from bench.sim.flight_log import FlightLogError, relative_to_start
from bench.so3 import rotmats

HELDOUT_DLL_MIN = 3.0
SHRINK_MIN = 0.5
N_CONFIRM = 4
Z_CONTRADICT = 3.0


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


class _Progress:
    def __init__(self, total: int, enabled: bool, label: str = "diagnose"):
        self.total, self.done, self.enabled, self.label = total, 0, enabled, label
        self.t0 = self.t_last = time.time()

    def __call__(self, n: int = 1):
        self.done += n
        if self.enabled and time.time() - self.t_last > 0.5:
            self.t_last = time.time()
            print(
                f"\r  {self.label}: {min(self.done, self.total)}/{self.total} replays, {time.time() - self.t0:5.1f} s",
                end="",
                flush=True,
                file=sys.stderr,
            )

    def close(self):
        if self.enabled:
            print(f"\r  {self.label}: {self.done} replays, {time.time() - self.t0:5.1f} s", file=sys.stderr)


def segment_of(d: LogData, t: np.ndarray) -> np.ndarray:
    """Which chained run (segment) each time falls in."""
    brk = np.flatnonzero(np.diff(d.imu_seg) != 0) + 1
    return np.searchsorted(d.imu_t[brk], np.asarray(t, float), side="right")


def signature_distance(a, b, cands: dict | None = None) -> float:
    """|J_a theta_a - J_b theta_b*|^2 on the training rows (screen Jacobians),
    theta_b* the closest fit inside b's physical bounds: how far, in noise
    standard deviations squared, candidate a's fitted signature lies from
    anything candidate b can produce (bench/campaigns/gap/separability.py)."""
    Ja, Jb = getattr(a, "J_u", None), getattr(b, "J_u", None)
    if Ja is None or Jb is None or Ja.shape[0] != Jb.shape[0]:
        return float("inf")
    cands = cands or CANDIDATES
    sa = Ja @ (a.theta / cands[a.name].scale)
    cb = cands[b.name]
    r = sa - bounded_fit(Jb, sa, cb.lower / cb.scale, cb.bound / cb.scale)
    return float(r @ r)


def _gap_cells(ctx: Context):
    """The deficit cells where the nominal model's gap lies on the training
    rows (quantify.gap_cells), every dynamics row's cell and its segment
    (quantify.dyn_segments)."""
    ch = ctx.ch
    if ch is None:
        return quantify.gap_cells(ctx.nominal.nis[ctx.train_nav]), None, None
    lab, seg = quantify.dyn_cell_labels(ch), quantify.dyn_segments(ch)
    tr = ctx.train_dyn
    return quantify.gap_cells(ctx.nominal.nis[ctx.train_nav], ch.e0[tr], lab[tr], seg[tr]), lab, seg


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
    cells, lab, seg = _gap_cells(c2)
    sh = quantify.shrink_combined(
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
    the nominal one. The shrink counts the gap's cells only (_gap_cells)."""

    def __init__(self, ctx: Context):
        self.ctx = ctx
        self.cells, self.lab_dyn, self.seg_dyn = _gap_cells(ctx)

    def shrink(self, after_nav: Pass, after_dyn) -> dict:
        ctx, ch, hd = self.ctx, self.ctx.ch, self.ctx.held_dyn
        e0 = e1 = td = None
        if ch is not None:
            td = ch.t[hd]
            e0, e1 = ch.e0[hd], (after_dyn if after_dyn is not None else ch.e0)[hd]
        held = ctx.held_nav
        return quantify.shrink_combined(
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
    holds arrays for the report (drop it before writing JSON).

    ``calibration``: a null calibration (checked against the log; refused
    with log_null.CalibrationMismatch when it does not hold), ``{}`` for no
    thresholds (the null runs themselves), or None: the committed one when
    the log is the bench's vehicle and manoeuvres, else one made for the log
    (``make_calibration``; bench/gap/log_null.py).

    Every time stamp is first taken from the log's own origin
    (flight_log.relative_to_start; the answer's ``log.time_origin_s``), so a
    log on a Unix epoch is diagnosed as the same log from zero. A log too
    short to diagnose is refused (FlightLogError, ``check_enough``)."""
    t_start = time.time()
    log = relative_to_start(log)
    d = prepare(log)
    check_enough(d)
    cal, cal_info = _calibration(log, d, calibration, make_calibration, calibration_source, calibration_runs, progress)
    n_screen = sum(c.n_params for c in CANDIDATES.values() if c.nav)
    prog = _Progress(1 + n_screen, progress)
    det = detect(d, progress=prog)
    ctx, fits = det.ctx, det.fits
    thr = cal.get("thresholds", {})
    thr_map, thr_glr = float(thr.get("map_max_abs_z", np.inf)), float(thr.get("screen_logp", np.inf))
    detected = bool(det.map_max_abs_z > thr_map or det.screen_logp_max > thr_glr)
    scores = HeldOut(ctx)
    ranking = []
    if detected or confirm_always:
        prog.total += n_confirm * 10
        ranking = _rank(ctx, fits, scores, n_confirm, prog, thr_map, det.map_max_abs_z)
    prog.close()
    verdict, ambiguous_with, ranking = _single_answer(d, fits, ranking) if detected else ("no_gap", [], ranking)
    effect_set = None
    if detected:
        verdict, effect_set, ambiguous_with = _set_answer(
            ctx, fits, scores, cal, thr_glr, thr_map, det.map_max_abs_z, verdict, ranking, ambiguous_with
        )
    out = _answer(d, ctx, det, cal, cal_info, fits, ranking, verdict, ambiguous_with, effect_set, detected)
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


MIN_IMU_S = 1.0  # the slewing regime averages the gyro over 1 s (localise.dyn_regimes)


def check_enough(d: LogData) -> None:
    """Refuse (FlightLogError, naming the field) a log the diagnosis cannot
    look at: less than MIN_IMU_S of IMU samples inside the segments, a
    stated segment whose run has no pose on its IMU ticks (a run starts at
    its first pose), or no pose update at all (a pose after a run's first)."""
    need = max(2, int(round(MIN_IMU_S / d.dt_s)))
    if d.imu_t.size < need:
        raise FlightLogError(
            f"imu/t_s: {d.imu_t.size} samples inside the segments, the diagnosis needs at least {need} "
            f"({MIN_IMU_S:g} s at {1.0 / d.dt_s:g} Hz)"
        )
    with_pose = np.unique(d.imu_seg[np.clip(d.pose_tick, 0, None)])
    bare = np.setdiff1d(np.unique(d.imu_seg), with_pose)
    if bare.size and d.desc.segments:
        t0 = float(d.imu_t[d.imu_seg == bare[0]][0])
        i = int(np.searchsorted([sg.t_start_s for sg in d.desc.segments], t0, side="right")) - 1
        raise FlightLogError(
            f"/description_json: segments[{i}]: no pose within one IMU interval of its IMU samples "
            "(a run starts at its first pose: check the pose clock, pose_sensor.time_offset_s)"
        )
    updates = int(d.pose_tc.size - d.pose_start.sum())
    if updates < 1:
        raise FlightLogError(
            f"pose/t_capture_s: {d.pose_tc.size} pose(s) on the IMU ticks, each the first of its run: the "
            "diagnosis needs at least one more (a run starts at its first pose, the next ones are compared)"
        )


def _calibration(log, d: LogData, calibration, make_calibration: bool, source, runs, progress) -> tuple:
    """(calibration, its description) for diagnose()."""
    from bench.gap import log_null

    if calibration == {}:
        return {}, {"source": "none (no thresholds)", "runs": 0, "note": None}
    if calibration is None and not make_calibration:
        return nullmod.load(), {"source": "committed (docking logs of the bench inspector)", "note": None}
    return log_null.choose(log, d, calibration, source, runs=runs or log_null.DEFAULT_RUNS, progress=progress)


def parameters(ctx: Context, name: str, theta, sigma) -> dict:
    """{name: {"value", "sigma"}} of a fit; a parameter the log cannot
    identify gets no value but why: a valve fired in one half of the
    split only (quantify.excitation_split), or no signature of it in the
    training time (its fitted spread zero or undefined). Never a value
    with zero uncertainty."""
    c = candidates_of(ctx.d)[name]
    unexcited = {u["valve"]: u["why"] for u in (ctx.split.unexcited if ctx.split is not None else [])}
    per_valve = {"thrust_loss": 1, "thruster_misalignment": 3}.get(name)
    out = {}
    for i, (p, v, s) in enumerate(zip(c.params, theta, sigma)):
        why = unexcited.get(i // per_valve) if per_valve else None
        if why is None and not (np.isfinite(s) and s > 0.0):
            why = "no signature of it in the training time"
        out[p] = (
            {"value": None, "sigma": None, "not_identifiable": f"not identifiable from this log: {why}"}
            if why
            else {"value": float(v), "sigma": float(s)}
        )
    return out


def _judge(ctx: Context, f, scores: HeldOut, thr_map: float, t_map: float) -> dict:
    """One confirmed candidate's entry in the ranking: its evidence, its
    parameters and whether it explains the held-out data."""
    d, ch = ctx.d, ctx.ch
    sh = scores.shrink(f.after_nav, f.after_dyn)
    dll_held = scores.dll(f.after_nav, f.after_dyn)
    map_after = localise.map_statistic(map_cells(d, f.after_nav) + localise.dyn_cells(d, ch, f.after_dyn))
    # What is left must look like the null: every candidate that touches
    # the IMU, the valves or the pose is exact (tests/py/test_gap_exact_candidates.py),
    # so a remainder above the threshold is something the candidate is not.
    # A shrink is required only where the held-out deficit stands out of its noise.
    # What is left may also simply be the null's own noise: a deficit
    # within twice its null spread.
    # Or a shrink whose bootstrap interval reaches SHRINK_MIN: the held-out
    # deficit is a sum of squares over many rows, and near the detection
    # limit its noise alone can hold the point estimate under the bar.
    shrink_ok = (
        (np.isfinite(sh["fraction"]) and sh["fraction"] >= SHRINK_MIN)
        or not sh["measurable"]
        or sh["deficit_after"] <= 2.0 * sh["deficit_null_sd"]
        or (np.isfinite(sh["ci95"][1]) and sh["ci95"][1] >= SHRINK_MIN)
    )
    contra = scores.train_channels(f.after_nav, f.after_dyn)
    consistent = all(c["z"] >= -Z_CONTRADICT for c in contra.values())
    explains = bool(dll_held > HELDOUT_DLL_MIN and shrink_ok and consistent and map_after <= thr_map)
    c = candidates_of(d)[f.name]
    return {
        "effect": f.name,
        "kind": f.kind,
        "evidence": {
            "ln_bf": f.ln_bf,
            "bic": f.bic,
            "dll_train": f.dll_train,
            "screen_bic": f.screen_bic,
            "dll_heldout": dll_held,
        },
        "parameters": parameters(ctx, f.name, f.theta, f.sigma),
        "unconstrained_fit_beyond_bound_sigma": f.bound_excess_sigma,
        "shrink_heldout": sh,
        "map_max_abs_z_after": map_after,
        "explains_heldout": explains,
        "training_channels": contra,
        "shrink_ok": bool(shrink_ok),
        "separate_by": c.separate_by,
        "replay_rms_heldout_after": quantify.channel_rms(f.after_nav.innovation[ctx.held_nav]),
    }


def _rank(ctx: Context, fits: list, scores: HeldOut, n_confirm: int, prog, thr_map: float, t_map: float) -> list:
    """The first ``n_confirm`` screened candidates refitted with the full
    filter and judged, by Bayes factor."""
    ranking = []
    for f in fits[:n_confirm]:
        if not np.isfinite(f.screen_bic):
            continue
        confirm(ctx, f)
        prog(10)
        ranking.append(_judge(ctx, f, scores, thr_map, t_map))
    ranking.sort(key=lambda r: -r["evidence"]["ln_bf"])
    return ranking


def _single_answer(d: LogData, fits: list, ranking: list) -> tuple:
    """(verdict, ambiguous_with, ranking) of a detected gap with one effect.

    The answer is the most probable candidate that explains the held-out
    data; one that does not is no explanation, however well it fits the
    training blocks (a small candidate fitting noise there can outrank the
    right one near the detection limit)."""
    explainers = [r for r in ranking if r["explains_heldout"]]
    if not explainers:
        return "unexplained", [], ranking
    ranking = explainers + [r for r in ranking if not r["explains_heldout"]]
    best = ranking[0]
    fit_of = {f.name: f for f in fits}
    ambiguous_with = []
    for r in ranking[1:]:
        if not r["explains_heldout"]:
            continue
        dbf = best["evidence"]["ln_bf"] - r["evidence"]["ln_bf"]
        # Two ways the data fail to tell them apart: the evidence is close,
        # or the best one's fitted signature is one the other reproduces
        # to within DELTA2_95 (then the Bayes factor between them is only
        # their priors' Occam factors, not the data).
        d2 = signature_distance(fit_of[best["effect"]], fit_of[r["effect"]], candidates_of(d))
        if dbf < BF_AMBIGUOUS or d2 < DELTA2_95:
            ambiguous_with.append(
                {
                    "effect": r["effect"],
                    "ln_bf_difference": dbf,
                    "signature_distance2": d2,
                    "separate_by": f"{best['separate_by']}; {r['separate_by']}",
                }
            )
    return ("ambiguous" if ambiguous_with else "explained"), ambiguous_with, ranking


def _set_answer(
    ctx: Context,
    fits: list,
    scores: HeldOut,
    cal: dict,
    thr_glr: float,
    thr_map: float,
    t_map: float,
    verdict: str,
    ranking: list,
    ambiguous_with: list,
) -> tuple:
    """(verdict, effect_set, ambiguous_with) once several effects at once are
    considered (bench/gap/select.py): the set forward selection supports
    replaces the single answer only when its joint fit explains the held-out
    data and beats the best single explanation there; with no explanation,
    the members that each earn their place make a partial answer."""
    effect_set = _effect_set(
        ctx,
        fits,
        thr_glr,
        thr_map,
        t_map,
        scores.shrink,
        scores.dll,
        scores.train_channels,
        ranking if verdict in ("explained", "ambiguous") else [],
        one_ok=verdict == "unexplained",
        null_map=cal.get("null_map_max_abs_z"),
    )
    if effect_set is not None and effect_set["explains_heldout"]:
        # Sets the data cannot tell from this one: ambiguous.
        ambiguous_with = _listed(ctx, fits, [m["effect"] for m in effect_set["members"]], thr_glr, [])
        return ("ambiguous" if ambiguous_with else "explained"), effect_set, ambiguous_with
    if verdict in ("explained", "ambiguous") and ranking:  # the single answer, and the sets beside it
        ambiguous_with = _listed(ctx, fits, [ranking[0]["effect"]], thr_glr, ambiguous_with)
        verdict = "ambiguous" if ambiguous_with else verdict
    if verdict == "unexplained" and effect_set is not None:
        effect_set = _partial_set(
            effect_set,
            ctx,
            fits,
            thr_glr,
            thr_map,
            t_map,
            scores.shrink,
            scores.dll,
            scores.train_channels,
            cal.get("null_map_max_abs_z"),
        )
        if effect_set is not None and effect_set["partly_explains"]:
            verdict = "partly_explained"
            ambiguous_with = _partial_alternatives(ctx, fits, [m["effect"] for m in effect_set["members"]], thr_glr)
        elif effect_set is not None:
            ambiguous_with = _possible_parts(ctx, fits, effect_set, thr_glr)
    return verdict, effect_set, ambiguous_with


def _possible_parts(ctx: Context, fits: list, effect_set: dict, thr_glr: float) -> list:
    """What an unexplained answer lists: the selected members that each gain
    more than HELDOUT_DLL_MIN on the held-out data while the set fails
    another test (it contradicts a channel, or shrinks too little of the
    deficit), as the in-library part that may sit beside what the library
    lacks, and the sets the data cannot tell from it (_listed). The verdict
    stays "unexplained": none of them is confirmed."""
    part = [m["effect"] for m in effect_set["members"] if m["adds_dll_heldout"] > HELDOUT_DLL_MIN]
    if not part:
        return []
    cands = candidates_of(ctx.d)
    first = {"set": part, "part_of_gap": True, "separate_by": "; ".join(cands[n].separate_by for n in part)}
    return _listed(ctx, fits, part, thr_glr, [first])


def _listed(ctx: Context, fits: list, names: list, thr_glr: float, listed: list) -> list:
    """``listed`` and then every other set the data cannot tell from the
    answer ``names`` (bench/gap/alternatives.py), each set once, each with
    what separates it from the answer: the separating manoeuvres of the
    members the two do not share."""
    from bench.gap.alternatives import alternative_sets

    cands = candidates_of(ctx.d)
    seen = {frozenset(a["set"] if "set" in a else [a["effect"]]) for a in listed}
    out = list(listed)
    for a in alternative_sets(ctx, fits, names, thr_glr):
        if frozenset(a["set"]) not in seen:
            seen.add(frozenset(a["set"]))
            differ = [n for n in names if n not in a["set"]] + [n for n in a["set"] if n not in names]
            out.append({**a, "separate_by": "; ".join(cands[n].separate_by for n in differ)})
    return out


def _partial_alternatives(ctx: Context, fits: list, names: list, thr_glr: float) -> list:
    """The sets a partial answer cannot be told from: the answer without
    each of its members (with something outside the library in the log, a
    member's fit may be that effect's shadow in the library, and the data
    cannot say which), then the sets listed beside any answer (_listed)."""
    without = [{"set": [n for n in names if n != m], "drop": m} for m in names] if len(names) > 1 else []
    cands = candidates_of(ctx.d)
    without = [dict(a, separate_by=cands[a["drop"]].separate_by) for a in without]
    return _listed(ctx, fits, names, thr_glr, without)


def _dynamics_or_sensor(where, verdict: str, ranking: list, effect_set) -> str | None:
    """Whether the gap is in the vehicle's dynamics or in a sensor: the
    answer's kind, or where the gap map puts it when nothing explains it."""
    set_kinds = (
        {m["kind"] for m in effect_set["members"]}
        if effect_set is not None and effect_set["explains_heldout"]
        else None
    )
    if set_kinds:
        return set_kinds.pop() if len(set_kinds) == 1 else "dynamics and sensor"
    if verdict in ("explained", "ambiguous"):
        return ranking[0]["kind"]
    if where is None:
        return None
    # The IMU disagreeing with the valve model while firing, or by a
    # slow drift or swing at any time (the body moving as no thrust
    # explains: a flexible panel, slosh), and position-only slow
    # gaps point at the dynamics; attitude, broadband or IMU-scatter
    # gaps at a sensor.
    s, st = where["stream"], where["stat"]
    return (
        "dynamics"
        if (
            s in ("imu accel vs valves", "gyro vs valve torques")
            and (where["regime_peak"] == "firing" or st in ("mean", "lowfreq"))
        )
        or (s == "pose position" and st in ("mean", "lowfreq", "lag"))
        else "sensor"
    )


def _answer(
    d: LogData,
    ctx: Context,
    det,
    cal: dict,
    cal_info: dict,
    fits: list,
    ranking: list,
    verdict: str,
    ambiguous_with: list,
    effect_set,
    detected: bool,
) -> dict:
    """The JSON-ready answer of diagnose()."""
    nominal, ch, held = ctx.nominal, ctx.ch, ctx.held_nav
    summ = localise.summarise(det.cells, cal.get("null_map_max_abs_z"))
    where = summ["where"]
    dyn_or_sensor = _dynamics_or_sensor(where, verdict, ranking, effect_set) if detected else None
    best = ranking[0] if ranking else None
    acts = None
    # The set is the answer when it explains the held-out data, or when it
    # explains part of it (the rest then stays a located remainder).
    is_set = effect_set is not None and (effect_set["explains_heldout"] or verdict == "partly_explained")
    if verdict in ("explained", "ambiguous"):
        if is_set:
            from bench.gap.select import as_fit

            f = as_fit(effect_set["_fit"])
        else:
            f = next(f for f in fits if f.name == best["effect"])
        acts = localise.signature_regimes(d, ch, nominal.white, f.after_nav.white, nominal.res, f.after_dyn)
    shrink_best = effect_set["shrink_heldout"] if is_set else (best["shrink_heldout"] if best else None)
    if is_set:
        runs_shrink = {"runs": int(d.n_segments), "fraction": None, "reason": "measured on held-out blocks for a set"}
    else:
        runs_shrink = heldout_runs_shrink(ctx, best["effect"]) if best is not None and verdict != "no_gap" else None
    return {
        "gap_detected": detected,
        "statistics": _statistics(det, cal, fits),
        "location": {
            "where": where,
            "dynamics_or_sensor": dyn_or_sensor,
            "top_cells": summ["top_cells"],
            "effect_acts_while": acts,
        },
        "attribution": ranking,
        "effects": _named_effects(effect_set, is_set, ranking, verdict),
        "effect_set": effect_set,
        "screening": _screen_table(fits),
        "verdict": verdict,
        "ambiguous_with": ambiguous_with,
        "shrink_heldout_runs": runs_shrink,
        "shrink_heldout": (
            {
                "effect": " + ".join(m["effect"] for m in effect_set["members"]) if is_set else best["effect"],
                "fraction": shrink_best["fraction"],
                "ci95": shrink_best["ci95"],
            }
            if best
            else None
        ),
        "replay_rms_heldout_before": quantify.channel_rms(nominal.innovation[held]),
        "not_modelled": list(NOT_MODELLED),
        "examined": examined(d, ctx, detected),
        "calibration": cal_info,
        "log": _log_summary(d, ctx),
    }


def _statistics(det, cal: dict, fits: list) -> dict:
    """The detection statistics beside their calibrated thresholds."""
    thr = cal.get("thresholds", {})
    return {
        "map_max_abs_z": det.map_max_abs_z,
        "map_threshold": float(thr.get("map_max_abs_z", np.inf)),
        "screen_logp_max": det.screen_logp_max,
        "screen_logp_threshold": float(thr.get("screen_logp", np.inf)),
        "screen_bic_max": max(f.screen_bic for f in fits),
        "false_alarm_rate": cal.get("false_alarm_rate"),
        "calibration_runs": cal.get("runs"),
    }


def _screen_table(fits: list) -> list:
    """Each candidate's screening statistics, one row per candidate."""
    return [
        {
            "effect": f.name,
            "kind": f.kind,
            "screen_2dll": f.screen_2dll,
            "rank": f.rank,
            "screen_logp": f.screen_logp,
            "screen_ln_bf": f.screen_ln_bf,
            "screen_bic": f.screen_bic,
        }
        for f in fits
    ]


def _named_effects(effect_set, is_set: bool, ranking: list, verdict: str) -> list:
    """The effects the answer names with their parameters: the set's members,
    or the best single candidate when that is the answer."""
    if is_set:
        return effect_set["members"]
    if verdict in ("explained", "ambiguous"):
        return [{"effect": ranking[0]["effect"], "parameters": ranking[0]["parameters"]}]
    return []


def _log_summary(d: LogData, ctx: Context) -> dict:
    """What the log held and how it was split into training and held-out data."""
    return {
        "duration_s": d.duration_s,
        "imu_samples": int(d.imu_t.size),
        "pose_updates": int(d.pose_tc.size),
        "segments": int(d.pose_start.sum()),
        "valves": d.valves is not None,
        "thrusters": int(d.desc.n_thrusters),
        "manoeuvres": d.desc.manoeuvres() or None,
        "defaults_used": list(d.desc.defaults),
        "dropped": dict(d.dropped),
        "train_updates": int(ctx.train_nav.sum()),
        "heldout_updates": int(ctx.held_nav.sum()),
    }


def _partial_set(es: dict, ctx, fits, thr_glr, thr_map, t_map, held_shrink, held_dll, train_channels, null_map):
    """The set behind a partial answer: the selected members that each earn
    their place on the held-out data, refitted without the others once."""
    if es["partly_explains"] or es["explains_heldout"]:
        return es
    keep = [st for st, m in zip(es["_steps"], es["members"]) if m["adds_dll_heldout"] > HELDOUT_DLL_MIN]
    if not keep or len(keep) == len(es["members"]):
        return es
    return _effect_set(
        ctx,
        fits,
        thr_glr,
        thr_map,
        t_map,
        held_shrink,
        held_dll,
        train_channels,
        [],
        one_ok=True,
        null_map=null_map,
        steps=keep,
    )


def _set_member(ctx, sf, step: dict, sh: dict, dll_h: float, held_shrink, held_dll) -> dict:
    """One member of a jointly fitted set: its parameters from the joint fit and
    what it adds beside the others (the set refitted without it)."""
    from bench.gap import select

    n = step["effect"]
    nav_wo, dyn_wo = select.without(sf, ctx, n)
    sh_wo = held_shrink(nav_wo, dyn_wo)
    c = candidates_of(ctx.d)[n]
    return {
        "effect": n,
        "kind": c.kind,
        "conditional_logp": step["conditional_logp"],
        "parameters": parameters(ctx, n, sf.theta[n], sf.sigma[n]),
        "adds_shrink": (
            float(sh["fraction"] - sh_wo["fraction"])
            if np.isfinite(sh["fraction"]) and np.isfinite(sh_wo["fraction"])
            else None
        ),
        "adds_dll_heldout": float(dll_h - held_dll(nav_wo, dyn_wo)),
    }


def _members_shrink(members: list, sh: dict) -> bool:
    """Each member shrinks the held-out deficit beside the others, and the
    set's shrink interval excludes zero where it is measured: a member that
    adds log-likelihood but no shrink fits noise or another effect's
    look-alike (a hinged panel's momentum exchange read as a loss of under
    1 % with 0 % shrink)."""
    each = all(m["adds_shrink"] is None or m["adds_shrink"] > 0.0 for m in members)
    return each and (not sh["measurable"] or not np.isfinite(sh["ci95"][0]) or sh["ci95"][0] > 0.0)


def _effect_set(
    ctx,
    fits,
    thr_glr,
    thr_map,
    t_map,
    held_shrink,
    held_dll,
    train_channels,
    single: list,
    one_ok: bool = False,
    null_map=None,
    steps: list | None = None,
):
    """The forward-selected set, jointly refitted and tested on the held-out
    data like a single candidate; None when the selection stops at one effect
    (or at none: ``one_ok`` keeps a set of one, for the partial answer)."""
    from bench.gap import select

    d, ch = ctx.d, ctx.ch
    if steps is None:
        steps = select.forward_select(ctx, fits, thr_glr)
    if len(steps) < (1 if one_ok else 2):
        return None
    names = [st["effect"] for st in steps]
    sf = select.confirm_set(ctx, names, fits)
    sh = held_shrink(sf.after_nav, sf.after_dyn)
    dll_h = held_dll(sf.after_nav, sf.after_dyn)
    cells_after = map_cells(d, sf.after_nav) + localise.dyn_cells(d, ch, sf.after_dyn)
    map_after = localise.map_statistic(cells_after)
    shrink_ok = (
        (np.isfinite(sh["fraction"]) and sh["fraction"] >= SHRINK_MIN)
        or not sh["measurable"]
        or sh["deficit_after"] <= 2.0 * sh["deficit_null_sd"]
    )
    consistent = all(c["z"] >= -Z_CONTRADICT for c in train_channels(sf.after_nav, sf.after_dyn).values())
    best_single = max((r["evidence"]["dll_heldout"] for r in single if r["explains_heldout"]), default=-np.inf)
    members = [_set_member(ctx, sf, st, sh, dll_h, held_shrink, held_dll) for st in steps]
    needed = all(m["adds_dll_heldout"] > HELDOUT_DLL_MIN for m in members)
    remainder_left = map_after > thr_map
    explains = bool(
        len(members) >= 2
        and dll_h > HELDOUT_DLL_MIN
        and shrink_ok
        and consistent
        and needed
        and dll_h - best_single > HELDOUT_DLL_MIN
        and not remainder_left
    )
    # A partial answer: every member earns its place on the held-out data and
    # contradicts no channel, and what is left is still a gap.
    partly = bool(
        not explains
        and needed
        and _members_shrink(members, sh)
        and consistent
        and dll_h > HELDOUT_DLL_MIN
        and (remainder_left or not shrink_ok)
    )
    rem = localise.summarise(cells_after, null_map)["where"]
    return {
        "members": members,
        "shrink_heldout": sh,
        "dll_heldout": dll_h,
        "map_max_abs_z_after": map_after,
        "explains_heldout": explains,
        "partly_explains": partly,
        "every_member_needed": needed,
        "consistent": bool(consistent),
        "remainder_where": rem,
        "dll_heldout_gain_over_single": float(dll_h - best_single) if np.isfinite(best_single) else None,
        "_fit": sf,
        "_steps": steps,
    }


MIN_RUN_UPDATES = 10  # fewer fused pose updates than this: a run too short to show a gap
RATE_EXCITED_RPS = 0.01  # a body axis never turned faster than this relative to Hill: not excited


def examined(d: LogData, ctx: Context, detected: bool) -> dict:
    """What the diagnosis could and could not look at in this log: the
    channels (the dynamics need the valve stream), runs too short to show a
    gap, thrusters that never fired and body axes that never turned (their
    effects are not examined), and the defaults taken for what the log does
    not state."""
    ok = np.isfinite(ctx.nominal.nis)
    channels = {"pose": {"examined": bool(ok.sum() > 0), "rows": int(ok.sum())}}
    if not channels["pose"]["examined"]:
        channels["pose"]["why"] = "no pose update accepted by the filter"
    not_examined = []
    if ctx.ch is None:
        for name in ("accelerometer vs valves", "gyro vs valve torques"):
            channels[name] = {"examined": False, "why": "no valves stream"}
        not_examined.append(
            "dynamics (accelerometer and gyro against the commanded thrust): no valves stream, so "
            "thrust loss, thruster misalignment and mass depletion cannot be seen"
        )
    else:
        n_a = int(np.sum(ctx.ch.kind == 0))
        channels["accelerometer vs valves"] = {"examined": True, "rows": n_a}
        channels["gyro vs valve torques"] = {"examined": True, "rows": int(ctx.ch.rows - n_a)}
        fired = d.valves.sum(axis=0) * d.dt_s
        idle = [int(i) for i in np.flatnonzero(fired <= 0.0)]
        if idle:
            not_examined.append(
                f"thruster{'s' if len(idle) > 1 else ''} {', '.join(map(str, idle))} never fired: "
                "their loss and tilt are not examined"
            )
        for u in ctx.split.unexcited if ctx.split is not None else []:
            not_examined.append(f"{u['why']}: its loss and tilt are not identifiable from this log")
    seg = segment_of(d, d.pose_tc)
    short = [int(k) for k in np.unique(seg) if int(np.sum(ok & (seg == k))) < MIN_RUN_UPDATES]
    if short:
        not_examined.append(
            f"run{'s' if len(short) > 1 else ''} {', '.join(map(str, short))}: fewer than "
            f"{MIN_RUN_UPDATES} pose updates each"
        )
    if d.ref_q is not None:
        w_h = np.einsum("nji,j->ni", rotmats(d.ref_q), np.array([0.0, 0.0, d.n_radps]))
        w_bh = np.abs(d.gyro - w_h)
        still = [a for i, a in enumerate("xyz") if np.percentile(w_bh[:, i], 99) < RATE_EXCITED_RPS]
        if still:
            not_examined.append(
                f"rotation about body {', '.join(still)} never exceeded {RATE_EXCITED_RPS} rad/s: "
                "gyro scale on that axis is not examined"
            )
    looked = [k for k, v in channels.items() if v["examined"]]
    missing = [k for k, v in channels.items() if not v["examined"]]
    summary = (f"no gap in {', '.join(looked)}" if not detected else f"channels: {', '.join(looked)}") + (
        f"; not examined: {', '.join(missing)} ({channels[missing[0]]['why']})" if missing else ""
    )
    return {
        "summary": summary,
        "channels": channels,
        "not_examined": not_examined,
        "defaults_used": list(d.desc.defaults) if d.desc is not None else [],
        "dropped": dict(d.dropped),
    }


def public(result: dict) -> dict:
    out = {k: v for k, v in result.items() if not k.startswith("_")}
    if isinstance(out.get("effect_set"), dict):
        out["effect_set"] = {k: v for k, v in out["effect_set"].items() if not k.startswith("_")}
    return out
