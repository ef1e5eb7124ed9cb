"""The null calibration made for a log (bench/gap/log_null.py), checked:
the evidence for its tail model on the committed 1000-run calibrations
(``tails``), its false-alarm rate on random vehicles (``far``), and what
the start pose of a run does to it (``start``).

    python -m bench.campaigns.gap.log_null_far tails
    python -m bench.campaigns.gap.log_null_far far --vehicles 40 --logs 20 --runs 40 --seed 1 --workers 2
    python -m bench.campaigns.gap.log_null_far start --vehicles 3 --runs 40 --seed 6 --workers 2
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bench.gap.log_null import (
    DEFAULT_RUNS,
    FA_EACH,
    STATISTICS,
    TAIL_FRACTION,
    VERSION,
    calibrate_for_log,
    frechet_threshold,
    null_run,
    plan_of,
    tail_threshold,
    thresholds_of,
)

# --- Evidence for the tail model, on the committed 1000-run calibrations ---


def _plugin_exponential(values, fa: float = FA_EACH) -> float:
    """The exponential tail of ``tail_threshold`` with its fitted scale (no
    predictive): for comparison."""
    v = np.sort(np.asarray(values, float))[::-1]
    n = v.size
    k = int(min(max(round(TAIL_FRACTION * n), 1), n - 1))
    return float(v[k] + np.mean(v[:k] - v[k]) * np.log((k + 1) / (n + 1) / fa))


def _gpd_ml(values, fa: float = FA_EACH, top: float = 0.25) -> float:
    """A generalised Pareto fitted by maximum likelihood to the excesses of
    the top ``top`` share (shape bounded to [-0.5, 0.5]): for comparison."""
    from scipy.stats import genpareto

    v = np.sort(np.asarray(values, float))[::-1]
    n = v.size
    k = max(int(round(top * n)), 3)
    e = v[:k] - v[k]
    xi, _, sig = genpareto.fit(e, floc=0.0)
    if not -0.5 <= xi <= 0.5:
        xi = float(np.clip(xi, -0.5, 0.5))
        sig = genpareto.fit(e, f0=xi, floc=0.0)[2]
    return float(v[k] + genpareto.ppf(1.0 - fa * (n + 1) / (k + 1), xi, 0.0, sig))


TAIL_MODELS = {
    "predictive exponential, top 60 % (used)": lambda v: tail_threshold(v)[0],
    "Gumbel by moments on log(values) (before)": frechet_threshold,
    "exponential, top 60 %, fitted scale": _plugin_exponential,
    "generalised Pareto, top 25 %, ML shape": _gpd_ml,
}
LOWER_TAIL_DECADES = 1.0  # how far the synthetic long lower tail reaches down
MAX_RATIO = 2.0  # a threshold at most this many times the largest null value


def _stretched_low(v: np.ndarray, rng) -> np.ndarray:
    """``v`` with its values below the tail's order statistic (the
    (k + 1)-th largest) spread down by up to LOWER_TAIL_DECADES decades: a
    long lower tail."""
    out = v.copy()
    k = int(min(max(round(TAIL_FRACTION * v.size), 1), v.size - 1))
    low = np.argsort(v)[: v.size - k - 1]
    out[low] = v[low] * 10.0 ** (-LOWER_TAIL_DECADES * rng.uniform(size=low.size))
    return out


def tail_evidence(draws: int = 1000, n: int = DEFAULT_RUNS, seed: int = 2026, models=None) -> dict:
    """Per committed 1000-run calibration and tail model: over ``draws``
    random ``n``-run subsets, the false-alarm rate of the two thresholds on
    all 1000 null runs (both statistics: median and 95th percentile; each:
    mean), the threshold over the subset's largest value (95th, 99th
    percentile), and the same ratio when the subset's lower values are
    stretched into a long lower tail (95th percentile, share above
    MAX_RATIO)."""
    from bench.gap import null as nullmod

    models = models or TAIL_MODELS
    out = {}
    for manoeuvres in ("docking", "docking+characterisation"):
        cal = nullmod.load(manoeuvres=manoeuvres)
        vals = {k: np.array(cal[f"null_{k}"], float) for k in STATISTICS}
        rng = np.random.default_rng(seed)
        idx = [rng.choice(vals[STATISTICS[0]].size, n, replace=False) for _ in range(draws)]
        low = {k: [_stretched_low(vals[k][i], rng) for i in idx] for k in STATISTICS}
        rows = {}
        for name, fn in models.items():
            fa, each, ratio, ratio_low = [], {k: [] for k in STATISTICS}, [], []
            for j, i in enumerate(idx):
                thr = {k: fn(vals[k][i]) for k in STATISTICS}
                over = {k: vals[k] > thr[k] for k in STATISTICS}
                fa.append(float(np.mean(over[STATISTICS[0]] | over[STATISTICS[1]])))
                for k in STATISTICS:
                    each[k].append(float(np.mean(over[k])))
                    ratio.append(thr[k] / vals[k][i].max())
                    ratio_low.append(fn(low[k][j]) / low[k][j].max())
            rows[name] = {
                "false_alarm_median": float(np.median(fa)),
                "false_alarm_p95": float(np.percentile(fa, 95)),
                **{f"false_alarm_mean_{k}": float(np.mean(each[k])) for k in STATISTICS},
                "ratio_to_max_p95": float(np.percentile(ratio, 95)),
                "ratio_to_max_p99": float(np.percentile(ratio, 99)),
                "long_lower_tail_ratio_p95": float(np.percentile(ratio_low, 95)),
                "long_lower_tail_above_max_ratio": float(np.mean(np.array(ratio_low) > MAX_RATIO)),
            }
        out[manoeuvres] = rows
    return {"draws": draws, "runs": n, "seed": seed, "fa_each": FA_EACH, "max_ratio": MAX_RATIO, "models": out}


def _print_tails(ev: dict) -> None:
    print(
        f"{ev['draws']} random {ev['runs']}-run subsets of each committed 1000-run calibration (seed {ev['seed']}); "
        "false alarms on its 1000 runs; threshold / largest of the subset"
    )
    for manoeuvres, rows in ev["models"].items():
        print(f"\n{manoeuvres}:")
        print("  model | FA both median, p95 | FA mean map, screen | ratio p95, p99 | long lower tail: p95, > 2")
        for name, r in rows.items():
            print(
                f"  {name} | {r['false_alarm_median']:.4f}, {r['false_alarm_p95']:.4f} | "
                f"{r['false_alarm_mean_map_max_abs_z']:.4f}, {r['false_alarm_mean_screen_logp']:.4f} | "
                f"{r['ratio_to_max_p95']:.2f}, {r['ratio_to_max_p99']:.2f} | "
                f"{r['long_lower_tail_ratio_p95']:.2f}, {r['long_lower_tail_above_max_ratio']:.1%}"
            )


# --- The false-alarm rate on random vehicles (``far``) ---


def random_flight(vehicle_seed: int) -> tuple:
    """(description, clocks, plan) of a random vehicle flying its
    characterisation (bench/sim/random_vehicle.py, bench/sim/plans.py)."""
    from bench.sim.plans import characterisation_plan
    from bench.sim.random_vehicle import random_clocks, random_description

    description = random_description(vehicle_seed)
    clocks = random_clocks(vehicle_seed, description["imu"]["rate_hz"])
    return description, clocks, characterisation_plan(description, vehicle_seed)


def effect_free_log(vehicle_seed: int, seed: int):
    """An effect-free log of the random vehicle's flight, noise and clock
    draws from ``seed``, its time stamps from its own origin (as diagnose()
    reads a log written on a Unix epoch)."""
    from bench.sim.flight_log import relative_to_start
    from bench.sim.vehicle_sim import simulate

    description, clocks, plan = random_flight(vehicle_seed)
    log, _ = simulate(description, plan, {}, seed=seed, clocks=clocks, with_truth=False)
    return relative_to_start(log)


def _log_statistics(item) -> dict:
    from bench.gap.detection import null_statistics

    return {"seed": int(item["seed"]), **null_statistics(effect_free_log(item["vehicle"], item["seed"]))}


def _vehicle_summary(vehicle_seed: int) -> dict:
    description, clocks, plan = random_flight(vehicle_seed)
    v, imu = description["vehicle"], description["imu"]
    return {
        "vehicle_seed": int(vehicle_seed),
        "mass_kg": v["mass_kg"],
        "thrusters": len(v["thrusters"]),
        "imu_rate_hz": imu["rate_hz"],
        "runs_flown": len(plan),
        "flight_s": float(sum(p.duration_s for p in plan)),
    }


def far_vehicle(vehicle_seed: int, n_logs: int, runs: int, seed: int, campaign, cache_dir=None) -> dict:
    """One random vehicle: a calibration made for one effect-free log (its
    ``runs`` null runs), then that log against its thresholds (what a team
    diagnosing its own log sees) and ``n_logs`` fresh effect-free logs of
    the same vehicle, plan and clock model against them (other noise and
    other clock draws: such a log's time stamps differ, so it would get a
    calibration of its own; against this one the test is stricter). Raises
    ValueError when the vehicle's log cannot be diagnosed."""
    rng = np.random.default_rng([int(seed), int(vehicle_seed)])
    seeds = [int(s) for s in rng.integers(0, 2**31, n_logs + 1)]
    out = _vehicle_summary(vehicle_seed)
    from bench.gap.detection import null_statistics

    log0 = effect_free_log(vehicle_seed, seeds[0])
    own = null_statistics(log0)  # raises where the log cannot be diagnosed, before the calibration
    cal = calibrate_for_log(log0, runs=runs, cache_dir=cache_dir, progress=campaign.progress)
    thr = cal["thresholds"]
    recs = campaign.map(
        f"vehicle-{vehicle_seed}",
        _log_statistics,
        [{"vehicle": int(vehicle_seed), "seed": s} for s in seeds[1:]],
        label=f"vehicle {vehicle_seed}: {n_logs} effect-free logs",
    )
    logs = [dict(r["result"]) if r is not None and r.get("ok") else None for r in recs]
    failed = [r.get("error") for r in recs if r is not None and not r.get("ok")]

    def judged(s: dict) -> dict:
        over = {k: bool(s[k] > thr[k]) for k in STATISTICS}
        return {**s, "over": over, "false_alarm": any(over.values())}

    old = {k: frechet_threshold(cal[f"null_{k}"]) for k in STATISTICS}
    out.update(
        thresholds=thr,
        tail=cal.get("tail"),
        null_max={k: float(np.max(cal[f"null_{k}"])) for k in STATISTICS},
        thresholds_before=old,  # the Gumbel on log(values) of the same null runs
        calibration_s=cal.get("elapsed_s"),
        calibration_from_cache=bool(cal.get("from_cache")),
        own_log=judged({"seed": seeds[0], **own}),
        null={k: cal[f"null_{k}"] for k in STATISTICS},
        leave_one_out=leave_one_out({k: cal[f"null_{k}"] for k in STATISTICS}),
        logs=[judged(s) for s in logs if s is not None],
        failed_logs=failed,
    )
    return out


def _moved_start(prepared: tuple, plan: list) -> tuple:
    """``prepared`` (plan_of) with every run starting at ``plan``'s start
    pose instead of the log's first pose."""
    import dataclasses

    description, runs_flown, times, d = prepared
    if len(runs_flown) != len(plan):
        raise ValueError(f"the log holds {len(runs_flown)} runs, the plan {len(plan)}")
    moved = [
        dataclasses.replace(p, r0_hill_m=q.r0_hill_m.copy(), q0_hb=q.q0_hb.copy()) for p, q in zip(runs_flown, plan)
    ]
    return description, moved, times, d


def _one_from(item, flights):
    return null_run(item["seed"], flights[item["start"]])


def _spread(values, draws: int = 200, seed: int = 0) -> float:
    """The standard deviation of tail_threshold over resamples of ``values``."""
    rng = np.random.default_rng(seed)
    v = np.asarray(values, float)
    return float(np.std([tail_threshold(rng.choice(v, v.size))[0] for _ in range(draws)]))


def start_pose_effect(vehicle_seed: int, runs: int, seed: int, campaign) -> dict:
    """Whether the start pose moves the thresholds: one random vehicle's
    calibration runs (same seeds) flown from its log's first pose and from
    the plan's true start; per statistic both thresholds, the threshold's
    own resampling spread, and the runs' paired differences."""
    from bench.so3 import qconj, qlog, qmul

    _, _, plan = random_flight(vehicle_seed)
    log0 = effect_free_log(vehicle_seed, int(np.random.default_rng([int(seed), int(vehicle_seed)]).integers(2**31)))
    prepared = plan_of(log0)
    flights = {"first pose": (log0, prepared), "true start": (log0, _moved_start(prepared, plan))}
    seeds = [int(s) for s in np.random.default_rng(7100).integers(0, 2**31, runs)]
    recs = campaign.map(
        f"start-{vehicle_seed}",
        _one_from,
        [{"seed": s, "start": w} for w in flights for s in seeds],
        shared=flights,
        label=f"vehicle {vehicle_seed}: null runs from two start poses",
    )
    rows = [r["result"] for r in recs]
    a, b = thresholds_of(rows[:runs]), thresholds_of(rows[runs:])
    p0, q0 = prepared[1][0], plan[0]
    out = {
        "vehicle_seed": int(vehicle_seed),
        "first_pose_offset_m": float(np.linalg.norm(p0.r0_hill_m - q0.r0_hill_m)),
        "first_pose_offset_deg": float(np.degrees(2 * np.linalg.norm(qlog(qmul(qconj(q0.q0_hb), p0.q0_hb))))),
    }
    for k in STATISTICS:
        out[k] = {
            "threshold_first_pose": a[0][k],
            "threshold_true_start": b[0][k],
            "threshold_spread": _spread(a[2][k]),
            "paired_abs_difference_median": float(np.median(np.abs(a[2][k] - b[2][k]))),
            "null_values_spread": float(np.std(a[2][k], ddof=1)),
        }
    return out


def leave_one_out(null: dict) -> tuple:
    """(flagged, runs): each of a calibration's null runs judged against the
    thresholds of the others (either statistic over its threshold): the
    false-alarm rate of a calibration of n - 1 runs for a log exchangeable
    with its bootstrap, on that log's own null distribution."""
    vals = [np.asarray(null[k], float) for k in STATISTICS]
    n = vals[0].size
    flagged = 0
    for i in range(n):
        keep = np.arange(n) != i
        flagged += any(v[i] > tail_threshold(v[keep])[0] for v in vals)
    return int(flagged), int(n)


def _rate(k: int, n: int) -> dict:
    """k of n, with the 95 % Clopper-Pearson interval."""
    from scipy.stats import beta

    if n == 0:
        return {"false_alarms": 0, "logs": 0, "rate": None, "interval95": None}
    lo = float(beta.ppf(0.025, k, n - k + 1)) if k > 0 else 0.0
    hi = float(beta.ppf(0.975, k + 1, n - k)) if k < n else 1.0
    return {"false_alarms": int(k), "logs": int(n), "rate": k / n if n else None, "interval95": [lo, hi]}


def far_summary(scored: list) -> dict:
    """The false-alarm rates over every vehicle's fresh logs and own logs,
    and how far the thresholds sit above their null runs."""
    logs = [s for v in scored for s in v["logs"]]
    own = [v["own_log"] for v in scored]
    ratio = {k: [v["thresholds"][k] / v["null_max"][k] for v in scored] for k in STATISTICS}
    ratio_before = {k: [v["thresholds_before"][k] / v["null_max"][k] for v in scored] for k in STATISTICS}
    return {
        "vehicles": len(scored),
        "fresh_logs": _rate(sum(s["false_alarm"] for s in logs), len(logs)),
        "fresh_logs_by_statistic": {k: _rate(sum(s["over"][k] for s in logs), len(logs)) for k in STATISTICS},
        "own_logs": _rate(sum(s["false_alarm"] for s in own), len(own)),
        "leave_one_out": _rate(*(int(x) for x in np.sum([v["leave_one_out"] for v in scored] or [(0, 0)], axis=0))),
        "threshold_over_null_max": {k: [float(np.median(r)), float(np.max(r))] for k, r in ratio.items()},
        "threshold_before_over_null_max": {k: [float(np.median(r)), float(np.max(r))] for k, r in ratio_before.items()},
    }


def far(vehicles: int, n_logs: int, runs: int, seed: int, campaign, cache_dir=None) -> dict:
    """``far_vehicle`` for random vehicles seed, seed + 1, ... until
    ``vehicles`` of them could be diagnosed (at most 3 * vehicles drawn);
    the others are listed with why."""
    t0 = time.time()
    scored, skipped = [], []
    vs = int(seed)
    while len(scored) < vehicles and vs < seed + 3 * vehicles:
        try:
            scored.append(far_vehicle(vs, n_logs, runs, seed, campaign, cache_dir))
        except ValueError as exc:
            skipped.append({**_vehicle_summary(vs), "error": f"{type(exc).__name__}: {exc}"})
            campaign.say(f"vehicle {vs}: not diagnosable ({exc})")
        vs += 1
    return {
        "question": "false-alarm rate of the calibration made for a log, on effect-free logs of random vehicles",
        "vehicles_asked": int(vehicles),
        "logs_per_vehicle": int(n_logs),
        "runs": int(runs),
        "seed": int(seed),
        "version": VERSION,
        "summary": far_summary(scored),
        "vehicles": scored,
        "not_diagnosable": skipped,
        "elapsed_s": time.time() - t0,
    }


def _print_far(res: dict) -> None:
    s = res["summary"]
    f, o = s["fresh_logs"], s["own_logs"]
    print(
        f"{s['vehicles']} random vehicles ({len(res['not_diagnosable'])} drawn could not be diagnosed), "
        f"{res['runs']} null runs each"
    )
    if f["logs"]:
        print(
            f"fresh effect-free logs: {f['false_alarms']} of {f['logs']} flagged = {f['rate']:.1%} "
            f"(95 % interval {f['interval95'][0]:.1%} to {f['interval95'][1]:.1%}); "
            + ", ".join(f"{k} {v['false_alarms']}" for k, v in s["fresh_logs_by_statistic"].items())
        )
    if o["logs"]:
        print(f"logs against the calibration made for each: {o['false_alarms']} of {o['logs']} flagged")
    if s.get("leave_one_out"):
        loo = s["leave_one_out"]
        print(
            f"null runs against the thresholds of the others: {loo['false_alarms']} of {loo['logs']} = {loo['rate']:.1%}"
        )
    for v in res["not_diagnosable"]:
        print(f"  vehicle {v['vehicle_seed']} ({v['imu_rate_hz']:g} Hz IMU): {v['error']}")


def _runner_arguments(p) -> None:
    p.add_argument("--workers", type=int, default=None, help="local Dask worker processes (default: all cores)")
    p.add_argument("--store", default=None, help="results store (default: the campaigns')")


def _campaign(a, name: str, arguments: dict):
    """The campaign (bench/runner) of a subcommand: its runs on a local
    cluster of --workers, each kept in the results store as it finishes."""
    from bench.runner import cluster
    from bench.runner.runner import Campaign
    from bench.runner.store import RunStore

    cluster.configure(None, a.workers)  # the calibrations' campaigns too
    return Campaign(RunStore(name, arguments, root=a.store), workers=a.workers)


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m bench.campaigns.gap.log_null_far", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    t = sub.add_parser("tails", help="the tail models on random subsets of the committed 1000-run calibrations")
    t.add_argument("--draws", type=int, default=1000)
    t.add_argument("--runs", type=int, default=DEFAULT_RUNS)
    t.add_argument("--seed", type=int, default=2026)
    f = sub.add_parser("far", help="false-alarm rate of calibrations made for logs of random vehicles")
    f.add_argument("--vehicles", type=int, default=20, help="random vehicles to score (seeds --seed, --seed + 1, ...)")
    f.add_argument("--logs", type=int, default=10, help="fresh effect-free logs per vehicle")
    f.add_argument("--runs", type=int, default=DEFAULT_RUNS, help="null runs per calibration")
    f.add_argument("--seed", type=int, default=1)
    f.add_argument("--cache", default=None, help="where the calibrations are cached (default: the diagnosis's)")
    st = sub.add_parser("start", help="whether the start pose moves a calibration's thresholds")
    st.add_argument("--vehicles", type=int, default=3)
    st.add_argument("--runs", type=int, default=DEFAULT_RUNS)
    st.add_argument("--seed", type=int, default=1)
    for p in (f, st):
        _runner_arguments(p)
    for p in (t, f, st):
        p.add_argument("--json", default=None)
    return ap


def main(argv=None) -> None:
    a = _parser().parse_args(argv)
    if a.what == "tails":
        res = tail_evidence(a.draws, a.runs, a.seed)
        _print_tails(res)
    elif a.what == "start":
        campaign = _campaign(a, "log-null-start", {"runs": a.runs, "seed": a.seed, "version": VERSION})
        res = {"vehicles": [start_pose_effect(a.seed + i, a.runs, a.seed, campaign) for i in range(a.vehicles)]}
        res["command"] = (
            f"python -m bench.campaigns.gap.log_null_far start --vehicles {a.vehicles} --runs {a.runs} --seed {a.seed}"
        )
        print(json.dumps(res, indent=1))
    else:
        args = {"vehicles": a.vehicles, "logs": a.logs, "runs": a.runs, "seed": a.seed, "version": VERSION}
        res = far(a.vehicles, a.logs, a.runs, a.seed, _campaign(a, "log-null-far", args), a.cache)
        res["command"] = (
            f"python -m bench.campaigns.gap.log_null_far far --vehicles {a.vehicles} --logs {a.logs} --runs {a.runs} --seed {a.seed}"
        )
        _print_far(res)
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps(res, indent=1) + "\n")


if __name__ == "__main__":
    main()
