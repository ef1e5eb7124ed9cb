"""Stage 7 of the diagnosis (bench/gap/diagnose.py): confirm and select.
The screened candidates refitted with the full filter and judged on the
held-out data (rank), forward selection's set when several effects at once
explain more (bench/gap/select.py), the sets the data cannot tell from the
answer (bench/gap/alternatives.py), and the verdict (decide).

Detection uses two statistics, each with a threshold from the null
calibration (bench/gap/null.py, bench/gap/log_null.py): the largest |z| of the gap map, and the
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

from dataclasses import dataclass
from typing import Callable

import numpy as np

from bench.gap import localise, quantify
from bench.gap.attribute import BF_AMBIGUOUS, DELTA2_95, Context, at_bounds, bounded_fit, confirm
from bench.gap.candidates import CANDIDATES, candidates_of
from bench.gap.detection import map_cells
from bench.gap.load import LogData
from bench.gap.quantify import HeldOut

HELDOUT_DLL_MIN = 3.0

SHRINK_MIN = 0.5

N_CONFIRM = 4

Z_CONTRADICT = 3.0


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


def parameters(ctx: Context, name: str, theta, sigma) -> dict:
    """{name: {"value", "sigma", "identified"}} of a fit. A parameter the
    log cannot identify says why (``not_identifiable``) and has
    ``identified`` false:

    - no value at all (value and sigma None) when a valve fired in one half
      of the split only (quantify.excitation_split), or when there is no
      signature of it in the training time (its fitted spread zero or
      undefined): never a value with zero uncertainty;
    - its value and sigma kept, but not identified, when its 1-sigma is
      larger than the candidate's physical bound (``Candidate.bound``, the
      largest plausible |parameter|, inside which every fit is kept): the
      data then narrow it no further than the range it was fitted in, and
      the value is wherever the bounded fit happened to stop.
      A sigma large beside the value alone is no such sign: a parameter
      fitted near zero with a small sigma is identified as (near) zero.

    A parameter the fit holds at one of its physical bounds (attribute.at_bounds:
    a thrust loss at 0, a gyro scale at -0.5) is identified, at that bound:
    ``at_bound`` "lower" or "upper", ``bound`` the bound's value, and no
    sigma (None): the data push it against the bound, and the curvature
    there is no sampling uncertainty (a loss of 4e-15 +/- 2e-18 read as
    beyond 2 sigma). The free parameters' sigmas are computed with it held
    (attribute.fit_sigma)."""
    c = candidates_of(ctx.d)[name]
    unexcited = {u["valve"]: u["why"] for u in (ctx.split.unexcited if ctx.split is not None else [])}
    per_valve = {"thrust_loss": 1, "thruster_misalignment": 3}.get(name)
    held = at_bounds(np.asarray(theta, float) / c.scale, c.lower / c.scale, c.bound / c.scale)
    out = {}
    for i, (p, v, s) in enumerate(zip(c.params, theta, sigma)):
        why = unexcited.get(i // per_valve) if per_valve else None
        if why is None and not (np.isfinite(s) and s > 0.0):
            why = "no signature of it in the training time"
        if why:
            out[p] = {
                "value": None,
                "sigma": None,
                "identified": False,
                "not_identifiable": f"not identifiable from this log: {why}",
            }
        elif unidentified(float(s), c.bound):
            out[p] = {
                "value": float(v),
                "sigma": float(s),
                "identified": False,
                "not_identifiable": (
                    f"not identified: its sigma {float(s):.2g} exceeds the physical bound {c.bound:g}, "
                    "the data do not narrow it beyond the range it is fitted in"
                ),
            }
        elif held[i]:
            side = "lower" if held[i] < 0 else "upper"
            out[p] = {
                "value": float(v),
                "sigma": None,
                "identified": True,
                "at_bound": side,
                "bound": float(c.lower if held[i] < 0 else c.bound),
            }
        else:
            out[p] = {"value": float(v), "sigma": float(s), "identified": True}
    return out


def unidentified(sigma: float, bound: float) -> bool:
    """A fitted parameter the data do not identify: its 1-sigma is larger
    than the candidate's physical bound (parameters())."""
    return bool(np.isfinite(bound) and sigma > bound)


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


def rank(ctx: Context, fits: list, scores: HeldOut, n_confirm: int, prog, thr_map: float, t_map: float) -> list:
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


def single_answer(d: LogData, fits: list, ranking: list) -> tuple:
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


@dataclass(frozen=True)
class SetScores:
    """What a jointly fitted set is fitted on and judged by, the same for the
    set forward selection picks and for the partial answer made of its
    members (_effect_set, _partial_set): the log's context and screened
    fits, the screening threshold (-log10 p), the gap map's threshold and
    statistic, the held-out scores (quantify.HeldOut: shrink, log-likelihood
    gain, each training channel's gain) and the null's largest map |z| per
    cell (to locate a remainder)."""

    ctx: Context
    fits: list
    thr_glr: float
    thr_map: float
    t_map: float
    held_shrink: Callable
    held_dll: Callable
    train_channels: Callable
    null_map: object = None


def set_answer(
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
    set_scores = SetScores(
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
    effect_set = _effect_set(
        set_scores, ranking if verdict in ("explained", "ambiguous") else [], one_ok=verdict == "unexplained"
    )
    if effect_set is not None and effect_set["explains_heldout"]:
        # Sets the data cannot tell from this one: ambiguous.
        ambiguous_with = _listed(ctx, fits, [m["effect"] for m in effect_set["members"]], thr_glr, [])
        return ("ambiguous" if ambiguous_with else "explained"), effect_set, ambiguous_with
    if verdict in ("explained", "ambiguous") and ranking:  # the single answer, and the sets beside it
        ambiguous_with = _listed(ctx, fits, [ranking[0]["effect"]], thr_glr, ambiguous_with)
        verdict = "ambiguous" if ambiguous_with else verdict
    if verdict == "unexplained" and effect_set is not None:
        effect_set = _partial_set(effect_set, set_scores)
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


def _partial_set(es: dict, set_scores: SetScores):
    """The set behind a partial answer: the selected members that each earn
    their place on the held-out data, refitted without the others once."""
    if es["partly_explains"] or es["explains_heldout"]:
        return es
    keep = [st for st, m in zip(es["_steps"], es["members"]) if m["adds_dll_heldout"] > HELDOUT_DLL_MIN]
    if not keep or len(keep) == len(es["members"]):
        return es
    return _effect_set(set_scores, [], one_ok=True, steps=keep)


def _set_member(set_scores: SetScores, sf, step: dict, sh: dict, dll_h: float) -> dict:
    """One member of a jointly fitted set: its parameters from the joint fit and
    what it adds beside the others (the set refitted without it)."""
    from bench.gap import select

    ctx, n = set_scores.ctx, step["effect"]
    nav_wo, dyn_wo = select.without(sf, ctx, n)
    sh_wo = set_scores.held_shrink(nav_wo, dyn_wo)
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
        "adds_dll_heldout": float(dll_h - set_scores.held_dll(nav_wo, dyn_wo)),
    }


def _members_shrink(members: list, sh: dict) -> bool:
    """Each member shrinks the held-out deficit beside the others, and the
    set's shrink interval excludes zero where it is measured: a member that
    adds log-likelihood but no shrink fits noise or another effect's
    look-alike (a hinged panel's momentum exchange read as a loss of under
    1 % with 0 % shrink)."""
    each = all(m["adds_shrink"] is None or m["adds_shrink"] > 0.0 for m in members)
    return each and (not sh["measurable"] or not np.isfinite(sh["ci95"][0]) or sh["ci95"][0] > 0.0)


def _effect_set(set_scores: SetScores, single: list, one_ok: bool = False, steps: list | None = None):
    """The forward-selected set (or ``steps``), jointly refitted and tested on
    the held-out data like a single candidate; None when the selection stops
    at one effect (or at none: ``one_ok`` keeps a set of one, for the partial
    answer)."""
    from bench.gap import select

    ctx, fits, thr_map = set_scores.ctx, set_scores.fits, set_scores.thr_map
    d, ch = ctx.d, ctx.ch
    if steps is None:
        steps = select.forward_select(ctx, fits, set_scores.thr_glr)
    if len(steps) < (1 if one_ok else 2):
        return None
    names = [st["effect"] for st in steps]
    sf = select.confirm_set(ctx, names, fits)
    sh = set_scores.held_shrink(sf.after_nav, sf.after_dyn)
    dll_h = set_scores.held_dll(sf.after_nav, sf.after_dyn)
    cells_after = map_cells(d, sf.after_nav) + localise.dyn_cells(d, ch, sf.after_dyn)
    map_after = localise.map_statistic(cells_after)
    shrink_ok = (
        (np.isfinite(sh["fraction"]) and sh["fraction"] >= SHRINK_MIN)
        or not sh["measurable"]
        or sh["deficit_after"] <= 2.0 * sh["deficit_null_sd"]
    )
    consistent = all(c["z"] >= -Z_CONTRADICT for c in set_scores.train_channels(sf.after_nav, sf.after_dyn).values())
    best_single = max((r["evidence"]["dll_heldout"] for r in single if r["explains_heldout"]), default=-np.inf)
    members = [_set_member(set_scores, sf, st, sh, dll_h) for st in steps]
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
    rem = localise.summarise(cells_after, set_scores.null_map)["where"]
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


def decide(ctx: Context, fits: list, scores: HeldOut, cal: dict, ranking: list, t_map: float) -> tuple:
    """(verdict, effect_set, ambiguous_with, ranking) of a detected gap: the
    single answer (single_answer), then several effects at once
    (set_answer)."""
    thr = cal.get("thresholds", {})
    thr_map, thr_glr = float(thr.get("map_max_abs_z", np.inf)), float(thr.get("screen_logp", np.inf))
    verdict, ambiguous_with, ranking = single_answer(ctx.d, fits, ranking)
    verdict, effect_set, ambiguous_with = set_answer(
        ctx, fits, scores, cal, thr_glr, thr_map, t_map, verdict, ranking, ambiguous_with
    )
    return verdict, effect_set, ambiguous_with, ranking
