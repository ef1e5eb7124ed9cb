"""The diagnosis in words: the three answers (where, which, how far) and
what was and was not examined, written once for the command line and the
report, so both say the same thing.

A number is shown only where the JSON has it as measured: no shrink or
interval that is not finite or not measurable, and none for a candidate the
verdict rejected.
"""

from __future__ import annotations

import math

import numpy as np

from bench.gap import localise
from bench.gap.attribute import Context
from bench.gap.candidates import NOT_MODELLED
from bench.gap.load import LogData
from bench.gap.quantify import channel_rms, heldout_runs_shrink, segment_of
from bench.sim.flight_log import VALVE_OVERLAP_TOL_S
from bench.so3 import rotmats

# The count of valve pulses that ran past the next command and were ended
# there (bench/gap/replay.py); every other entry of ``dropped`` is left out.
CLIPPED = "valve pulses clipped at the next command"


def _finite(*xs) -> bool:
    return all(x is not None and isinstance(x, (int, float)) and math.isfinite(x) for x in xs)


def where_text(out: dict) -> str | None:
    """One "where": the gap map's strongest cell, and the regime in which the
    named effect acts (its signature's) or, without one, where the gap map is
    strongest."""
    if not out["gap_detected"]:
        return None
    loc = out["location"]
    w = loc["where"] or {}
    acts = loc.get("effect_acts_while")
    regime = (
        f"the effect acts mostly while {acts['peak']}"
        if acts and acts.get("peak")
        else f"strongest while {w.get('regime_peak')}"
    )
    kind = loc.get("dynamics_or_sensor")
    return f"{w.get('stream')} {w.get('axis')} ({w.get('stat')}); {regime}" + (f"; a {kind} gap" if kind else "")


# How many of the sets an answer cannot be told from the one-line answer
# shows; the JSON and the report list them all.
SHOWN_SETS = 4


def listed_sets(out: dict) -> list:
    """The sets the answer lists beside its own, each as its members: the
    answer cannot be told from any of them."""
    return [list(a["set"]) if "set" in a else [a["effect"]] for a in out.get("ambiguous_with") or []]


def _sets_text(out: dict) -> str:
    sets = listed_sets(out)
    if not sets:
        return ""
    shown = "; ".join(" + ".join(s) or "none of the library" for s in sets[:SHOWN_SETS])
    more = f"; {len(sets) - SHOWN_SETS} more sets in the JSON" if len(sets) > SHOWN_SETS else ""
    return f"; cannot be told from: {shown}{more}"


def which_text(out: dict) -> str | None:
    if not out["gap_detected"]:
        return None
    v = out["verdict"]
    if v == "unexplained":
        sets = listed_sets(out)
        parts = "; ".join(" + ".join(s) for s in sets[:SHOWN_SETS])
        more = f"; {len(sets) - SHOWN_SETS} more sets in the JSON" if len(sets) > SHOWN_SETS else ""
        return "unexplained: no effect in the library accounts for the gap on held-out data" + (
            f"; in the library, part of it could be: {parts}{more}" if sets else ""
        )
    if v == "partly_explained":
        names = " + ".join(m["effect"] for m in out.get("effects") or [])
        return (
            f"{names} (partly explained: each accounts for part of the gap on held-out data; "
            f"a remainder no effect in the library accounts for stays{_sets_text(out)})"
        )
    if len(out.get("effects") or []) > 1:
        return " + ".join(m["effect"] for m in out["effects"]) + f" ({v}, together{_sets_text(out)})"
    return f"{out['attribution'][0]['effect']} ({v}{_sets_text(out)})"


def identified(v: dict) -> bool:
    """Whether a fitted parameter's value is shown: the diagnosis's own flag
    (bench/gap/verdict.py parameters: not identified when its sigma exceeds
    the candidate's physical bound, or when the log cannot identify it at
    all); an answer written before the flag: whether it has a value."""
    return bool(v.get("identified", v.get("value") is not None))


def not_identified_count(params: dict) -> int:
    """How many of a fit's parameters are not identified (identified)."""
    return sum(not identified(v) for v in params.values())


def counted_text(params: dict) -> str:
    """How many parameters a fit has and how many the data do not identify,
    as the printed answer and the report both say it: " (24 parameters, 16
    not identified)"; "" when every one is identified."""
    n_not = not_identified_count(params)
    return f" ({len(params)} parameter{'s' if len(params) != 1 else ''}, {n_not} not identified)" if n_not else ""


def at_bound(v: dict) -> bool:
    """Whether the fit holds a parameter at a physical bound (bench/gap/verdict.py
    parameters): shown at the bound, with no sigma, never beyond 2 sigma."""
    return identified(v) and v.get("at_bound") in ("lower", "upper")


def significant(v: dict) -> bool:
    """An identified parameter fitted beyond 2 sigma of zero; one held at a
    bound has no sampling sigma and never is."""
    return (
        identified(v)
        and not at_bound(v)
        and _finite(v.get("value"), v.get("sigma"))
        and v["sigma"] > 0
        and abs(v["value"]) > 2 * v["sigma"]
    )


def bound_text(params: dict) -> str:
    """The parameters held at a physical bound, grouped by bound, as the
    printed answer and the report both say it: " (at the lower bound 0:
    loss_5 [1], loss_7 [1])"; "" when none is."""
    groups = {}
    for k, v in params.items():
        if at_bound(v):
            groups.setdefault((v["at_bound"], v.get("bound")), []).append(k)
    parts = [
        f"at the {side} bound{f' {b:g}' if _finite(b) else ''}: {', '.join(ks)}" for (side, b), ks in groups.items()
    ]
    return f" ({'; '.join(parts)})" if parts else ""


def fitted_text(out: dict) -> str | None:
    """The named effects' parameters beyond 2 sigma, those the fit holds at a
    physical bound (never beyond 2 sigma: bound_text), and for each effect
    with parameters the data do not identify, how many: those are never
    shown as values."""
    if not out["gap_detected"] or out["verdict"] == "unexplained" or not (out["attribution"] or out.get("effects")):
        return None
    members = out.get("effects") or [out["attribution"][0]]
    parts = []
    for m in members:
        pars = ", ".join(
            f"{k} {v['value']:.3g} +/- {v['sigma']:.2g}" for k, v in m["parameters"].items() if significant(v)
        )
        held = bound_text(m["parameters"])
        counted = counted_text(m["parameters"])
        if pars or held or counted:
            parts.append((f"{m['effect']}: " if len(members) > 1 else "") + (pars or "none") + held + counted)
    return "fitted (beyond 2 sigma): " + "; ".join(parts) if parts else None


def how_far_lines(out: dict) -> list:
    if not out["gap_detected"]:
        return []
    if out["verdict"] == "unexplained":
        return ["no shrink to report: no candidate explains the held-out data"]
    es = out.get("effect_set")
    partly = out["verdict"] == "partly_explained"
    if es and (es.get("explains_heldout") or partly):
        sh = es["shrink_heldout"]
        lines = []
        together = "with it" if len(es["members"]) == 1 else f"with all {len(es['members'])} together"
        if sh.get("measurable", True) and _finite(sh.get("fraction")) and _finite(*sh.get("ci95", [None, None])):
            lines.append(
                f"held-out deficit shrinks {100 * sh['fraction']:.0f} % "
                f"[95 % CI {100 * sh['ci95'][0]:.0f}, {100 * sh['ci95'][1]:.0f}] {together}"
            )
        for m in es["members"]:
            if len(es["members"]) == 1:
                lines.append(f"{m['effect']}: held-out log-likelihood +{m['adds_dll_heldout']:.1f}")
                continue
            add = f"{100 * m['adds_shrink']:.0f} % of the shrink" if _finite(m.get("adds_shrink")) else "its share"
            lines.append(
                f"{m['effect']} adds {add} beside the others (held-out log-likelihood +{m['adds_dll_heldout']:.1f})"
            )
        if partly:
            rem = es.get("remainder_where") or {}
            left = (
                f"{100 * (1 - sh['fraction']):.0f} % of the held-out deficit left; "
                if sh.get("measurable", True) and _finite(sh.get("fraction"))
                else ""
            )
            lines.append(
                f"remainder: {left}gap map |z| {es['map_max_abs_z_after']:.1f} after the fit, strongest in "
                f"{rem.get('stream')} {rem.get('axis')} ({rem.get('stat')}) while {rem.get('regime_peak')}"
            )
        return lines
    best = out["attribution"][0]
    sh = best["shrink_heldout"]
    lines = []
    if sh.get("measurable", True) and _finite(sh.get("fraction")) and _finite(*sh.get("ci95", [None, None])):
        lines.append(
            f"held-out deficit shrinks {100 * sh['fraction']:.0f} % "
            f"[95 % CI {100 * sh['ci95'][0]:.0f}, {100 * sh['ci95'][1]:.0f}] with {best['effect']}"
        )
    else:
        lines.append(
            f"held-out shrink not measurable: the held-out blocks' deficit does not stand out of its noise "
            f"(the effect is named from the training fit and the held-out likelihood gain "
            f"{best['evidence']['dll_heldout']:.1f})"
        )
    r = out.get("shrink_heldout_runs")
    if r and _finite(r.get("fraction")) and _finite(*r.get("ci95", [None, None])):
        lines.append(
            f"on held-out runs ({r['heldout_runs']} of {r['runs']}, fitted on the others): "
            f"{100 * r['fraction']:.0f} % [95 % CI {100 * r['ci95'][0]:.0f}, {100 * r['ci95'][1]:.0f}]"
        )
    elif r and r.get("runs", 0) >= 2:
        lines.append(f"on held-out runs: not measured ({r.get('reason', 'no deficit left there to shrink')})")
    return lines


def examined_lines(out: dict) -> list:
    ex = out.get("examined") or {}
    lines = []
    if ex.get("summary"):
        lines.append(ex["summary"])
    lines += [f"not examined: {x}" for x in ex.get("not_examined", [])]
    for why, n in (ex.get("dropped") or {}).items():
        lines.append(
            f"{n} {why} (each ran past it by less than {VALVE_OVERLAP_TOL_S * 1e3:g} ms)"
            if why == CLIPPED
            else f"left out: {n} {why}"
        )
    d = ex.get("defaults_used") or []
    if d:
        lines.append("defaults taken (the log does not state them): " + "; ".join(d))
    cal = out.get("calibration") or {}
    if cal.get("note"):
        lines.append(cal["note"])
    return lines


def answer_lines(out: dict) -> list:
    """(label, text) pairs of the whole answer, in reading order."""
    rows = [("gap detected", "yes" if out["gap_detected"] else "no")]
    for label, text in (("where", where_text(out)), ("which", which_text(out)), ("", fitted_text(out))):
        if text:
            rows.append((label, text))
    for i, t in enumerate(how_far_lines(out)):
        rows.append(("how far" if i == 0 else "", t))
    for i, t in enumerate(examined_lines(out)):
        rows.append(("examined" if i == 0 else "", t))
    return rows


# --- the answer as JSON -------------------------------------------------------


MIN_RUN_UPDATES = 10  # fewer fused pose updates than this: a run too short to show a gap

RATE_EXCITED_RPS = 0.01  # a body axis never turned faster than this relative to Hill: not excited


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


def result(
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
    """The JSON-ready answer of diagnose() (stage 8)."""
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
        "replay_rms_heldout_before": channel_rms(nominal.innovation[held]),
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
