"""Blind validation on logs from Basilisk: ``proxops validate-gap --engine
basilisk``.

The campaign of ``--vehicle 12kg`` (bench/gap/validate_vehicle.py: the 12 kg
inspector's characterisation, time stamps as real logs have them, one run in
ten without a valves stream, null, in-library and out-of-library runs at 1x
and 2x each run's own minimum detectable size, keys hashed before any
diagnosis), with every scored log flown by Basilisk (bench/basilisk_sim.py)
instead of the bench's plant. The out-of-library effects are Basilisk's own
modules: ``flex_mode`` a hinged panel (hingedRigidBodyStateEffector),
``fuel_slosh`` spring-mass-damper slosh (linearSpringMassDamper).

What stays the bench's: the minimum detectable size of each run (measured
on the bench's flight of it, bench/gap/detectable.py, as the bench campaign
does; a Basilisk search would fly tens of logs per run) and the null
calibration the diagnosis thresholds with (the 12 kg vehicle's, made on the
bench's plant). A null Basilisk log that the diagnosis flags is therefore a
disagreement between the engines, scored as a false alarm.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from bench.gap import validate_vehicle as vv
from bench.gap.validate import key_hash, pool_map, score


def simulate_key(key: dict, effects: dict | None = None):
    """The Basilisk log of ``key``'s run (with ``effects``, default the key's)."""
    from bench.basilisk_sim import simulate
    from bench.gap.plans import characterisation_plan

    desc = vv.description()
    log, _ = simulate(desc, characterisation_plan(desc, seed=key["seed"]), key["effects"] if effects is None else effects,
                      seed=key["seed"], clocks=vv.clocks_for(key["seed"]), with_truth=False)
    if key.get("no_valves"):
        log.streams.pop("valves")
    log.config = {}
    return log


def _run_one(arg):
    key, calibration = arg
    from bench.gap.diagnose import diagnose, public
    from bench.gap.separability import separability_of_logs
    from bench.gap.validate import forced_fit

    t0 = time.time()
    log = simulate_key(key)
    t_sim = time.time() - t0
    res = diagnose(log, calibration=calibration, calibration_source="the 12 kg vehicle's null calibration")
    pub = public(res)
    out = {"run": key["run"], "gap_detected": pub["gap_detected"], "verdict": pub["verdict"],
           "top1": pub["attribution"][0]["effect"] if pub["attribution"] else None,
           "ranking": [r["effect"] for r in pub["attribution"]],
           "map_max_abs_z": pub["statistics"]["map_max_abs_z"], "screen_logp_max": pub["statistics"]["screen_logp_max"],
           "not_examined": pub["examined"]["not_examined"], "t_sim_s": t_sim, "t_diagnose_s": pub["elapsed_s"]}
    it = res["_internal"]
    eff = key["effect"]
    if key["category"] == "in_library":
        out["true_fit"] = forced_fit(it, eff)
        wrong = [n for n in it["d"].cands if n != eff]
        w = wrong[np.random.default_rng(key["seed"]).integers(len(wrong))]
        out["wrong_fit"] = {"effect": w, **forced_fit(it, w)}
    if eff is not None:
        sep = separability_of_logs(simulate_key(key, {}), log, eff, key["category"] == "in_library")
        out["separability"] = {k: sep.get(k) for k in ("lambda", "closest", "delta2_min", "separable")}
    return out


def run_campaign(n_runs: int, seed: int, out: str | None, workers: int, progress: bool = True) -> dict:
    from bench.basilisk_sim import basilisk_version

    cal = vv.load_calibration()
    t0 = time.time()
    keys = pool_map(vv._size_one, [(k, cal) for k in vv.draw_campaign(n_runs, seed)], workers, progress,
                    "minimum detectable sizes (bench engine)")
    hashes = [key_hash(k) for k in keys]
    if out:
        prereg = Path(str(out) + ".prereg.json")
        prereg.parent.mkdir(parents=True, exist_ok=True)
        prereg.write_text(json.dumps({"seed": seed, "runs": n_runs, "vehicle": vv.VEHICLE, "engine": "basilisk",
                                      "key_sha256": hashes}, indent=1) + "\n")
    answers = pool_map(_run_one, [(k, cal) for k in keys], workers, progress, "validate-gap (Basilisk logs)")
    if [key_hash(k) for k in keys] != hashes:
        raise RuntimeError("drawn keys changed during the campaign")
    res = score(keys, answers)
    no_valves = [(k, a) for k, a in zip(keys, answers) if k["no_valves"]]
    res["no_valves_stream"] = {
        "n": len(no_valves),
        "said_dynamics_not_examined": int(sum(any(x.startswith("dynamics") for x in a["not_examined"])
                                              for _, a in no_valves))}
    res.update({"seed": seed, "vehicle": vv.VEHICLE, "engine": "basilisk", "basilisk_version": basilisk_version(),
                "workers": workers, "elapsed_s": time.time() - t0,
                "calibration": {"runs": cal.get("runs"), "thresholds": cal.get("thresholds")},
                "keys_match_preregistration": True, "key_sha256": hashes, "keys": keys, "answers": answers,
                "command": f"proxops validate-gap --engine basilisk --runs {n_runs} --seed {seed}"})
    return res
