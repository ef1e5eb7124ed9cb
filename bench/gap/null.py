"""Null calibration: detection thresholds from the diagnoser run on
simulated-on-simulated logs (a seeded Monte Carlo), not from chi-square
tables, stored with the false-alarm rate they give.

Regenerate the committed cache (bench/gap/data/null_calibration.json):
    python -m bench.gap.null --runs 1000 --seed 1000 --workers 2

(each run a Dask task, kept in a results store as it finishes; add
``--scheduler tcp://HOST:PORT`` for a cluster, docs/CAMPAIGNS.md)

Logs that also fly the thruster characterisation after docking have their
own (bench/gap/data/null_calibration_characterisation.json):
    python -m bench.gap.null --runs 1000 --seed 1001 --manoeuvres docking+characterisation

Each statistic gets the threshold that leaves FA_EACH of the null runs above
it (the empirical quantile, a little beyond the largest value when there are
few runs); the stored ``false_alarm_rate`` is the fraction of the null runs
that either statistic flags.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "null_calibration.json"
DATA_BY_MANOEUVRES = {
    "docking": DATA,
    "docking+characterisation": DATA.with_name("null_calibration_characterisation.json"),
}
FA_EACH = 0.005


def load(path=DATA, manoeuvres: str | None = None) -> dict:
    """The null calibration at ``path``, or the committed one for logs that
    fly ``manoeuvres`` (bench/gap/validate.py MANOEUVRES)."""
    p = Path(DATA_BY_MANOEUVRES[manoeuvres] if manoeuvres is not None else path)
    if not p.exists():
        return {}
    return json.loads(p.read_text())


def null_log(seed: int, duration_s: float, manoeuvres: str = "docking"):
    """One simulated-on-simulated log: bench.sim.reality without effects when
    available, else the bench's docking scenario."""
    from bench.gap.simlogs import docking_log, reality_available
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


def quantile_threshold(values: np.ndarray, fa: float) -> float:
    """The threshold a null value exceeds with probability ``fa``: midway
    between the order statistics around the (1 - fa) quantile, or just beyond
    the largest value when there are too few values for that quantile."""
    v = np.sort(np.asarray(values, float))
    k = int(np.floor((1.0 - fa) * v.size))
    if k >= v.size - 1:  # too few runs for that quantile: just beyond the largest
        return float(v[-1] + 0.05 * (v[-1] - v[0] + 1e-9))
    return float(0.5 * (v[k] + v[k + 1]))


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


def main(argv=None):
    from bench.commands.campaign_args import add_campaign_arguments, campaign_from

    ap = argparse.ArgumentParser(description="Null calibration of the gap diagnoser")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument(
        "--manoeuvres",
        default="docking",
        choices=tuple(DATA_BY_MANOEUVRES),
        help="what the null logs fly (bench/gap/validate.py)",
    )
    ap.add_argument("--out", default=None, help="default: the committed calibration for --manoeuvres")
    add_campaign_arguments(ap)
    a = ap.parse_args(argv)
    campaign = campaign_from(
        a, "null-calibration", {"runs": a.runs, "seed": a.seed, "duration_s": a.duration, "manoeuvres": a.manoeuvres}
    )
    seeds = np.random.default_rng(a.seed).integers(0, 2**31, a.runs)
    cal = calibrate(seeds, a.duration, manoeuvres=a.manoeuvres, campaign=campaign)
    cal["command"] = f"python -m bench.gap.null --runs {a.runs} --seed {a.seed} --duration {a.duration:g}" + (
        f" --manoeuvres {a.manoeuvres}" if a.manoeuvres != "docking" else ""
    )
    out = Path(a.out) if a.out else DATA_BY_MANOEUVRES[a.manoeuvres]
    if a.summarise_only and cal["runs"] < a.runs:
        print(f"{cal['runs']} of {a.runs} runs stored: {out} left as it is")
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(cal, indent=1) + "\n")
    print(f"thresholds {cal['thresholds']}, false-alarm rate {cal['false_alarm_rate']:.3f} over {cal['runs']} runs")


if __name__ == "__main__":
    main()
