"""Blind validation of the diagnoser (``proxops validate-gap``).

A seeded generator draws the campaign: null runs, in-library effects and
out-of-library effects, each with a random direction and a scale of 1x or
2x. The size is then scale x the effect's minimum detectable size for that
run's manoeuvres (bench/campaigns/gap/detectable.py: the size the diagnoser's screen
detects with probability 0.95 in that run, from the run's own signature);
an effect that no sensible size makes detectable in its run is simulated at
its largest sensible size and scored apart. Every run's key (simulation
seed, effect, parameters) is hashed and the hashes are written to
``<OUT>.prereg.json`` before any diagnosis runs. Each run (a Dask task,
bench/runner/runner.py) simulates the log, strips it to what a user's
log would hold (the streams, orbit and sensor settings; no key, no truth),
and diagnoses it. Only then are the keys re-hashed, checked against the
pre-registered hashes, and compared with the answers.

Scores: confusion matrix (truth -> answer), detection and top-1 attribution
by effect and size, false alarms on null runs, "unexplained" on
out-of-library runs, held-out shrink with the true effect fitted and with a
wrong one, and the coverage of the fitted parameters' 95 % intervals.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bench.runner.runner import new_campaign  # noqa: F401  (re-exported for the validations)

# What each campaign run flies: bench/sim/plans.py.
from bench.sim.plans import MANOEUVRES, then_scripts

FRACTIONS = {"null": 0.2, "in_library": 0.6, "out_of_library": 0.2}
SCALES = (1.0, 2.0)
USER_CONFIG_KEYS = (
    "orbit_radius_m",
    "dt_imu_s",
    "accel_sigma_mps2",
    "gyro_sigma_rps",
    "pose_period_s",
    "noise",
    "vehicle",
    "gate_chi2",
)
# Effects whose simulated parameters are the diagnoser's parameters (same
# definition and sign), so the fitted intervals can be scored.
SAME_PARAMETERS = (
    "accel_bias",
    "gyro_bias",
    "gyro_scale",
    "imu_misalignment",
    "camera_latency",
    "camera_lever_arm",
    "com_offset",
    "thrust_loss",
    "mass_depletion",
    "clock_drift",
)


def sized_and_diagnosed(
    campaign, drawn: list, size_fn, run_fn, shared, out: str | None, prereg: dict, label: str
) -> tuple:
    """The two stages of a blind validation through ``campaign``
    (bench/runner/runner.py): each drawn run's size, the key hashes
    written to ``<out>.prereg.json``, then each run's diagnosis. Returns
    (keys, answers) of the runs that finished both, the hashes of every
    drawn run (None where its sizing failed) and what the campaign did."""
    from bench.runner.runner import all_failed, failures, missing, results

    sized = campaign.map("size", size_fn, drawn, shared=shared, label="minimum detectable sizes")
    all_failed(sized)
    keys = results(sized)
    hashes = [None if k is None else key_hash(k) for k in keys]
    if out and not campaign.summarise_only:
        path = Path(str(out) + ".prereg.json")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({**prereg, "key_sha256": hashes}, indent=1) + "\n")
    diagnosed = campaign.map("diagnose", run_fn, keys, shared=shared, label=label)
    all_failed(diagnosed)
    answers = results(diagnosed)
    # Only now: the keys are re-hashed and compared with the answers.
    if [None if k is None else key_hash(k) for k in keys] != hashes:
        raise RuntimeError("drawn keys changed during the campaign")
    done = [i for i, (k, a) in enumerate(zip(keys, answers)) if k is not None and a is not None]
    if not done:
        raise ValueError("no finished runs to score" + (f" ({campaign.store.path})" if campaign.store.path else ""))
    info = {
        "runs_drawn": len(drawn),
        "runs_scored": len(done),
        "failed_runs": failures(sized) + failures(diagnosed),
        "missing_runs": sorted(set(missing(sized)) | set(i for i in missing(diagnosed) if keys[i] is not None)),
        "store": None if campaign.store.path is None else str(campaign.store.path),
        "where": campaign.where(),
    }
    return [keys[i] for i in done], [answers[i] for i in done], hashes, info


def key_hash(key: dict) -> str:
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


def draw_campaign(n_runs: int, seed: int, manoeuvres: str = "docking") -> list:
    """The drawn plan: [{"run", "seed", "category", "effect", "scale", "unit"}];
    ``unit`` is the effect's direction (a draw at size 1; sign, spread, phase);
    ``manoeuvres`` one of MANOEUVRES, recorded in every key."""
    from bench.sim.effects import EFFECTS

    if manoeuvres not in MANOEUVRES:
        raise ValueError(f"manoeuvres must be one of {MANOEUVRES}, not {manoeuvres!r}")
    rng = np.random.default_rng(seed)
    # The campaign's logs have synthetic poses: effects of the camera that
    # exist only with rendered images are not drawn.
    inlib = sorted(n for n, s in EFFECTS.items() if s.in_library and not s.needs_images)
    outlib = sorted(n for n, s in EFFECTS.items() if not s.in_library and not s.needs_images)
    n_null = int(round(FRACTIONS["null"] * n_runs))
    n_out = int(round(FRACTIONS["out_of_library"] * n_runs))
    n_in = n_runs - n_null - n_out
    plan = [("null", None, 0.0)] * n_null
    plan += [("in_library", inlib[i % len(inlib)], SCALES[(i // len(inlib)) % 2]) for i in range(n_in)]
    plan += [("out_of_library", outlib[i % len(outlib)], SCALES[(i // len(outlib)) % 2]) for i in range(n_out)]
    order = rng.permutation(len(plan))
    keys = []
    for run, j in enumerate(order):
        cat, eff, scale = plan[j]
        unit = None if eff is None else [float(x) for x in EFFECTS[eff].draw_fn(rng, 1.0)]
        keys.append(
            {
                "run": run,
                "seed": int(rng.integers(0, 2**31)),
                "category": cat,
                "effect": eff,
                "scale": scale,
                "unit": unit,
                "effects": {},
            }
        )
        if manoeuvres != "docking":  # keys of docking-only campaigns hash as they always did
            keys[-1]["manoeuvres"] = manoeuvres
    return keys


def _size_one(key, run_ctx):
    """The drawn run's minimum detectable size, and its effect at scale x that."""
    duration_s, calibration = run_ctx
    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS, max_size_for
    from bench.sim.log_description import resolve

    key = dict(key)
    if key["effect"] is None:
        return key
    # The largest size that is physical on the bench inspector (its lever
    # arms and its valves' mass flow).
    spec = replace(EFFECTS[key["effect"]], max_size=max_size_for(key["effect"], resolve(None)))
    md = min_detectable_size(
        key["seed"],
        key["effect"],
        key["unit"],
        duration_s,
        calibration,
        then_scripts=then_scripts(key),
        max_size=spec.max_size,
    )
    key["min_detectable"] = md["size"]
    key["detectable"] = md["detectable"]
    key["lambda_at_min_detectable"] = md.get("lambda_at_size")
    key["lambda_required"] = md.get("lambda_required")
    # Beyond the effect's largest sensible size in this run: simulated at that
    # size and scored apart (the run's manoeuvres cannot show it).
    size = key["scale"] * md["size"] if md["detectable"] else spec.max_size
    key["effects"] = {key["effect"]: [float(x) for x in spec.at(key["unit"], min(size, spec.max_size))]}
    key["size"] = float(min(size, spec.max_size))
    return key


def simulate(key: dict, duration_s: float):
    from bench.campaigns.gap.simlogs import docking_log, reality_available

    if reality_available():
        from bench.sim.reality import simulate_log_with_key

        log, _ = simulate_log_with_key(
            key["seed"], key["effects"], duration_s=duration_s, with_truth=False, then_scripts=then_scripts(key)
        )
        return log
    if then_scripts(key) is not None:
        raise ValueError("a characterisation needs bench.sim.reality")
    # Fallback without bench.sim.reality: the sensor-profile effects only.
    from bench.sim.sensors import NoiseProfile

    prof = NoiseProfile.paper()
    for name, p in key["effects"].items():
        field = {"accel_bias": "accel_bias_mps2", "gyro_bias": "gyro_bias_rps", "gyro_scale": "gyro_scale"}.get(name)
        if field is None:
            raise ValueError(f"effect {name!r} needs bench.sim.reality")
        prof = prof.with_(**{field: tuple(p)})
    return docking_log(key["seed"], prof, t_max_s=duration_s)


def blind(log):
    """What a user's log would hold: the streams and the sensor settings."""
    log.streams.pop("truth", None)
    log.config = {k: v for k, v in (log.config or {}).items() if k in USER_CONFIG_KEYS}
    return log


def forced_fit(internal: dict, name: str) -> dict:
    """Fit one named candidate (whatever the ranking) and its held-out shrink."""
    from bench.gap.attribute import confirm, screen

    f = screen(internal["ctx"], names=[name])[0]
    if not np.isfinite(f.screen_bic):
        return {"theta": f.theta.tolist(), "sigma": f.sigma.tolist(), "shrink": float("nan"), "measurable": False}
    confirm(internal["ctx"], f)
    sh = internal["held_shrink"](f.after_nav, f.after_dyn)
    return {
        "theta": f.theta.tolist(),
        "sigma": f.sigma.tolist(),
        "shrink": sh["fraction"],
        "measurable": sh["measurable"],
    }


def _run_one(key, run_ctx):
    duration_s, calibration = run_ctx
    from bench.gap.candidates import CANDIDATES
    from bench.gap.diagnose import diagnose, public

    t0 = time.time()
    log = blind(simulate(key, duration_s))
    t_sim = time.time() - t0
    res = diagnose(log, calibration=calibration)
    pub = public(res)
    out = {
        "run": key["run"],
        "gap_detected": pub["gap_detected"],
        "verdict": pub["verdict"],
        "top1": pub["attribution"][0]["effect"] if pub["attribution"] else None,
        "ranking": [r["effect"] for r in pub["attribution"]],
        "shrink_best": pub["shrink_heldout"]["fraction"] if pub["shrink_heldout"] else None,
        "map_max_abs_z": pub["statistics"]["map_max_abs_z"],
        "screen_logp_max": pub["statistics"]["screen_logp_max"],
        "screen_top": pub["screening"][0]["effect"] if pub["screening"] else None,
        "t_sim_s": t_sim,
        "t_diagnose_s": pub["elapsed_s"],
    }
    # Scoring fits (after the answer is frozen): the true effect and a wrong one.
    it = res["_internal"]
    eff = key["effect"]
    if key["category"] == "in_library":
        if eff in CANDIDATES:
            out["true_fit"] = forced_fit(it, eff)
        wrong = [n for n in CANDIDATES if n != eff]
        w = wrong[np.random.default_rng(key["seed"]).integers(len(wrong))]
        out["wrong_fit"] = {"effect": w, **forced_fit(it, w)}
    if eff is not None:
        # Could this run's data tell its effect from each candidate at all?
        from bench.campaigns.gap.separability import separability

        sep = separability(
            key["seed"],
            eff,
            key["effects"],
            duration_s,
            key["category"] == "in_library",
            then_scripts=then_scripts(key),
        )
        out["separability"] = {k: sep.get(k) for k in ("lambda", "closest", "delta2_min", "separable")}
    return out


def _label_truth(k: dict) -> str:
    if k["category"] == "null":
        return "null"
    lab = k["effect"] if k["category"] == "in_library" else f"out:{k['effect']}"
    return lab if k.get("detectable", True) else f"{lab} (beyond limit)"


def _label_answer(a: dict) -> str:
    if not a["gap_detected"]:
        return "no_gap"
    return a["verdict"] if a["verdict"] in ("unexplained", "partly_explained") else a["top1"]


def _top1(k: dict, a: dict) -> bool:
    return bool(a["gap_detected"] and a["verdict"] in ("explained", "ambiguous") and a["top1"] == k["effect"])


def score(keys: list, answers: list) -> dict:
    """The campaign's scores against its targets, from the frozen answers."""
    by = {a["run"]: a for a in answers}
    confusion = {}
    for k in keys:
        t, a = _label_truth(k), _label_answer(by[k["run"]])
        confusion.setdefault(t, {}).setdefault(a, 0)
        confusion[t][a] += 1
    null = [by[k["run"]] for k in keys if k["category"] == "null"]
    # Runs whose effect no size up to its largest sensible one makes detectable
    # in that run's manoeuvres are scored apart: there is no 1x or 2x to test.
    beyond = [(k, by[k["run"]]) for k in keys if k["effect"] is not None and not k.get("detectable", True)]
    outl = [by[k["run"]] for k in keys if k["category"] == "out_of_library" and k.get("detectable", True)]
    inl = [(k, by[k["run"]]) for k in keys if k["category"] == "in_library" and k.get("detectable", True)]
    res = {
        "runs": len(keys),
        "confusion": confusion,
        "false_alarm_rate": float(np.mean([a["gap_detected"] for a in null])) if null else None,
        "n_null": len(null),
        "beyond_detection_limit": _beyond_limit(beyond),
    }
    if outl:
        res["out_of_library"] = _out_of_library(outl)
    res["in_library_by_scale"] = _by_scale(inl)
    res["in_library_by_scale_separable"] = _by_scale_separable(inl)
    per_effect = {}
    for k, a in inl:
        e = per_effect.setdefault(k["effect"], {})
        c = e.setdefault(f"{k['scale']:g}x", {"n": 0, "detected": 0, "top1": 0})
        c["n"] += 1
        c["detected"] += int(a["gap_detected"])
        c["top1"] += int(_top1(k, a))
    res["in_library_by_effect"] = per_effect
    # Shrink is scored where the held-out deficit stands out of its null spread.
    true_sh = [a["true_fit"]["shrink"] for _, a in inl if "true_fit" in a and a["true_fit"].get("measurable")]
    wrong_sh = [a["wrong_fit"]["shrink"] for _, a in inl if "wrong_fit" in a and a["wrong_fit"].get("measurable")]
    res["shrink_heldout"] = {
        "true_effect_median": float(np.median(true_sh)) if true_sh else None,
        "n_true": len(true_sh),
        "wrong_effect_median": float(np.median(wrong_sh)) if wrong_sh else None,
        "n_wrong": len(wrong_sh),
        "n_in_library": len(inl),
    }
    res["interval_coverage_95"] = _coverage(inl)
    res["timing_s"] = {
        "simulate_median": float(np.median([a["t_sim_s"] for a in answers])),
        "diagnose_median": float(np.median([a["t_diagnose_s"] for a in answers])),
        "diagnose_max": float(np.max([a["t_diagnose_s"] for a in answers])),
    }
    return res


def _beyond_limit(beyond: list) -> dict:
    by_eff = {}
    for k, a in beyond:
        e = by_eff.setdefault(k["effect"], {"n": 0, "detected": 0, "answers": {}})
        e["n"] += 1
        e["detected"] += int(a["gap_detected"])
        lab = _label_answer(a)
        e["answers"][lab] = e["answers"].get(lab, 0) + 1
    return {"n": len(beyond), "by_effect": by_eff}


def _out_of_library(outl: list) -> dict:
    return {
        "n": len(outl),
        "unexplained_rate": float(np.mean([a["gap_detected"] and a["verdict"] == "unexplained" for a in outl])),
        "not_detected_rate": float(np.mean([not a["gap_detected"] for a in outl])),
        "confident_misattribution_rate": float(
            np.mean([a["gap_detected"] and a["verdict"] == "explained" for a in outl])
        ),
        "partly_explained_rate": float(
            np.mean([a["gap_detected"] and a["verdict"] == "partly_explained" for a in outl])
        ),
    }


def _by_scale(inl: list) -> dict:
    by_scale = {}
    for s in SCALES:
        sel = [(k, a) for k, a in inl if k["scale"] == s]
        if sel:
            by_scale[f"{s:g}x"] = {
                "n": len(sel),
                "detection": float(np.mean([a["gap_detected"] for _, a in sel])),
                "top1": float(np.mean([_top1(k, a) for k, a in sel])),
            }
    return by_scale


def _by_scale_separable(inl: list) -> dict:
    """The top-1 rate over the runs whose data can tell the true effect from
    every other candidate (bench/campaigns/gap/separability.py: delta2 >= 10.8, where a
    perfect two-way decision is right 95 % of the time); the runs it leaves
    out are ones no diagnoser can attribute reliably."""
    sep_scale = {}
    for s in SCALES:
        sel = [(k, a) for k, a in inl if k["scale"] == s and a.get("separability", {}).get("separable")]
        nsel = [(k, a) for k, a in inl if k["scale"] == s and a.get("separability", {}).get("separable") is False]
        if sel or nsel:
            sep_scale[f"{s:g}x"] = {
                "n_separable": len(sel),
                "n_not_separable": len(nsel),
                "top1_separable": float(np.mean([_top1(k, a) for k, a in sel])) if sel else None,
                "not_separable_by_effect": {
                    e: sum(1 for k, _ in nsel if k["effect"] == e) for e in sorted({k["effect"] for k, _ in nsel})
                },
                "closest_when_not_separable": {
                    c: sum(1 for _, a in nsel if a["separability"]["closest"] == c)
                    for c in sorted({a["separability"]["closest"] for _, a in nsel})
                },
            }
    return sep_scale


def _coverage(inl: list) -> dict:
    """How often the 95 % intervals of the true effect's fit hold the drawn
    parameters (the IMU's own errors are drawn and fitted in its own axes)."""
    inside, total = 0, 0
    for k, a in inl:
        if k["effect"] in SAME_PARAMETERS and "true_fit" in a:
            truth = np.asarray(k["effects"][k["effect"]], float)
            th, sg = np.asarray(a["true_fit"]["theta"]), np.asarray(a["true_fit"]["sigma"])
            if truth.size == th.size:
                ok = np.abs(th - truth) <= 1.96 * sg
                inside += int(ok.sum())
                total += ok.size
    return {"fraction": inside / total if total else None, "n_parameters": total, "effects": list(SAME_PARAMETERS)}


def run_campaign(
    n_runs: int,
    seed: int,
    out: str | None,
    workers: int | None = None,
    duration_s: float = 120.0,
    progress: bool = True,
    manoeuvres: str = "docking",
    campaign=None,
) -> dict:
    from bench.gap import null as nullmod

    cal = nullmod.load(manoeuvres=manoeuvres)
    if not cal:
        raise FileNotFoundError(
            f"no null calibration for {manoeuvres!r} logs (python -m bench.commands.null_calibration --manoeuvres {manoeuvres})"
        )
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    keys, answers, hashes, info = sized_and_diagnosed(
        campaign,
        draw_campaign(n_runs, seed, manoeuvres),
        _size_one,
        _run_one,
        (duration_s, cal),
        out,
        {"seed": seed, "runs": n_runs, "manoeuvres": manoeuvres},
        "validate-gap",
    )
    res = score(keys, answers)
    res.update(
        {
            "seed": seed,
            "duration_s": duration_s,
            "manoeuvres": manoeuvres,
            "workers": workers,
            "elapsed_s": time.time() - t0,
            "campaign": info,
            "calibration": {
                "runs": cal.get("runs"),
                "false_alarm_rate": cal.get("false_alarm_rate"),
                "thresholds": cal.get("thresholds"),
            },
            "keys_match_preregistration": True,
            "key_sha256": hashes,
            "keys": keys,
            "answers": answers,
            "command": f"proxops validate-gap --runs {n_runs} --seed {seed} --duration {duration_s:g}"
            + (f" --manoeuvres {manoeuvres}" if manoeuvres != "docking" else ""),
        }
    )
    return res


def runs_table(res: dict) -> str:
    """One CSV line per run: the drawn key (after scoring) beside the answer."""
    by = {a["run"]: a for a in res["answers"]}
    lines = [
        "run,seed,category,effect,scale,min_detectable,size,detectable,gap_detected,verdict,top1,"
        "map_max_abs_z,screen_logp_max,true_fit_shrink,wrong_fit_effect,wrong_fit_shrink,"
        "lambda_at_min_detectable,signature_lambda,closest_candidate,delta2_closest"
    ]
    for k in res["keys"]:
        a = by[k["run"]]
        tf, wf = a.get("true_fit", {}), a.get("wrong_fit", {})
        vals = [
            k["run"],
            k["seed"],
            k["category"],
            k["effect"] or "",
            k["scale"],
            k.get("min_detectable", ""),
            k.get("size", ""),
            k.get("detectable", ""),
            a["gap_detected"],
            a["verdict"],
            a["top1"] or "",
            f"{a['map_max_abs_z']:.4g}",
            f"{a['screen_logp_max']:.4g}",
            tf.get("shrink", ""),
            wf.get("effect", ""),
            wf.get("shrink", ""),
            k.get("lambda_at_min_detectable", ""),
            a.get("separability", {}).get("lambda", ""),
            a.get("separability", {}).get("closest", "") or "",
            a.get("separability", {}).get("delta2_min", ""),
        ]
        lines.append(",".join(str(v) for v in vals))
    return "\n".join(lines) + "\n"
