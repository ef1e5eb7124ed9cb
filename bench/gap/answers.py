"""The diagnosis in words: the three answers (where, which, how far) and
what was and was not examined, written once for the command line and the
report, so both say the same thing.

A number is shown only where the JSON has it as measured: no shrink or
interval that is not finite or not measurable, and none for a candidate the
verdict rejected.
"""

from __future__ import annotations

import math

from bench.sim.flight_log import VALVE_OVERLAP_TOL_S

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


def fitted_text(out: dict) -> str | None:
    if not out["gap_detected"] or out["verdict"] == "unexplained" or not (out["attribution"] or out.get("effects")):
        return None
    members = out.get("effects") or [out["attribution"][0]]
    parts = []
    for m in members:
        pars = ", ".join(
            f"{k} {v['value']:.3g} +/- {v['sigma']:.2g}"
            for k, v in m["parameters"].items()
            if _finite(v["value"], v["sigma"]) and v["sigma"] > 0 and abs(v["value"]) > 2 * v["sigma"]
        )
        if pars:
            parts.append((f"{m['effect']}: " if len(members) > 1 else "") + pars)
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
