"""The campaign that makes the committed null calibrations
(bench/gap/null.py): the diagnoser's two detection statistics on seeded
simulated-on-simulated logs, each run a Dask task kept in a results store
as it finishes. Its command line: bench/commands/null_calibration.py."""

from __future__ import annotations

import time

import numpy as np

from bench.gap.null import FA_EACH, quantile_threshold


def null_log(seed: int, duration_s: float, manoeuvres: str = "docking"):
    """One simulated-on-simulated log: bench.sim.reality without effects when
    available, else the bench's docking scenario."""
    from bench.campaigns.gap.simlogs import docking_log, reality_available
    from bench.sim.plans import then_scripts

    then = then_scripts({"manoeuvres": manoeuvres})
    if reality_available():
        from bench.sim.reality import simulate_log_with_key

        log, _ = simulate_log_with_key(seed, {}, duration_s=duration_s, with_truth=True, then_scripts=then)
        return log
    if then is not None:
        raise ValueError("a characterisation needs bench.sim.reality")
    return docking_log(seed, t_max_s=duration_s)


def run_statistics(seed, run_ctx):
    duration_s, manoeuvres = run_ctx
    from bench.gap.detection import null_statistics

    return {"seed": seed, **null_statistics(null_log(seed, duration_s, manoeuvres))}


def calibrate(
    seeds,
    duration_s: float = 120.0,
    workers: int | None = None,
    progress: bool = True,
    manoeuvres: str = "docking",
    campaign=None,
) -> dict:
    from bench.runner.runner import all_failed, failures, new_campaign, results

    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    seeds = [int(s) for s in seeds]
    recs = campaign.map(
        "null",
        run_statistics,
        seeds,
        idents=[{"seed": s} for s in seeds],
        shared=(duration_s, manoeuvres),
        label="null calibration",
    )
    all_failed(recs)
    rows = [r for r in results(recs) if r is not None]
    if not rows:
        raise ValueError("no finished null runs")
    z = np.array([r["map_max_abs_z"] for r in rows])
    b = np.array([r["screen_logp"] for r in rows])
    thr = {"map_max_abs_z": quantile_threshold(z, FA_EACH), "screen_logp": quantile_threshold(b, FA_EACH)}
    fa = float(np.mean((z > thr["map_max_abs_z"]) | (b > thr["screen_logp"])))
    return {
        "thresholds": thr,
        "false_alarm_rate": fa,
        "false_alarm_target_each": FA_EACH,
        "runs": len(rows),
        "duration_s": duration_s,
        "manoeuvres": manoeuvres,
        "seeds": [r["seed"] for r in rows],
        "null_map_max_abs_z": z.tolist(),
        "null_screen_logp": b.tolist(),
        "elapsed_s": time.time() - t0,
        **({"failed_runs": failures(recs)} if failures(recs) else {}),
        "command": None,
    }
