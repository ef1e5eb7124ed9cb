"""Blind validation with several effects at once:
``proxops validate-gap --mixtures``.

Each drawn run carries two or three simultaneous effects: in-library pairs,
in-library triples, or one in-library effect with one out of the library;
every effect at 1x or 2x its own minimum detectable size in that run
(bench/campaigns/gap/detectable.py, the effect alone), in a random direction. Keys are
hashed before any diagnosis, as in bench/campaigns/gap/validate.py.

Scores:
  exact set        the named effects are exactly the run's in-library ones
                   (and, reported beside it, the run's set is the answer or
                   one of the sets an ambiguous answer names with it)
  named are real   every named effect is one of the run's
  remainder        (in + out runs) the out-of-library part is left as a
                   remainder: the verdict is not a plain "explained" with the
                   in-library effect alone fitting everything
  joint shrink     the held-out shrink of the true in-library set refitted
                   jointly (bench/gap/select.py), after the answer is frozen
A run with a member that no sensible size makes detectable in it is scored
apart.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bench.campaigns.gap.validate import SCALES, blind, new_campaign, sized_and_diagnosed
from bench.sim.plans import then_scripts

KINDS = ("pair", "triple", "in+out")


def draw_mixtures(n_runs: int, seed: int, manoeuvres: str = "docking") -> list:
    from bench.sim.effects import EFFECTS

    rng = np.random.default_rng(seed)
    inlib = sorted(
        n for n, s in EFFECTS.items() if s.in_library and not s.needs_images and s.detectable and not s.needs_truth
    )
    outlib = sorted(n for n, s in EFFECTS.items() if not s.in_library and not s.needs_images)
    keys = []
    for run in range(n_runs):
        kind = KINDS[run % len(KINDS)]
        scale = SCALES[(run // len(KINDS)) % 2]
        if kind == "pair":
            effs = list(rng.choice(inlib, 2, replace=False))
        elif kind == "triple":
            effs = list(rng.choice(inlib, 3, replace=False))
        else:
            effs = [str(rng.choice(inlib)), str(rng.choice(outlib))]
        keys.append(
            {
                "run": run,
                "seed": int(rng.integers(0, 2**31)),
                "category": "mixture",
                "kind": kind,
                "scale": scale,
                "members": [str(e) for e in effs],
                "units": {str(e): [float(x) for x in EFFECTS[e].draw_fn(rng, 1.0)] for e in effs},
                "effects": {},
            }
        )
    if manoeuvres != "docking":  # (docking keys hash as they did before manoeuvres were a choice)
        keys = [dict(k, manoeuvres=manoeuvres) for k in keys]
    order = rng.permutation(n_runs)
    keys = [dict(keys[i], run=r) for r, i in enumerate(order)]
    return keys


def _size_one(key, run_ctx):
    duration_s, calibration = run_ctx
    from dataclasses import replace

    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS, max_size_for
    from bench.sim.log_description import resolve

    key = dict(key)
    key["min_detectable"], key["effects"] = {}, {}
    for e in key["members"]:
        spec = replace(EFFECTS[e], max_size=max_size_for(e, resolve(None)))
        md = min_detectable_size(
            key["seed"],
            e,
            key["units"][e],
            duration_s,
            calibration,
            then_scripts=then_scripts(key),
            max_size=spec.max_size,
        )
        size = key["scale"] * md["size"] if md["detectable"] else spec.max_size
        size = float(min(size, spec.max_size))
        key["min_detectable"][e] = md["size"] if md["detectable"] else None
        key["effects"][e] = [float(x) for x in spec.at(key["units"][e], size)]
    # A member that no sensible size makes detectable in this run: the run is
    # scored apart (there is no 1x or 2x of it to test).
    key["detectable"] = all(v is not None for v in key["min_detectable"].values())
    return key


def _run_one(key, run_ctx):
    duration_s, calibration = run_ctx
    from bench.gap import select
    from bench.gap.diagnose import diagnose, public
    from bench.sim.effects import EFFECTS
    from bench.sim.reality import simulate_log_with_key

    log, _ = simulate_log_with_key(
        key["seed"], key["effects"], duration_s=duration_s, with_truth=False, then_scripts=then_scripts(key)
    )
    res = diagnose(blind(log), calibration=calibration)
    pub = public(res)
    named = [m["effect"] for m in pub["effects"]] if pub["gap_detected"] else []
    truth_in = sorted(e for e in key["members"] if EFFECTS[e].in_library)
    # An ambiguous or partial answer lists the sets the data cannot tell
    # from its own (bench/gap/answers.py listed_sets).
    from bench.gap.answers import listed_sets

    alternatives = [sorted(s) for s in listed_sets(pub)] if pub["gap_detected"] else []
    out = {
        "run": key["run"],
        "gap_detected": pub["gap_detected"],
        "verdict": pub["verdict"],
        "named": named,
        "alternatives": alternatives,
        "t_diagnose_s": pub["elapsed_s"],
    }
    it = res["_internal"]
    ctx = it["ctx"]
    fits = {f.name: f for f in it["fits"]}
    try:
        sf = select.confirm_set(ctx, truth_in, [fits[n] for n in truth_in])
        sh = it["held_shrink"](sf.after_nav, sf.after_dyn)
        out["true_set_shrink"], out["true_set_measurable"] = sh["fraction"], sh["measurable"]
    except Exception as exc:  # scored as not measured, with the reason
        out["true_set_shrink"], out["true_set_measurable"], out["true_set_error"] = None, False, str(exc)
    # After the answer is frozen: can this run's data tell its set from the
    # sets one step away (bench/campaigns/gap/separability.py)?
    from bench.campaigns.gap.separability import set_separability

    sep = set_separability(key["seed"], key["effects"], truth_in, duration_s, then_scripts=then_scripts(key))
    out["separability"] = {
        k: sep.get(k)
        for k in ("lambda", "closest", "delta2_min", "separable", "beyond_library_delta2", "beyond_library_separable")
    }
    return out


def _separable(key: dict, answer: dict) -> bool:
    """The run's data tell its in-library set from every set one step away
    and, in an in + out run, its out-of-library part from the whole library
    (answers scored before separability was measured count as separable)."""
    sep = answer.get("separability") or {}
    return bool(sep.get("separable", True)) and (
        key["kind"] != "in+out" or bool(sep.get("beyond_library_separable", True))
    )


def _scores(sel: list, kind: str) -> dict:
    """Exact set, every named effect real and (in + out runs) the
    out-of-library part left as a remainder, over (key, answer) pairs."""
    from bench.sim.effects import EFFECTS

    exact, among, real, remainder, n_listed = [], [], [], [], []
    for k, a in sel:
        n_listed.append(len(a.get("alternatives", [])))
        truth_in = {e for e in k["members"] if EFFECTS[e].in_library}
        named = set(a["named"])
        exact.append(named == truth_in and a["verdict"] != "unexplained")
        among.append(exact[-1] or any(set(alt) == truth_in for alt in a.get("alternatives", [])))
        real.append(named <= set(k["members"]))
        if k["kind"] == "in+out":
            # the out-of-library part left as a remainder, with or without
            # the in-library part named beside it
            remainder.append(a["gap_detected"] and a["verdict"] in ("unexplained", "partly_explained"))
    if not sel:
        return {"n": 0}
    return {
        "n": len(sel),
        "exact_set": float(np.mean(exact)),
        "exact_set_among_named": float(np.mean(among)),
        "named_are_real": float(np.mean(real)),
        # how many sets an answer lists beside its own: the price of the
        # "among the listed sets" score
        "listed_sets_median": float(np.median(n_listed)),
        "listed_sets_max": int(max(n_listed)),
        **(
            {"out_of_library_left_unexplained": float(np.mean(remainder)), "n_in_out": len(remainder)}
            if remainder
            else {}
        ),
    }


def score_mixtures(keys: list, answers: list) -> dict:
    by = {a["run"]: a for a in answers}
    apart = [k for k in keys if not k.get("detectable", True)]
    keys = [k for k in keys if k.get("detectable", True)]
    res = {"runs": len(keys) + len(apart), "beyond_detection_limit": len(apart), "by_kind_scale": {}}
    for kind in KINDS:
        for s in SCALES:
            sel = [(k, by[k["run"]]) for k in keys if k["kind"] == kind and k["scale"] == s]
            if not sel:
                continue
            row = _scores(sel, kind)
            row.update(
                {f"{m}_separable": v for m, v in _scores([(k, a) for k, a in sel if _separable(k, a)], kind).items()}
            )
            res["by_kind_scale"][f"{kind} {s:g}x"] = row
    for s in SCALES:
        res[f"at_{s:g}x"] = _scores([(k, by[k["run"]]) for k in keys if k["scale"] == s], "all")
        res[f"at_{s:g}x"]["separable"] = _scores(
            [(k, by[k["run"]]) for k in keys if k["scale"] == s and _separable(k, by[k["run"]])], "all"
        )
        res[f"at_{s:g}x"]["not_separable"] = _scores(
            [(k, by[k["run"]]) for k in keys if k["scale"] == s and not _separable(k, by[k["run"]])], "all"
        )
    # The joint shrink of the true set measures how much of the gap the set
    # explains; in an in + out run the out-of-library part is not the set's
    # to explain, so those runs are reported apart.
    scored = {k["run"]: k for k in keys}
    res["true_set_shrink"] = {}
    for label, kinds in (("in-library sets", ("pair", "triple")), ("in + out", ("in+out",))):
        for s in SCALES:
            sh = [
                a["true_set_shrink"]
                for a in answers
                if a.get("true_set_measurable")
                and a["run"] in scored
                and scored[a["run"]]["kind"] in kinds
                and scored[a["run"]]["scale"] == s
            ]
            res["true_set_shrink"][f"{label} {s:g}x"] = {"median": float(np.median(sh)) if sh else None, "n": len(sh)}
    sh = [a["true_set_shrink"] for a in answers if a.get("true_set_measurable") and a["run"] in scored]
    res["true_set_shrink_median"] = float(np.median(sh)) if sh else None
    res["n_shrink_measurable"] = len(sh)
    res["diagnose_s_median"] = float(np.median([a["t_diagnose_s"] for a in answers]))
    return res


def _pct(v: dict, key: str) -> str:
    return f"{100 * v[key]:.0f} %" if v.get("n") and key in v else "-"


def summary_lines(res: dict) -> list:
    """The campaign's scores as a GNC engineer reads them: per kind and
    size, then at each size over all kinds, all runs and the runs whose data
    separate their set (bench/campaigns/gap/separability.py set_separability)."""
    lines = []
    for k, v in res["by_kind_scale"].items():
        extra = (
            f", out-of-library part left as a remainder {_pct(v, 'out_of_library_left_unexplained')}"
            if "out_of_library_left_unexplained" in v
            else ""
        )
        lines.append(
            f"{k}: exact set {_pct(v, 'exact_set')}, named are real {_pct(v, 'named_are_real')}{extra} "
            f"(n = {v['n']}; separable: exact {_pct(v, 'exact_set_separable')} of "
            f"{v.get('n_separable', 0)})"
        )
    for s in SCALES:
        a = res.get(f"at_{s:g}x")
        if not a or not a.get("n"):
            continue
        sep = a["separable"]
        lines.append(
            f"at {s:g}x, all kinds: exact set {_pct(a, 'exact_set')} (among the sets the "
            f"answer lists: {_pct(a, 'exact_set_among_named')}), named are real "
            f"{_pct(a, 'named_are_real')}, remainder {_pct(a, 'out_of_library_left_unexplained')} "
            f"(n = {a['n']}); where the data separate the set: {_pct(sep, 'exact_set')}, "
            f"{_pct(sep, 'named_are_real')}, {_pct(sep, 'out_of_library_left_unexplained')} "
            f"(n = {sep.get('n', 0)})"
        )
        ns = a.get("not_separable") or {}
        if ns.get("n"):
            lines.append(
                f"at {s:g}x, where the data do not separate the set: the true set among the listed sets "
                f"{_pct(ns, 'exact_set_among_named')} (n = {ns['n']}; listed sets per answer: median "
                f"{ns['listed_sets_median']:g}, largest {ns['listed_sets_max']})"
            )
    for k, v in res.get("true_set_shrink", {}).items():
        med = "-" if v["median"] is None else f"{v['median']:.2f}"
        lines.append(f"held-out shrink of the true set refitted jointly, {k}: median {med} (n = {v['n']})")
    return lines


def run_campaign(
    n_runs: int,
    seed: int,
    out: str | None,
    workers: int | None = None,
    duration_s: float = 120.0,
    progress: bool = True,
    campaign=None,
    manoeuvres: str = "docking",
) -> dict:
    from bench.gap import null as nullmod

    cal = nullmod.load(manoeuvres=manoeuvres)
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    keys, answers, hashes, info = sized_and_diagnosed(
        campaign,
        draw_mixtures(n_runs, seed, manoeuvres),
        _size_one,
        _run_one,
        (duration_s, cal),
        out,
        {"seed": seed, "runs": n_runs, "mixtures": True, "manoeuvres": manoeuvres},
        "validate-gap mixtures",
    )
    res = score_mixtures(keys, answers)
    res.update(
        {
            "seed": seed,
            "duration_s": duration_s,
            "workers": workers,
            "elapsed_s": time.time() - t0,
            "campaign": info,
            "keys_match_preregistration": True,
            "keys": keys,
            "answers": answers,
            "manoeuvres": manoeuvres,
            "command": f"proxops validate-gap --mixtures --runs {n_runs} --seed {seed}"
            + (f" --manoeuvres {manoeuvres}" if manoeuvres != "docking" else ""),
        }
    )
    return res


# Pairs of effects on one docking-then-characterisation log, each effect at a
# size the diagnosis names when it is alone in the log (python -m
# bench.campaigns.gap.validate_mixtures pairs; docs/results/2026-11-26-several-effects.md).
_RNG_TILT = np.random.default_rng(5)
PAIRS = {
    "thrust loss on one valve + gyro bias": {
        "thrust_loss": [0, 0, 0, 0.05, 0, 0, 0, 0],
        "gyro_bias": [2e-3, -1.5e-3, 1e-3],
    },
    "centre-of-mass offset + camera latency": {"com_offset": [0.01, -0.008, 0.006], "camera_latency": [1.0]},
    "thruster misalignment + accelerometer bias": {
        "thruster_misalignment": (0.03 * _RNG_TILT.normal(size=24)).tolist(),
        "accel_bias": [8e-4, -6e-4, 4e-4],
    },
    "thrust loss on one valve + flexible panel": {
        "thrust_loss": [0, 0, 0, 0.05, 0, 0, 0, 0],
        "flex_mode": [0.3, 0.012],
    },
}


def _pair_answer(effects: dict, seed: int) -> dict:
    from bench.gap import null as nullmod
    from bench.gap.diagnose import diagnose, public
    from bench.sim.reality import simulate_log_with_key

    key = {"manoeuvres": "docking+characterisation"}
    log, _ = simulate_log_with_key(seed, effects, duration_s=120.0, with_truth=False, then_scripts=then_scripts(key))
    pub = public(diagnose(blind(log), calibration=nullmod.load(manoeuvres=key["manoeuvres"])))
    es = pub.get("effect_set") or {}
    shares = {m["effect"]: m.get("adds_shrink") for m in es.get("members", [])}
    return {
        "verdict": pub["verdict"],
        "named": [m["effect"] for m in pub["effects"]],
        "shares": shares,
        "shrink": (es.get("shrink_heldout") or {}).get("fraction"),
    }


def pairs(seed: int = 11) -> list:
    """Each pair of PAIRS alone and together: [{"pair", "alone", "together"}]."""
    out = []
    for name, eff in PAIRS.items():
        alone = {e: _pair_answer({e: v}, seed) for e, v in eff.items()}
        out.append({"pair": name, "effects": eff, "alone": alone, "together": _pair_answer(eff, seed)})
        print(
            f"{name}: alone {[a['verdict'] + ' ' + '+'.join(a['named']) for a in alone.values()]}; together "
            f"{out[-1]['together']['verdict']} {'+'.join(out[-1]['together']['named'])}",
            file=sys.stderr,
        )
    return out


def rediagnose(path: str, member: str | None = None) -> dict:
    """The recorded campaign's runs (its stored ``.full.json.gz``; those that
    carry ``member``, or every scored run), flown again at their recorded
    sizes and diagnosed by today's library, run for run. A member that has
    joined the library since counts as in-library: an in + out run whose
    out-of-library member it was is now a pair, and its exact set is both.
    Returns {"rows": [{"run", "scale", "members", "kind", "before", "after"}],
    "scores_before", "scores_after"}: the same runs scored as today's
    library counts them, with the recorded answers and with today's."""
    import gzip
    import json

    from bench.gap import null as nullmod
    from bench.sim.effects import EFFECTS

    rec = json.load(gzip.open(path))
    by = {a["run"]: a for a in rec["answers"]}
    cal = nullmod.load(manoeuvres=rec.get("manoeuvres", "docking"))
    rows, keys, before, after = [], [], [], []
    for key in rec["keys"]:
        if (member and member not in key["members"]) or not key.get("detectable", True) or key["run"] not in by:
            continue
        n_in = sum(EFFECTS[e].in_library for e in key["members"])
        kind = key["kind"] if n_in < len(key["members"]) else ("pair", "triple")[n_in - 2]
        keys.append(dict(key, kind=kind))
        before.append(by[key["run"]])
        after.append(_run_one(key, (rec["duration_s"], cal)))
        was, now = before[-1], after[-1]
        rows.append(
            {
                "run": key["run"],
                "scale": key["scale"],
                "members": key["members"],
                "kind": kind,
                "before": {k: was[k] for k in ("verdict", "named")},
                "after": {k: now[k] for k in ("verdict", "named", "true_set_shrink")},
            }
        )
        print(
            f"run {key['run']} {kind} {key['scale']:g}x {'+'.join(key['members'])}: before {was['verdict']} "
            f"{'+'.join(was['named'])}; now {now['verdict']} {'+'.join(now['named'])}",
            file=sys.stderr,
        )
    return {
        "record": str(path),
        "member": member,
        "rows": rows,
        "scores_before": score_mixtures(keys, before),
        "scores_after": score_mixtures(keys, after),
        "keys": keys,
        "answers": after,
    }


def main(argv=None):
    import argparse
    import json

    ap = argparse.ArgumentParser(
        description="The four pairs of effects on one log, alone and together; or a "
        "recorded campaign's runs that carry one effect, diagnosed again"
    )
    ap.add_argument("what", choices=("pairs", "rediagnose"))
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--record", help="rediagnose: the campaign's .full.json.gz")
    ap.add_argument("--member", help="rediagnose: only the runs that carry this effect (default: every scored run)")
    a = ap.parse_args(argv)
    if a.what == "rediagnose":
        if not a.record:
            ap.error("rediagnose needs --record")
        print(json.dumps(rediagnose(a.record, a.member), indent=1))
        return
    print(json.dumps(pairs(a.seed), indent=1))


if __name__ == "__main__":
    main()
