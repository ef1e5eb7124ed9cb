"""Blind validation on logs from Basilisk: ``proxops validate-gap --engine
basilisk``.

The campaign of ``--vehicle 12kg`` (bench/campaigns/gap/validate_vehicle.py: the 12 kg
inspector's characterisation, time stamps as real logs have them, one run in
ten without a valves stream, null, in-library and out-of-library runs at 1x
and 2x each run's own minimum detectable size, keys hashed before any
diagnosis), with every scored log flown by Basilisk (bench/sim/basilisk_sim.py)
instead of the bench's plant. The out-of-library effects are Basilisk's own
modules: ``flex_mode`` a hinged panel (hingedRigidBodyStateEffector),
``fuel_slosh`` spring-mass-damper slosh (linearSpringMassDamper).

What stays the bench's: the minimum detectable size of each run (measured
on the bench's flight of it, bench/campaigns/gap/detectable.py, as the bench campaign
does; a Basilisk search would fly tens of logs per run) and the null
calibration the diagnosis thresholds with (the 12 kg vehicle's, made on the
bench's plant). A null Basilisk log that the diagnosis flags is therefore a
disagreement between the engines, scored as a false alarm.
"""

from __future__ import annotations

import time

from bench.campaigns.gap import validate_vehicle as vv
from bench.campaigns.gap.validate import score, sized_and_diagnosed


def simulate_key(key: dict, effects: dict | None = None):
    """The Basilisk log of ``key``'s run (with ``effects``, default the key's)."""
    from bench.sim.basilisk_sim import simulate
    from bench.sim.plans import characterisation_plan

    desc = vv.description()
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=key["seed"]),
        key["effects"] if effects is None else effects,
        seed=key["seed"],
        clocks=vv.clocks_for(key["seed"]),
        with_truth=False,
    )
    if key.get("no_valves"):
        log.streams.pop("valves")
    log.config = {}
    return log


def run_one(key: dict, calibration: dict) -> dict:
    """The 12 kg campaign's diagnosis of one run, on its Basilisk log."""
    return vv.diagnose_run(key, calibration, simulate_key)


def run_campaign(
    n_runs: int, seed: int, out: str | None, workers: int | None = None, progress: bool = True, campaign=None
) -> dict:
    from bench.runner.runner import new_campaign
    from bench.sim.basilisk_sim import basilisk_version

    cal = vv.load_calibration()
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    keys, answers, hashes, info = sized_and_diagnosed(
        campaign,
        vv.draw_campaign(n_runs, seed),
        vv.size_run,
        run_one,
        cal,
        out,
        {"seed": seed, "runs": n_runs, "vehicle": vv.VEHICLE, "engine": "basilisk"},
        "validate-gap (Basilisk logs)",
    )
    res = score(keys, answers)
    no_valves = [(k, a) for k, a in zip(keys, answers) if k["no_valves"]]
    res["no_valves_stream"] = {
        "n": len(no_valves),
        "said_dynamics_not_examined": int(
            sum(any(x.startswith("dynamics") for x in a["not_examined"]) for _, a in no_valves)
        ),
    }
    res.update(
        {
            "seed": seed,
            "vehicle": vv.VEHICLE,
            "engine": "basilisk",
            "basilisk_version": basilisk_version(),
            "workers": workers,
            "elapsed_s": time.time() - t0,
            "campaign": info,
            "calibration": {"runs": cal.get("runs"), "thresholds": cal.get("thresholds")},
            "keys_match_preregistration": True,
            "key_sha256": hashes,
            "keys": keys,
            "answers": answers,
            "command": f"proxops validate-gap --engine basilisk --runs {n_runs} --seed {seed}",
        }
    )
    return res


def refly(campaign_result: dict, effect: str, calibration: dict | None = None, progress: bool = True) -> dict:
    """The runs of ``effect`` in a finished campaign (its result with keys and
    answers: the ``--json`` file, or its ``.full.json.gz``), flown again by
    the current engine and diagnosed with the same calibration: the answers
    before and after a change to the engine, run by run."""
    cal = calibration if calibration is not None else vv.load_calibration()
    pairs = [(k, a) for k, a in zip(campaign_result["keys"], campaign_result["answers"]) if k.get("effect") == effect]
    if not pairs:
        raise ValueError(f"no {effect!r} run in the campaign (seed {campaign_result.get('seed')})")
    rows = []
    for i, (key, before) in enumerate(pairs):
        t0 = time.time()
        after = run_one(key, cal)
        rows.append(
            {
                "run": key["run"],
                "effects": key["effects"],
                "scale": key["scale"],
                "before": {f: before.get(f) for f in ("verdict", "gap_detected", "top1", "map_max_abs_z")},
                "after": {f: after.get(f) for f in ("verdict", "gap_detected", "top1", "map_max_abs_z")},
                "answer": after,
            }
        )
        if progress:
            import sys

            print(
                f"  run {key['run']} ({i + 1} of {len(pairs)}): {_said(before)} -> {_said(after)}, "
                f"{time.time() - t0:.0f} s",
                file=sys.stderr,
                flush=True,
            )

    def counts(which):
        out = {}
        for r in rows:
            s = _said(r[which])
            out[s] = out.get(s, 0) + 1
        return out

    return {
        "effect": effect,
        "seed": campaign_result.get("seed"),
        "n": len(rows),
        "before": counts("before"),
        "after": counts("after"),
        "runs": rows,
    }


def _said(answer: dict) -> str:
    return answer["verdict"] if answer.get("gap_detected") else "no_gap"


def main(argv=None):
    import argparse
    import gzip
    import json

    from bench.sim.basilisk_sim import basilisk_version

    ap = argparse.ArgumentParser(
        description="Fly one effect's runs of a finished Basilisk campaign again with the "
        "current engine: the answers before and after"
    )
    ap.add_argument("what", choices=("refly",))
    ap.add_argument("campaign", help="the campaign's result with keys and answers (--json OUT, or its .full.json.gz)")
    ap.add_argument("--effect", required=True)
    ap.add_argument("--json", default=None, help="write the answers here")
    a = ap.parse_args(argv)
    opener = gzip.open if a.campaign.endswith(".gz") else open
    with opener(a.campaign, "rt") as f:
        src = json.load(f)
    t0 = time.time()
    res = refly(src, a.effect)
    res.update({"source": a.campaign, "basilisk_version": basilisk_version(), "elapsed_s": time.time() - t0})
    print(
        f"{a.effect}, {res['n']} runs of seed {res['seed']}: before {res['before']}, after {res['after']}; "
        f"{res['elapsed_s']:.0f} s"
    )
    if a.json:
        from bench.report import write_json

        write_json(a.json, res, strict=True)


if __name__ == "__main__":
    main()
