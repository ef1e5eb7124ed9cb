"""Designed plans, flown and diagnosed: ``proxops validate-gap --plans``.

The designed plan (bench/gap/design.py, docs/GAP.md "Designing the test
that separates") checked as a campaign, not on one log:

1. Draws: runs of two or three effects as the mixture campaign draws them
   (bench/campaigns/gap/validate_mixtures.py draw_mixtures: in-library
   pairs and triples, one in-library effect beside one out of the library,
   random directions), every member at 2x its own minimum detectable size
   in the run, on docking logs; or the 2x runs of recorded mixture
   campaigns at their recorded sizes (``recorded``). Each docking log is
   diagnosed with the committed docking calibration (as the mixture
   campaign does); a run is kept when its answer is ambiguous, or when its
   true in-library set is not the answer but is one of the sets it lists.
2. For each kept run (``plan_run``): the plan designed from the answer
   under the selection criterion (the defaults: every direction of a
   hidden member, two passes, 120 s and the fixed characterisation's
   delta-v; each test at its level at the docking log's screening
   threshold), the shortest plan reaching every level within half the
   fixed plan's duration and delta-v (``--reach``), and the continuous
   bound within NEEDED_LIMITS (design.continuous_bound: whether any plan
   of the blocks reaches the levels there); their shares of the levels
   and the tests they leave short. The true effects are flown on each plan
   and on the fixed characterisation by the bench's vehicle simulator
   (bench/sim/vehicle_sim.py, as ``proxops plan --check``): their distance
   from every listed set that does not hold the true set, and each true
   member's selection test (the true set against it without that member,
   half of it against the member's level). The designed plan is then appended to the
   docking log: the same docking runs with the same effects, then the
   plan's runs open loop (bench.sim.reality ``then_scripts``, as the
   docking-then-characterisation campaign appends the fixed plan), and the
   whole log is diagnosed again. The same docking seed and plan flown
   without any effect and diagnosed is the false-alarm check.
3. On Basilisk (``basilisk_run``, inside ``plan_run`` for ``basilisk_runs``
   kept runs spread over those whose effects its engine flies): the designed plan alone, flown with the true effects and
   without, each log diagnosed alone with a calibration made for it (a
   Basilisk flight cannot be appended to a bench docking log), beside the
   same plan alone flown by the bench's vehicle simulator.

Scores (``score_plans``), over the kept runs: the exact set named after
the plan (the named set is the true in-library set), and settled (named,
and the answer no longer ambiguous); the true set the answer or listed;
every level reached (predicted: the default plan, within half the fixed
plan, the fixed plan, the continuous bound within NEEDED_LIMITS; flown:
every true member's test, and 10.8 from the nearest listed set); false
alarms on the effect-free flights. Targets: TARGETS.
"""

from __future__ import annotations

import gzip
import json
import time
from pathlib import Path

import numpy as np

from bench.gap.attribute import DELTA2_95
from bench.sim.plans import DT_S

TARGETS = {"exact_set": 0.90, "false_alarms": 0.02, "duration_share": 0.5, "delta_v_share": 0.5}
SCALE = 2.0
# The widest limits the campaign asks the shortest plan reaching every
# level within (duration [s], delta-v [m/s]): what the data would need.
NEEDED_LIMITS = (1200.0, 1.6)


# --- the draws -----------------------------------------------------------------------------------


def draw_keys(n_runs: int, seed: int) -> list:
    """The mixture campaign's draws (validate_mixtures.draw_mixtures), every
    run at 2x (the size is found by ``size_key``)."""
    from bench.campaigns.gap.validate_mixtures import draw_mixtures

    return [dict(k, scale=SCALE, source=f"drawn, seed {seed}") for k in draw_mixtures(n_runs, seed)]


def recorded_keys(paths: list) -> list:
    """The 2x runs of recorded mixture campaigns (their JSON or .full.json.gz)
    whose every member was detectable, at their recorded sizes, numbered
    afresh in order (``source`` and ``recorded_run`` say where each is from)."""
    keys = []
    for p in paths:
        opener = gzip.open if str(p).endswith(".gz") else open
        with opener(p, "rt") as f:
            rec = json.load(f)
        if rec.get("manoeuvres", "docking") != "docking":
            raise ValueError(f"{p}: a campaign of {rec['manoeuvres']} logs; the plans are appended to docking logs")
        for k in rec["keys"]:
            if k["scale"] == SCALE and k.get("detectable", True):
                keys.append(dict(k, source=Path(p).name, recorded_run=k["run"]))
    return [dict(k, run=i) for i, k in enumerate(keys)]


def size_key(key: dict, shared) -> dict:
    """Each member at 2x its own minimum detectable size in the run (the
    mixture campaign's sizing); a key drawn from a record keeps its sizes."""
    if key.get("effects"):
        return key
    from dataclasses import replace

    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS, max_size_for
    from bench.sim.log_description import resolve

    duration_s, calibration = shared
    key = dict(key, min_detectable={}, effects={})
    for e in key["members"]:
        spec = replace(EFFECTS[e], max_size=max_size_for(e, resolve(None)))
        md = min_detectable_size(key["seed"], e, key["units"][e], duration_s, calibration, max_size=spec.max_size)
        size = float(min(key["scale"] * md["size"] if md["detectable"] else spec.max_size, spec.max_size))
        key["min_detectable"][e] = md["size"] if md["detectable"] else None
        key["effects"][e] = [float(x) for x in spec.at(key["units"][e], size)]
    key["detectable"] = all(v is not None for v in key["min_detectable"].values())
    return key


def truth_in(key: dict) -> list:
    from bench.sim.effects import EFFECTS

    return sorted(e for e in key["members"] if EFFECTS[e].in_library)


def answer_of(pub: dict, key: dict) -> dict:
    """A diagnosis as scored: the named set, the listed sets, exact, listed,
    settled (exact and not ambiguous)."""
    from bench.gap.answers import listed_sets

    named = [m["effect"] for m in pub["effects"]] if pub["gap_detected"] else []
    alts = [sorted(s) for s in listed_sets(pub)] if pub["gap_detected"] else []
    truth = set(truth_in(key))
    exact = set(named) == truth and pub["verdict"] != "unexplained"
    return {
        "gap_detected": bool(pub["gap_detected"]),
        "verdict": pub["verdict"],
        "named": named,
        "alternatives": alts,
        "exact": bool(exact),
        "listed": bool(exact or any(set(a) == truth for a in alts)),
        "settled": bool(exact and pub["verdict"] != "ambiguous"),
        "t_diagnose_s": pub.get("elapsed_s"),
    }


def docking_log(key: dict, duration_s: float, effects: dict | None = None, then: list | None = None):
    """The run's docking log, blind (what a user's log holds); ``then``: valve scripts flown after it."""
    from bench.campaigns.gap.validate import blind
    from bench.sim.reality import simulate_log_with_key

    eff = key["effects"] if effects is None else effects
    log, _ = simulate_log_with_key(key["seed"], eff, duration_s=duration_s, with_truth=False, then_scripts=then)
    return blind(log)


def diagnose_docking(key: dict, shared) -> dict:
    """The docking log diagnosed as the mixture campaign does; kept when
    ambiguous, or when the true set is listed but not the answer."""
    from bench.gap.diagnose import diagnose, public

    duration_s, calibration = shared
    pub = public(diagnose(docking_log(key, duration_s), calibration=calibration))
    a = answer_of(pub, key)
    a["run"] = key["run"]
    a["kept"] = bool(a["gap_detected"] and (a["verdict"] == "ambiguous" or (a["listed"] and not a["exact"])))
    # What the design reads back (design.sets_of_diagnosis), as a saved diagnosis holds it.
    a["diagnosis"] = {k: pub.get(k) for k in ("verdict", "gap_detected", "effects", "ambiguous_with")}
    return a


# --- the plans, designed and flown ---------------------------------------------------------------


def plan_scripts(plan: dict) -> list:
    """The plan's runs as the bench's docking engine flies valve scripts
    (one configuration per control interval, bit i opens valve i)."""
    out = []
    for r in plan["schedule"]:
        ((v, [[a, b]]),) = r["valves"].items()
        n_lead, n_on, n_coast = (int(round(x / DT_S)) for x in (a, b - a, r["duration_s"] - b))
        out.append([0] * n_lead + [1 << int(v)] * n_on + [0] * n_coast)
    return out


def plan_row(res: dict, key: str) -> dict:
    """A plan's cost, predicted distances and share of the selection's
    levels; the tests it leaves short of their level."""
    p = res[key]
    return {
        "duration_s": p["duration_s"],
        "delta_v_mps": p["delta_v_mps"],
        "runs": p["runs"],
        "delta2_min": p["delta2_min"],
        "level_min": p["level_min"],
        # before rounding to whole runs (the optimiser's plan)
        "continuous_level_min": (
            res["designed_continuous"]["level_min"] if key == "designed" and "designed_continuous" in res else None
        ),
        "short": [
            {k: r[k] for k in ("a", "b", "test", "delta2_half", "required_half")}
            for r in p["pairs"]
            if not r.get("reached", r["separated_95"])
        ],
        "pairs": len(p["pairs"]),
    }


def true_hypothesis(key: dict):
    """The run's true effects as a hypothesis: its in-library members, every effect flown."""
    from bench.gap.design import Hypothesis

    return Hypothesis(truth_in(key), {k: np.asarray(v) for k, v in key["effects"].items()}, "the true effects")


def flown_true(key: dict, description: dict, plan: dict, hyps: list, levels: dict | None = None) -> dict:
    """The true effects flown on ``plan`` by the bench's vehicle simulator
    (common random numbers): their distance from each listed set that does
    not hold the true set (design.flown_distances), and the smallest; and
    the selection's own test of each true member on that flight: the true
    set against it without that member, half of it against the level
    ``levels`` (design.member_levels) asks."""
    from bench.gap.design import Hypothesis, committed_screen_logp, flown_distances, plan_segments, selection_level
    from bench.sim.vehicle_sim import KNOWN

    missing = sorted(set(key["effects"]) - set(KNOWN))
    if missing:
        return {"flown": False, "why": f"{', '.join(missing)} not flown by the vehicle simulator"}
    truth = true_hypothesis(key)
    others = [h for h in hyps if set(h.members) != set(truth.members)]
    if not others or not truth.members:
        return {"flown": False, "why": "no listed set to measure against"}
    listed = {frozenset(h.members) for h in others}
    without = [
        Hypothesis([n for n in truth.members if n != c], {}, f"without {c}")
        for c in truth.members
        if frozenset(n for n in truth.members if n != c) not in listed
    ]
    segs = plan_segments(plan, len(description["vehicle"]["thrusters"]))
    f = flown_distances(description, segs, [truth, *others, *without], 0, key["seed"])
    nothing = Hypothesis([], {}).name
    d2 = {frozenset() if p["b"] == nothing else frozenset(p["b"].split(" + ")): p["delta2"] for p in f["pairs"]}
    pairs = [{"b": h.name, "delta2": d2[frozenset(h.members)]} for h in others if frozenset(h.members) in d2]
    members = []
    for c in truth.members:
        rest = frozenset(n for n in truth.members if n != c)  # a listed set may name its members in another order
        lv = (levels or {}).get(c)
        rank = np.asarray(key["effects"][c]).size  # no listed set holds it: its parameters
        req = lv["required_half"] if lv else max(DELTA2_95, selection_level(committed_screen_logp(), rank))
        members.append({"member": c, "delta2_half": 0.5 * d2[rest], "required_half": req})
    for m in members:
        m["reached"] = bool(m["delta2_half"] >= m["required_half"])
    out = {"flown": bool(pairs), "lambda": f["lambda"], "members": members}
    if not pairs:  # every listed set holds the true set: nothing it must be told from
        return {**out, "why": "every other listed set holds the true set"}
    return {**out, "pairs": pairs, "delta2_min": min(p["delta2"] for p in pairs)}


def listed_of_unexplained(diagnosis: dict) -> list | None:
    """An unexplained answer names no set to separate, but lists the library
    parts that may sit beside what the library lacks: with two or more,
    the plan separates those (as ``proxops plan --hypotheses`` would)."""
    from bench.gap.answers import listed_sets

    sets = listed_sets(diagnosis) if diagnosis.get("verdict") == "unexplained" else []
    return [list(x) for x in sets] if len(sets) >= 2 else None


def designs(key: dict, log, diagnosis: dict) -> tuple:
    """(hypotheses, description, the default design, the shortest design
    reaching the selection's levels within half the fixed plan's duration
    and delta-v, and the continuous bound within NEEDED_LIMITS), each at the
    screening threshold the docking log was judged by."""
    from bench.gap.design import continuous_bound, description_of, design, diagnosis_screen_logp, hypotheses_for

    hyps, _ = hypotheses_for(log, diagnosis, listed_of_unexplained(diagnosis))
    description = description_of(log)
    thr = diagnosis_screen_logp(diagnosis)
    res = design(hyps, description, screen_logp=thr)
    fixed_t, fixed_v = res["fixed"]["duration_s"], res["fixed"]["delta_v_mps"]
    half = design(hyps, description, 0.5 * fixed_t, 0.5 * fixed_v, screen_logp=thr, reach=True)
    needed = continuous_bound(hyps, description, *NEEDED_LIMITS, screen_logp=thr)
    return hyps, description, res, half, needed


def appended(key: dict, duration_s: float, scripts: list, calibration: dict) -> dict:
    """The plan appended to the docking log, with the true effects and
    without any, each diagnosed: the answer after the plan, and whether the
    effect-free flight raised a gap (a false alarm)."""
    from bench.gap.diagnose import diagnose, public

    pub = public(diagnose(docking_log(key, duration_s, then=scripts), calibration=calibration))
    null = public(diagnose(docking_log(key, duration_s, effects={}, then=scripts), calibration=calibration))
    return {
        "after": answer_of(pub, key),
        "null": {"gap_detected": bool(null["gap_detected"]), "verdict": null["verdict"]},
    }


def fixed_appended(key: dict, duration_s: float) -> dict:
    """For comparison: the fixed characterisation (each valve alone 3 s, then
    20 s) appended to the docking log instead, diagnosed with the committed
    calibration of such logs (the docking-then-characterisation campaign's)."""
    from bench.gap import null as nullmod
    from bench.gap.diagnose import diagnose, public
    from bench.sim.plans import CHARACTERISATION_COAST_S, CHARACTERISATION_FIRE_S, single_valve_scripts

    then = single_valve_scripts(CHARACTERISATION_FIRE_S, CHARACTERISATION_COAST_S)
    cal = nullmod.load(manoeuvres="docking+characterisation")
    return answer_of(public(diagnose(docking_log(key, duration_s, then=then), calibration=cal)), key)


def plan_run(item, shared) -> dict:
    """One kept run: the plans designed from its answer, flown and diagnosed
    (module docstring, step 2)."""
    key, answer = item
    duration_s, calibration = shared
    t0 = time.time()
    out = {"run": key["run"], "before": {k: answer[k] for k in ("verdict", "named", "alternatives", "exact")}}
    log = docking_log(key, duration_s)
    try:
        hyps, description, res, half, needed = designs(key, log, answer["diagnosis"])
    except ValueError as exc:  # e.g. an answer that names no effect: nothing to design from
        out.update(designed=False, why=str(exc), elapsed_s=time.time() - t0)
        return out
    out["designed"] = True
    out["hypotheses"] = [h.name for h in hyps]
    out["hypotheses_from"] = (
        "the listed sets of an unexplained answer"
        if listed_of_unexplained(answer["diagnosis"])
        else "the answer and the sets it lists"
    )
    out["plans"] = {"designed": plan_row(res, "designed"), "half": plan_row(half, "designed")}
    out["plans"]["fixed"] = plan_row(res, "fixed")
    out["plans"]["half"]["target_reached"] = bool(half.get("target_reached"))
    out["needed"] = needed
    out["levels"] = res.get("levels")
    out["schedule"] = [{"valves": r["valves"], "duration_s": r["duration_s"]} for r in res["designed"]["schedule"]]
    out["flown_true"] = {
        "designed": flown_true(key, description, res["designed"], hyps, res.get("levels")),
        "half": flown_true(key, description, half["designed"], hyps, res.get("levels")),
        "fixed": flown_true(key, description, res["fixed"], hyps, res.get("levels")),
    }
    out.update(appended(key, duration_s, plan_scripts(res["designed"]), calibration))
    out["fixed_after"] = fixed_appended(key, duration_s)
    if answer.get("basilisk"):
        try:
            out["elsewhere"] = basilisk_run((key, out), shared)
        except Exception as exc:  # noqa: BLE001 - the bench engine's results stand without it
            out["elsewhere"] = {"error": f"{type(exc).__name__}: {exc}"}
    out["elapsed_s"] = time.time() - t0
    return out


def _plan_alone(description: dict, segs: list, effects: dict, seed: int, engine: str) -> dict:
    """The plan alone flown by ``engine`` and diagnosed with a calibration made for its log."""
    from bench.gap.diagnose import diagnose, public

    if engine == "basilisk":
        from bench.sim.basilisk_sim import simulate
    else:
        from bench.sim.vehicle_sim import simulate
    log, _ = simulate(description, segs, effects, seed=seed, with_truth=False)
    return public(diagnose(log))


def basilisk_run(item, shared) -> dict:
    """The designed plan alone (``plan_run``'s schedule so far), flown with the true
    effects and without by Basilisk and by the bench's vehicle simulator,
    each log diagnosed alone (module docstring, step 3)."""
    from bench.gap.design import description_of, plan_segments

    key, planned = item
    duration_s, _ = shared
    t0 = time.time()
    description = description_of(docking_log(key, duration_s))
    segs = plan_segments({"schedule": planned["schedule"]}, len(description["vehicle"]["thrusters"]))
    out = {"run": key["run"]}
    for engine in ("basilisk", "bench"):
        t1 = time.time()
        pub = _plan_alone(description, segs, key["effects"], key["seed"], engine)
        null = _plan_alone(description, segs, {}, key["seed"], engine)
        out[engine] = {
            "after": answer_of(pub, key),
            "null": {"gap_detected": bool(null["gap_detected"]), "verdict": null["verdict"]},
            "calibration": (pub.get("calibration") or {}).get("source"),
            "elapsed_s": time.time() - t1,
        }
    out["elapsed_s"] = time.time() - t0
    return out


def basilisk_flies(key: dict) -> bool:
    from bench.sim.basilisk_sim import EFFECTS_HERE

    return set(key["effects"]) <= set(EFFECTS_HERE)


def basilisk_subset(kept: list, n: int) -> set:
    """The kept runs that also fly their plan on Basilisk: ``n`` spread evenly
    over those whose effects its engine flies (in run order)."""
    ok = [i for i, (k, _) in enumerate(kept) if basilisk_flies(k)]
    if n <= 0 or not ok:
        return set()
    step = max(1, len(ok) // n)
    return set(ok[::step][:n])


# --- scores --------------------------------------------------------------------------------------


def _rate(flags: list) -> dict:
    return {"n": len(flags), "k": int(sum(flags)), "fraction": float(np.mean(flags)) if flags else None}


def _after(p: dict | None, a: dict) -> dict:
    """The answer the run ends with: after the plan, or its own when no plan was designed."""
    return p["after"] if p and p.get("designed") else a


def _members_reached(f: dict) -> bool:
    """Every true member's selection test reached on the flight (flown_true)."""
    return bool(f.get("members")) and all(m["reached"] for m in f["members"])


def _distance_scores(done: list) -> dict:
    """The designed plans' reach: predicted (every test at its level) and
    flown (the true effects: their distance from the nearest listed set
    against 10.8, and every true member's selection test against its
    level), and their cost."""
    half = [p["plans"]["half"] for p in done]
    needed = [p["needed"] for p in done if "needed" in p]
    flown = {
        k: [p["flown_true"][k] for p in done if p["flown_true"][k].get("members")]
        for k in ("designed", "half", "fixed")
    }
    paired = {k: [f for f in v if f.get("flown")] for k, v in flown.items()}
    fixed_t = [p["plans"]["fixed"]["duration_s"] for p in done]
    fixed_v = [p["plans"]["fixed"]["delta_v_mps"] for p in done]
    med = lambda xs: float(np.median(xs)) if xs else None  # noqa: E731
    reached_needed = [n for n in needed if n["reached"] and n.get("duration_s") is not None]
    return {
        "half_limits_reach_predicted": _rate([h["target_reached"] for h in half]),
        "half_duration_share_median": med([h["duration_s"] / t for h, t in zip(half, fixed_t)]),
        "half_delta_v_share_median": med([h["delta_v_mps"] / v for h, v in zip(half, fixed_v)]),
        "designed_reach_predicted": _rate([p["plans"]["designed"]["level_min"] >= 1.0 for p in done]),
        "fixed_reach_predicted": _rate([p["plans"]["fixed"]["level_min"] >= 1.0 for p in done]),
        "level_min_median": {
            "designed": med([p["plans"]["designed"]["level_min"] for p in done]),
            "designed_continuous": med([p["plans"]["designed"]["continuous_level_min"] for p in done]),
            "half": med([h["level_min"] for h in half]),
            "half_continuous": med([h["continuous_level_min"] for h in half]),
            "fixed": med([p["plans"]["fixed"]["level_min"] for p in done]),
        },
        "needed_reach_continuous": _rate([n["reached"] for n in needed]),
        "needed_level_max_median": med([n["level_max"] for n in needed]),
        "needed_limits": list(NEEDED_LIMITS),
        "needed_duration_s_median": med([n["duration_s"] for n in reached_needed]),
        "needed_delta_v_median": med([n["delta_v_mps"] for n in reached_needed]),
        "members_reached_flown": {k: _rate([_members_reached(f) for f in v]) for k, v in flown.items()},
        "listed_reach_flown": {k: _rate([f["delta2_min"] >= DELTA2_95 for f in v]) for k, v in paired.items()},
        "designed_duration_share_median": med(
            [p["plans"]["designed"]["duration_s"] / t for p, t in zip(done, fixed_t)]
        ),
        "designed_delta_v_share_median": med(
            [p["plans"]["designed"]["delta_v_mps"] / v for p, v in zip(done, fixed_v)]
        ),
        "flown_true_delta2_median": {k: med([f["delta2_min"] for f in v]) for k, v in paired.items()},
    }


def run_rows(keys: list, answers: list, planned: list) -> list:
    """One row per kept run: what it carried, its answer before and after, the plans' reach."""
    rows = []
    for k, a, p in zip(keys, answers, planned):
        after = _after(p, a)
        row = {
            "run": k["run"],
            "kind": k["kind"],
            "members": k["members"],
            "source": k.get("source"),
            "recorded_run": k.get("recorded_run"),
            "before": {x: a[x] for x in ("verdict", "named", "exact", "listed")},
            "after": {x: after[x] for x in ("verdict", "named", "exact", "settled", "listed")},
            "designed": bool(p and p.get("designed")),
        }
        if p and p.get("designed"):
            row["plans"] = {
                n: {
                    x: v.get(x)
                    for x in ("duration_s", "delta_v_mps", "delta2_min", "level_min", "continuous_level_min")
                }
                for n, v in p["plans"].items()
            }
            row["half_target_reached"] = p["plans"]["half"]["target_reached"]
            row["needed"] = p.get("needed")
            row["short_designed"] = p["plans"]["designed"]["short"]
            row["flown_true_delta2_min"] = {n: f.get("delta2_min") for n, f in p["flown_true"].items()}
            row["flown_true_members"] = {n: f.get("members") for n, f in p["flown_true"].items()}
            row["null_gap_detected"] = p["null"]["gap_detected"]
            if "fixed_after" in p:
                row["fixed_appended"] = {x: p["fixed_after"][x] for x in ("verdict", "named", "exact", "settled")}
        elif p:
            row["why_no_plan"] = p.get("why")
        else:  # not run (a campaign stopped early): scored nowhere
            row["not_run"] = True
        rows.append(row)
    return rows


def score_plans(keys: list, answers: list, planned: list, flown_elsewhere: list) -> dict:
    """Scores over the kept runs (``keys``, ``answers``, ``planned`` aligned;
    a planned None: not run yet), and the Basilisk subset's."""
    pairs = [(k, a, p) for k, a, p in zip(keys, answers, planned) if p is not None]
    done = [p for _, _, p in pairs if p.get("designed")]
    res = {
        "kept": len(pairs),
        "designed": len(done),
        "exact_before": _rate([a["exact"] for _, a, _ in pairs]),
        "settled_before": _rate([a["exact"] and a["verdict"] != "ambiguous" for _, a, _ in pairs]),
        "listed_before": _rate([a["listed"] for _, a, _ in pairs]),
        "exact_after": _rate([_after(p, a)["exact"] for _, a, p in pairs]),
        "settled_after": _rate([bool(_after(p, a).get("settled")) for _, a, p in pairs]),
        "listed_after": _rate([_after(p, a)["listed"] for _, a, p in pairs]),
        "false_alarms": _rate([p["null"]["gap_detected"] for p in done]),
        "fixed_appended_exact": _rate([p["fixed_after"]["exact"] for p in done if "fixed_after" in p]),
        "fixed_appended_settled": _rate([p["fixed_after"]["settled"] for p in done if "fixed_after" in p]),
        "by_kind": {},
        "distances": _distance_scores(done) if done else {},
        "not_designed": [{"run": p["run"], "why": p.get("why")} for _, _, p in pairs if not p.get("designed")],
    }
    for kind in sorted({k["kind"] for k, _, _ in pairs}):
        sel = [(a, p) for k, a, p in pairs if k["kind"] == kind]
        res["by_kind"][kind] = {
            "n": len(sel),
            "exact_after": _rate([_after(p, a)["exact"] for a, p in sel])["k"],
            "settled_after": _rate([bool(_after(p, a).get("settled")) for a, p in sel])["k"],
        }
    res["elsewhere"] = {}
    for engine in ("basilisk", "bench"):
        sel = [b[engine] for b in flown_elsewhere if b and engine in b]
        if sel:
            res["elsewhere"][engine] = {
                "exact": _rate([s["after"]["exact"] for s in sel]),
                "settled": _rate([s["after"]["settled"] for s in sel]),
                "listed": _rate([s["after"]["listed"] for s in sel]),
                "false_alarms": _rate([s["null"]["gap_detected"] for s in sel]),
            }
    return res


def _pct(r: dict) -> str:
    return "-" if not r or not r.get("n") else f"{r['k']} of {r['n']} ({100 * r['fraction']:.0f} %)"


def summary_lines(res: dict) -> list:
    """The campaign's scores against its targets, as printed."""
    s = res["scores"]
    d = s.get("distances") or {}
    lines = [
        f"docking logs diagnosed: {res['docking_runs']}; kept (ambiguous, or the true set listed but not the "
        f"answer): {s['kept']}; plans designed: {s['designed']}",
        f"exact set named: before the plan {_pct(s['exact_before'])}, after {_pct(s['exact_after'])}; settled "
        f"(exact and not ambiguous): before {_pct(s['settled_before'])}, after {_pct(s['settled_after'])} "
        f"(target >= {100 * TARGETS['exact_set']:.0f} %)",
        f"true set the answer or listed after the plan: {_pct(s['listed_after'])}",
        f"for comparison, the fixed characterisation (200 s) appended instead: exact {_pct(s['fixed_appended_exact'])}, "
        f"settled {_pct(s['fixed_appended_settled'])}",
        f"false alarms, the plan flown after an effect-free docking: {_pct(s['false_alarms'])} "
        f"(target <= {100 * TARGETS['false_alarms']:.0f} %)",
    ]
    if d:
        lv = d["level_min_median"]
        fl = d["members_reached_flown"]
        lines += [
            f"each test of the diagnosis at its level (the smallest share of a level, median): default design "
            f"{lv['designed']:.3g} (the optimiser's, before whole runs, {lv['designed_continuous']:.3g}), within half "
            f"the fixed plan {lv['half']:.3g} ({lv['half_continuous']:.3g}), fixed characterisation {lv['fixed']:.3g}",
            f"every level reached, predicted: default {_pct(d['designed_reach_predicted'])}, within half the fixed "
            f"plan {_pct(d['half_limits_reach_predicted'])}, fixed {_pct(d['fixed_reach_predicted'])}; within "
            f"{d['needed_limits'][0]:g} s and {d['needed_limits'][1]:g} m/s, by any plan of the blocks (the "
            f"continuous bound) {_pct(d['needed_reach_continuous'])}",
            f"the true effects flown, every true member's selection test at its level: designed "
            f"{_pct(fl['designed'])}, half {_pct(fl['half'])}, fixed {_pct(fl['fixed'])}",
        ]
    for engine, v in s.get("elsewhere", {}).items():
        lines.append(
            f"plan alone on the {engine} engine, diagnosed alone: exact {_pct(v['exact'])}, settled "
            f"{_pct(v['settled'])}, listed {_pct(v['listed'])}, false alarms {_pct(v['false_alarms'])}"
        )
    return lines


def run_campaign(
    drawn: list,
    out: str | None,
    prereg: dict,
    duration_s: float = 120.0,
    campaign=None,
    workers: int | None = None,
    progress: bool = True,
    basilisk_runs: int = 0,
) -> dict:
    """Size and diagnose the drawn docking runs, keep the ambiguous ones,
    design, fly and diagnose their plans, and score (module docstring)."""
    from bench.campaigns.gap.validate import new_campaign, sized_and_diagnosed
    from bench.gap import null as nullmod
    from bench.runner.runner import failures, results

    cal = nullmod.load(manoeuvres="docking")
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    shared = (duration_s, cal)
    keys, answers, _, info = sized_and_diagnosed(
        campaign, drawn, size_key, diagnose_docking, shared, out, prereg, "validate-gap plans: docking logs"
    )
    kept = [(k, a) for k, a in zip(keys, answers) if a["kept"] and k.get("detectable", True)]
    chosen = basilisk_subset(kept, basilisk_runs)
    kept = [(k, dict(a, basilisk=True) if i in chosen else a) for i, (k, a) in enumerate(kept)]
    recs = campaign.map("plan", plan_run, kept, seeds=[k["seed"] for k, _ in kept], shared=shared, label="plans")
    planned = results(recs)
    info["failed_runs"] += failures(recs)
    elsewhere = [p.get("elsewhere") for p in planned if p]
    return {
        "docking_runs": len(keys),
        "scores": score_plans([k for k, _ in kept], [a for _, a in kept], planned, elsewhere),
        "targets": TARGETS,
        "delta2_95": DELTA2_95,
        "rows": run_rows([k for k, _ in kept], [a for _, a in kept], planned),
        "elapsed_s": time.time() - t0,
        "duration_s": duration_s,
        "campaign": info,
        "keys": keys,
        "answers": answers,
        "planned": planned,
        "elsewhere": elsewhere,
    }
