"""`proxops modal` and `proxops modal-timing`: the modal estimator on the
simulation and experiment of "Shape, Motion, and Parameter Estimation of Large
Flexible Space Structures using Range Images" (Lichter and Dubowsky), and its
timing grid (that paper's Table I)."""

from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np

from bench.commands.args import HelpFormatter, number, one_line_errors, seed
from bench.commands.campaign_args import add_campaign_arguments, campaign_from
from bench.report import matplotlib_agg, report_dir, write_json

# The paper's experiment: 20 trials converged to these (value, +- spread).
PAPER_OMEGA = [(4.31, 0.01), (8.68, 0.02)]
PAPER_ALPHA = [(0.049, 0.007), (0.143, 0.008)]
# The paper's Table I, seconds per sample on a 1 GHz Pentium III (None: not given).
PAPER_TABLE = {
    10: [0.030, 0.038, 0.18, 1.4],
    20: [0.22, 0.24, 0.65, 4.4],
    30: [0.87, 0.89, 1.7, 9.1],
    40: [2.1, 2.2, 3.5, None],
    50: [4.6, 4.8, 6.6, None],
}
GRID_N = [100, 1000, 10000, 100000]


def register(sub):
    _register_modal(sub)
    _register_timing(sub)


def _register_modal(sub):
    p = sub.add_parser(
        "modal",
        help="modal estimator: plate simulation or quadruple-pendulum experiment analogue",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops modal")
    periods = number(float, 0.0, 1000.0, lo_open=True)
    p.add_argument(
        "--scenario",
        choices=["structure", "pendulum"],
        required=True,
        help="structure: the vibrating plate seen in range images; pendulum: the quadruple pendulum",
    )
    p.add_argument(
        "--modes",
        type=number(int, 1, 50),
        default=None,
        help="modes estimated (structure: 1 to 50, default 10; pendulum: 3, the default)",
    )
    p.add_argument("--trials", type=number(int, 1, 1000), default=1, help="trials (1 to 1000, default 1)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the first trial (trial k: seed + k), any integer >= 0")
    p.add_argument(
        "--filter",
        choices=["bank", "joint"],
        default="bank",
        help="bank: one filter per mode (the default); joint: one filter over all modes",
    )
    p.add_argument(
        "--images",
        type=number(int, 2, 100000),
        default=None,
        help="images per trial, 2 to 100000 (default: structure 180, pendulum 150)",
    )
    p.add_argument(
        "--dt",
        type=number(float, 0.0, 1e5, lo_open=True),
        default=None,
        help="image interval [s], > 0 and <= 1e5 (default: structure 60, pendulum 1/15)",
    )
    _add_structure_options(p, periods)
    p.add_argument("--json", default=None, help="write the results here (JSON)")
    p.add_argument("--plots", default=None, help="folder for the figures")
    add_campaign_arguments(p)
    p.set_defaults(func=main)


def _add_structure_options(p, periods):
    """The options that apply to the plate (structure) scenario only."""
    p.add_argument(
        "--range-noise",
        type=number(float, 0.0, 1.0, lo_open=True, hi_open=True),
        default=0.03,
        metavar="FRAC",
        help="structure: range noise as a fraction of the range, in (0, 1) (default 0.03, the published experiment's)",
    )
    p.add_argument(
        "--batch-ml-at",
        type=periods,
        nargs="+",
        default=(),
        metavar="PERIODS",
        help="structure: also fit the batch maximum-likelihood reference to every coarse estimate up to "
        "these times [lowest-mode periods] and compare its shape error with the filter's",
    )
    p.add_argument(
        "--crb-at",
        type=periods,
        nargs="+",
        default=(),
        metavar="PERIODS",
        help="structure: also compute the Cramer-Rao bounds of each run's coarse estimates at these times "
        "[lowest-mode periods] and set the filter's frequency and shape errors beside them",
    )
    p.add_argument(
        "--acquire-at",
        type=periods,
        default=None,
        metavar="PERIODS",
        help="structure: also acquire the frequencies at this time [lowest-mode periods] by a search over "
        "every image so far, replay a new flight joint filter from them and run it on; scored at "
        "--crb-at",
    )
    p.add_argument(
        "--acquire-with",
        choices=["flight", "batch-ml"],
        default="flight",
        help="structure: the search for --acquire-at: the flight ModalAcquisition (default) or the "
        "bench's batch ML fit",
    )
    p.add_argument(
        "--acquire-grid-sigmas",
        type=number(float, 0.0, 100.0, lo_open=True),
        default=3.0,
        metavar="K",
        help="structure: the flight search's frequency grid spans +-K a priori sigmas (default 3; the "
        "a priori sigma is 10 %% of each frequency)",
    )
    p.add_argument(
        "--points-at",
        choices=["measured", "footprint"],
        default="measured",
        help="structure: evaluate the mode shapes at the measured point (default, as published) or where "
        "the ray meets the undeformed plane",
    )
    p.add_argument(
        "--coarse-check",
        action="store_true",
        help="structure: also check every image's coarse amplitudes against the truth with their "
        "covariance (NEES, per-mode bias)",
    )
    p.add_argument(
        "--ut-alpha",
        type=number(float, 0.0, 10.0, lo_open=True),
        default=1.0,
        help="structure: unscented-transform spread alpha of the filters (default 1: sigma points at "
        "sqrt(n) standard deviations)",
    )


def _register_timing(sub):
    t = sub.add_parser(
        "modal-timing",
        help="timing grid of the modal estimator: flight code vs numpy vs the published figures",
        formatter_class=HelpFormatter,
    )
    one_line_errors(t, "proxops modal-timing")
    t.add_argument(
        "--bench-exe",
        action="append",
        default=[],
        metavar="[LABEL=]PATH",
        help="bench_modal executable (Google Benchmark) for the full flight grid; repeat with labels "
        "(e.g. portable=build/bench-rel/bench_modal v3=build/bench-v3/bench_modal) to set builds "
        "side by side in one run",
    )
    t.add_argument("--max-points", type=number(int, 1, 10**7), default=100000, help="1 to 1e7 (default 100000)")
    t.add_argument("--repeats", type=number(int, 1, 1000), default=5, help="1 to 1000 (default 5)")
    t.add_argument("--json", default=None, help="write the timing grid here (JSON)")
    t.set_defaults(func=timing_main)


def _summary(vals):
    v = np.asarray(vals, float)
    return {
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "half_range": float((v.max() - v.min()) / 2),
        "min": float(v.min()),
        "max": float(v.max()),
    }


def _run_trials(args, spec: dict) -> list:
    """Trials seed, seed + 1, ... as a campaign (bench/runner): each a Dask
    task kept in the results store; the first keeps its series for --plots."""
    from bench.campaigns import modal_campaign as mc
    from bench.runner.runner import all_failed, failures, missing, results

    campaign = campaign_from(args, f"modal-{spec['scenario']}", {"seed": args.seed, **spec})
    items = [{"seed": args.seed + k, "keep_series": bool(k == 0 and args.plots)} for k in range(args.trials)]
    recs = campaign.map("trial", mc.run_trial, items, shared=spec, label=f"modal {spec['scenario']}")
    all_failed(recs)
    for f in failures(recs):
        print(f"trial {f['run']} (seed {f['seed']}) failed: {f['error']}")
    if missing(recs):
        print(f"{len(missing(recs))} of {len(recs)} trials not stored: left out")
    trials = [r for r in results(recs) if r is not None]
    if not trials:
        raise ValueError("no finished trials")
    return trials


def main(args):
    if args.modes is None:
        args.modes = 3 if args.scenario == "pendulum" else 10
    out = _pendulum(args) if args.scenario == "pendulum" else _structure(args)
    if args.json:
        write_json(args.json, out, strict=True)
    return 0


def _pendulum(args) -> dict:
    """The quadruple-pendulum experiment analogue: the first two modes'
    frequencies and damping against the published ones."""
    if args.modes != 3:
        raise ValueError("the pendulum scenario estimates 3 modes (--modes 3)")
    dur = (args.images or 150) * (args.dt or 1 / 15)
    trials = _run_trials(
        args,
        {
            "scenario": "pendulum",
            "kwargs": {"kind": args.filter, "duration_s": dur, "rate_hz": 1 / (args.dt or 1 / 15)},
        },
    )
    out = {
        "scenario": "pendulum",
        "filter": args.filter,
        "trials": [],
        "paper": {"omega_radps": PAPER_OMEGA, "alpha_ps": PAPER_ALPHA, "measurements_to_converge_max": 90},
    }
    for tr in trials:
        out["trials"].append({k: v for k, v in tr.items() if k not in ("t_s", "est", "coarse", "truth")})
    for i in range(2):
        out[f"omega{i + 1}"] = _summary([t["omega_final_radps"][i] for t in trials])
        out[f"alpha{i + 1}"] = _summary([t["alpha_final_ps"][i] for t in trials])
    nc = [t["measurements_to_converge"] for t in trials]
    out["measurements_to_converge_max"] = None if any(v is None for v in nc) else int(max(nc))
    for i in range(2):
        w, a = out[f"omega{i + 1}"], out[f"alpha{i + 1}"]
        print(
            f"mode {i + 1}: omega {w['mean']:.4f} +- {w['std']:.4f} (half-range {w['half_range']:.4f}) rad/s "
            f"[paper {PAPER_OMEGA[i][0]} +- {PAPER_OMEGA[i][1]}];  alpha {a['mean']:.4f} +- {a['std']:.4f} "
            f"(half-range {a['half_range']:.4f}) 1/s [paper {PAPER_ALPHA[i][0]} +- {PAPER_ALPHA[i][1]}]"
        )
    print(f"measurements to converge (max over trials): {out['measurements_to_converge_max']} (paper < 90)")
    if args.plots:
        _plot_pendulum(trials[0], report_dir(args.plots))
    return out


def _structure(args) -> dict:
    """The plate simulation: convergence of frequencies and shapes per trial,
    with the optional references (batch ML, Cramer-Rao bounds, acquisition)."""
    from bench.campaigns import modal_campaign as mc

    if not 0.0 < args.range_noise < 1.0:
        raise ValueError(f"--range-noise must be a fraction of the range in (0, 1), got {args.range_noise}")
    n_img = args.images or 180
    trials = _run_trials(
        args,
        {
            "scenario": "structure",
            "kwargs": dict(
                n_modes=args.modes,
                kind=args.filter,
                n_images=n_img,
                dt_s=args.dt or 60.0,
                noise_frac=args.range_noise,
                batch_ml_periods=tuple(args.batch_ml_at),
                crb_periods=tuple(args.crb_at),
                acquire_periods=args.acquire_at,
                acquire_with=args.acquire_with,
                acquire_grid_sigmas=args.acquire_grid_sigmas,
                ut_alpha=args.ut_alpha,
                points_at=args.points_at,
                coarse_check=args.coarse_check,
            ),
        },
    )
    out = {
        "scenario": "structure",
        "filter": args.filter,
        "modes": args.modes,
        "range_noise": args.range_noise,
        "points_at": args.points_at,
        "trials": [],
    }
    for tr in trials:
        out["trials"].append({k: v for k, v in tr.items() if k not in ("t_s", "est", "coarse", "truth")})
        n1, p1 = tr["measurements_to_converge_1pct"], tr["time_to_converge_1pct_periods"]
        px, ps = tr["time_to_converge_1pct_excited_periods"], tr["shape_converge_periods"]
        print(
            f"seed {tr['seed']}: all frequencies within 1 % "
            f"{'never' if n1 is None else f'after {n1} images ({_fmt(p1)} lowest-mode periods)'}; "
            f"those of the modes excited >= 0.2 {'never' if px is None else f'after {_fmt(px)} periods'}; "
            f"final max relative error {tr['freq_rel_err_final_max']:.2e}; shape RMS at its floor "
            f"({tr['shape_noise_floor_m']:.2f} m) {'never' if ps is None else f'after {_fmt(ps)} periods'}; "
            f"median cond(M_Y) {tr['condition_number_median']:.1f}"
        )
    if args.batch_ml_at:
        out["batch_ml_summary"] = _batch_ml_summary(trials)
    if args.crb_at:
        out["crb_summary"] = _crb_summary(trials)
    if args.acquire_at is not None:
        out["acquisition_summary"] = _acquisition_summary(trials)
    if args.coarse_check:
        out["coarse_check_summary"] = _coarse_check_summary(trials, args.modes, args.points_at)
    out["ill_conditioned_cases"] = mc.plate_aliased_case(args.modes)
    print(
        "ill-conditioned cases: "
        + "; ".join(
            f"{name.replace('_', ' ')}: {case['status'].replace('_', ' ')} ({case['n_used']} points used"
            + (f", condition number {case['condition_number']:.3g}" if "condition_number" in case else "")
            + ")"
            for name, case in out["ill_conditioned_cases"].items()
        )
    )
    if args.plots:
        _plot_structure(trials[0], report_dir(args.plots))
    return out


def _batch_ml_summary(trials):
    """Per requested time, medians over trials of the shape error of the filter,
    the batch ML reference and the known-frequency filter, each also over the
    trial's floor; and how many trials are within twice the floor."""
    rows = []
    for j, first in enumerate(trials[0]["batch_ml"]):
        r = {"periods": first["periods"], "images": first["images"], "trials": len(trials)}
        for key, name in (
            ("shape_rms_filter_m", "filter"),
            ("shape_rms_batch_ml_m", "batch_ml"),
            ("shape_rms_known_omega_m", "known_omega"),
        ):
            v = np.array([t["batch_ml"][j][key] for t in trials])
            floor = np.array([t["shape_noise_floor_m"] for t in trials])
            r[f"{name}_median_m"] = float(np.median(v))
            r[f"{name}_over_floor_median"] = float(np.median(v / floor))
            r[f"{name}_within_2x_floor"] = int(np.sum(v <= 2.0 * floor))
        ratio = np.array(
            [t["batch_ml"][j]["shape_rms_filter_m"] / t["batch_ml"][j]["shape_rms_batch_ml_m"] for t in trials]
        )
        r["filter_over_batch_ml_median"] = float(np.median(ratio))
        r["filter_over_batch_ml_quartiles"] = [float(q) for q in np.percentile(ratio, [25, 75])]
        c = [t["batch_ml"][j] for t in trials]
        r["excited_modes"] = int(sum(x["n_excited"] for x in c))
        for name in ("filter", "batch_ml"):
            r[f"{name}_excited_within_1pct"] = int(sum(x[f"excited_within_1pct_{name}"] for x in c))
            r[f"{name}_runs_all_excited_within_1pct"] = int(
                sum(x[f"excited_within_1pct_{name}"] == x["n_excited"] for x in c)
            )
        r["from_truth_excited_within_1pct"] = int(sum(x["from_truth_excited_within_1pct"] for x in c))
        # runs where the optimum reached from the true frequencies is lower (by more than 1e-6
        # relative) than the estimator's: its own starts missed the data's better optimum
        r["runs_better_optimum_near_truth"] = int(
            sum(x["from_truth_cost"] < x["batch_ml_cost"] * (1 - 1e-6) for x in c)
        )
        rows.append(r)
        print(
            f"at {r['periods']:.2f} periods ({r['images']} images), medians over {len(trials)} trials: shape RMS "
            f"filter {r['filter_median_m']:.3f} m ({r['filter_over_floor_median']:.2f} x floor), batch ML "
            f"{r['batch_ml_median_m']:.3f} m ({r['batch_ml_over_floor_median']:.2f} x), known omega "
            f"{r['known_omega_median_m']:.3f} m ({r['known_omega_over_floor_median']:.2f} x); filter / batch ML "
            f"{r['filter_over_batch_ml_median']:.2f} [{r['filter_over_batch_ml_quartiles'][0]:.2f}, "
            f"{r['filter_over_batch_ml_quartiles'][1]:.2f}]; within 2x floor: filter {r['filter_within_2x_floor']}, "
            f"batch ML {r['batch_ml_within_2x_floor']}, known omega {r['known_omega_within_2x_floor']}; excited "
            f"modes within 1 %: filter {r['filter_excited_within_1pct']}, batch ML {r['batch_ml_excited_within_1pct']}, "
            f"from the true frequencies {r['from_truth_excited_within_1pct']} of {r['excited_modes']}; runs with a "
            f"lower optimum near the truth than the batch ML found: {r['runs_better_optimum_near_truth']}"
        )
    return rows


def _crb_summary(trials):
    """Per requested time, the filter beside its run's Cramer-Rao bounds:
    excited modes within 1 % (filter's count, the bound's expectation), runs
    with every excited mode within 1 % (filter's count, the bound's expected
    count), and shape RMS medians (filter, bound with frequencies unknown,
    known-frequency filter, bound with frequencies known), each also over the
    run's floor."""
    rows = []
    for j, first in enumerate(trials[0]["crb"]):
        c = [t["crb"][j] for t in trials]
        floor = np.array([t["shape_noise_floor_m"] for t in trials])
        r = {
            "periods": first["periods"],
            "images": first["images"],
            "trials": len(trials),
            "excited_modes": int(sum(x["n_excited"] for x in c)),
            "filter_excited_within_1pct": int(sum(x["filter_excited_within_1pct"] for x in c)),
            "crb_expected_excited_within_1pct": float(sum(x["crb_expected_excited_within_1pct"] for x in c)),
            "filter_runs_all_excited_within_1pct": int(
                sum(x["filter_excited_within_1pct"] == x["n_excited"] for x in c)
            ),
            "crb_expected_runs_all_excited_within_1pct": float(sum(x["crb_p_all_excited_within_1pct"] for x in c)),
        }
        for key, name in (
            ("shape_rms_filter_m", "filter"),
            ("crb_shape_rms_m", "crb"),
            ("shape_rms_known_omega_m", "known_omega"),
            ("crb_shape_rms_known_omega_m", "crb_known"),
        ):
            v = np.array([x[key] for x in c])
            r[f"{name}_median_m"] = float(np.median(v))
            r[f"{name}_over_floor_median"] = float(np.median(v / floor))
            r[f"{name}_within_2x_floor"] = int(np.sum(v <= 2.0 * floor))
        # against the known-frequency filter at the same image: a floor that does not move with the run length
        known = np.array([x["shape_rms_known_omega_m"] for x in c])
        r["filter_within_2x_known_same_image"] = int(
            np.sum(np.array([x["shape_rms_filter_m"] for x in c]) <= 2.0 * known)
        )
        r["crb_within_2x_known_same_image"] = int(np.sum(np.array([x["crb_shape_rms_m"] for x in c]) <= 2.0 * known))
        # efficiency: the filter's mean squared shape error over the bound's (1 for an efficient estimator)
        r["filter_over_crb_rms"] = float(
            np.sqrt(
                np.mean([x["shape_rms_filter_m"] ** 2 for x in c]) / np.mean([x["crb_shape_rms_m"] ** 2 for x in c])
            )
        )
        rows.append(r)
        print(
            f"at {r['periods']:.2f} periods ({r['images']} images), {len(trials)} runs: excited modes within 1 %: "
            f"filter {r['filter_excited_within_1pct']} of {r['excited_modes']}, bound expects "
            f"{r['crb_expected_excited_within_1pct']:.1f}; runs with all within 1 %: filter "
            f"{r['filter_runs_all_excited_within_1pct']}, bound expects "
            f"{r['crb_expected_runs_all_excited_within_1pct']:.1f}; shape RMS medians filter "
            f"{r['filter_median_m']:.3f} m ({r['filter_over_floor_median']:.2f} x floor), bound "
            f"{r['crb_median_m']:.3f} m ({r['crb_over_floor_median']:.2f} x), known omega "
            f"{r['known_omega_median_m']:.3f} m, its bound {r['crb_known_median_m']:.3f} m; within 2x floor: "
            f"filter {r['filter_within_2x_floor']}, bound {r['crb_within_2x_floor']}; within 2x the known-frequency "
            f"filter at that image: filter {r['filter_within_2x_known_same_image']}, bound "
            f"{r['crb_within_2x_known_same_image']}; RMS over runs, filter / bound {r['filter_over_crb_rms']:.2f}"
        )
    return rows


def _acquisition_summary(trials):
    """Acquisition then filter, beside the one-pass filter: excited modes
    within 1 %, runs with all of them, and runs with the shape within 2x the
    noise floor, per scored time."""
    rows = []
    first = trials[0]["acquisition"]
    n_exc = [int(np.sum(np.asarray(t["amp_true"]) >= 0.2)) for t in trials]
    for j, at in enumerate(first["at"]):
        a = [t["acquisition"]["at"][j] for t in trials]
        r = {
            "method": first["method"],
            "periods": at["periods"],
            "images": at["images"],
            "trials": len(trials),
            "acquired_at_periods": first["periods"],
            "excited_modes": int(sum(n_exc)),
            "search_excited_within_1pct": int(sum(t["acquisition"]["search_excited_within_1pct"] for t in trials)),
            "excited_within_1pct": int(sum(x["excited_within_1pct"] for x in a)),
            "runs_all_excited_within_1pct": int(sum(x["excited_within_1pct"] == n for x, n in zip(a, n_exc))),
            "shape_rms_median_m": float(np.median([x["shape_rms_m"] for x in a])),
        }
        if all("shape_noise_floor_m" in t for t in trials):
            ratio = [x["shape_rms_m"] / t["shape_noise_floor_m"] for x, t in zip(a, trials)]
            r["shape_x_floor_median"] = float(np.median(ratio))
            r["runs_shape_within_2x_floor"] = int(sum(v <= 2.0 for v in ratio))
        known = np.array([x["shape_rms_known_omega_m"] for x in a])
        if np.all(np.isfinite(known)):
            r["runs_shape_within_2x_known_same_image"] = int(
                np.sum(np.array([x["shape_rms_m"] for x in a]) <= 2.0 * known)
            )
        if r["method"] == "flight":
            r["search_s_median"] = float(np.median([t["acquisition"]["search_s"] for t in trials]))
            r["replay_s_median"] = float(np.median([t["acquisition"]["replay_s"] for t in trials]))
        rows.append(r)
        print(
            f"acquisition ({r['method']}) at {r['acquired_at_periods']:.2f} periods (search alone: "
            f"{r['search_excited_within_1pct']} of {r['excited_modes']} excited within 1 %), then the flight joint "
            f"filter, at {r['periods']:.2f} periods: excited within 1 % {r['excited_within_1pct']} of "
            f"{r['excited_modes']}, runs with all {r['runs_all_excited_within_1pct']} of {len(trials)}, shape RMS "
            f"median {r['shape_rms_median_m']:.3f} m"
            + (
                f" ({r['shape_x_floor_median']:.2f} x floor), within 2x floor in {r['runs_shape_within_2x_floor']} runs"
                if "runs_shape_within_2x_floor" in r
                else ""
            )
            + (
                f", within 2x the known-frequency filter at that image in {r['runs_shape_within_2x_known_same_image']}"
                if "runs_shape_within_2x_known_same_image" in r
                else ""
            )
        )
    return rows


def _coarse_check_summary(trials, m, points_at):
    """Pooled over every image of every run: NEES mean against M (its
    standard error from the chi-square's 2M variance), and per mode the mean
    error in reported sigmas with its standard error."""
    cc = [t["coarse_check"] for t in trials]
    nees = np.concatenate([np.asarray(c["nees"]) for c in cc])
    n = int(sum(c["images"] for c in cc))
    z_mean = sum(np.asarray(c["z_mean"]) * c["images"] for c in cc) / n
    z_sd = np.sqrt(np.maximum(sum(np.asarray(c["z_sq_sum"]) for c in cc) / n - z_mean**2, 0.0))
    se = z_sd / np.sqrt(n)
    biased = np.nonzero(np.abs(z_mean) > 4 * se)[0]
    worst = int(np.argmax(np.abs(z_mean)))
    r = {
        "points_at": points_at,
        "images": n,
        "nees_mean": float(nees.mean()),
        "nees_expected": m,
        "nees_mean_se": float(np.sqrt(2 * m / n)),
        "bias_sigma": z_mean.tolist(),
        "spread_sigma": z_sd.tolist(),
        "modes_biased_4se": [int(i) + 1 for i in biased],
        "worst_mode": worst + 1,
        "worst_bias_sigma": float(z_mean[worst]),
    }
    print(
        f"coarse amplitudes vs truth (mode shapes at the {points_at} point), {n} images: NEES mean "
        f"{r['nees_mean']:.2f} (expected {m} +- {r['nees_mean_se']:.2f}); modes biased beyond 4 standard errors: "
        f"{len(biased)} of {m}, the largest {r['worst_bias_sigma']:+.2f} sigma (mode {worst + 1})"
    )
    return r


def _fmt(v):
    return "never" if v is None else f"{v:.2f}"


def _plot_pendulum(tr, folder: Path):
    plt = matplotlib_agg()
    t, est, coarse = tr["t_s"], tr["est"], tr["coarse"]
    fig, ax = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for i in range(3):
        ax[i].plot(t, coarse[:, i], "k-", lw=0.8, label="coarse A~ (eq. 3)")
        ax[i].plot(t, est[:, i, 0], color="0.6", lw=2, label="filtered A^")
        ax[i].set_ylabel(f"mode {i + 1} [m]")
    ax[0].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.suptitle("Pendulum: coarse and filtered modal coefficients (cf. seed Fig. 9)")
    fig.savefig(folder / "modal_pendulum_fig9.png", dpi=110)
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for i, (w, a) in enumerate(zip([4.31, 8.68], [0.049, 0.143])):
        ax[0].plot(t, est[:, i, 2])
        ax[0].axhline(w, ls=":", color="k")
        ax[1].plot(t, est[:, i, 3])
        ax[1].axhline(a, ls=":", color="k")
    ax[0].set_ylabel("omega [rad/s]")
    ax[1].set_ylabel("alpha [1/s]")
    ax[1].set_xlabel("time [s]")
    fig.savefig(folder / "modal_pendulum_params.png", dpi=110)
    plt.close("all")


def _plot_structure(tr, folder: Path):
    plt = matplotlib_agg()
    t = tr["t_s"] / 60.0
    est, coarse = tr["est"], tr["coarse"]
    m = est.shape[1]
    show = sorted({0, 1, m // 2, m - 1})
    fig, ax = plt.subplots(len(show), 1, figsize=(8, 2 * len(show)), sharex=True)
    for a, i in zip(ax, show):
        a.plot(t, coarse[:, i], "k-", lw=0.8)
        a.plot(t, est[:, i, 0], color="0.6", lw=2)
        a.set_ylabel(f"A{i + 1}")
    ax[-1].set_xlabel("time [min]")
    fig.suptitle(f"Plate, {m} modes: coarse (black) and filtered (grey) coefficients (cf. seed Fig. 4)")
    fig.savefig(folder / f"modal_structure{m}_fig4.png", dpi=110)
    fig, a = plt.subplots(figsize=(8, 4))
    a.plot(t, est[:, :, 2] / np.asarray(tr["omega_true_radps"])[None, :], lw=0.8)
    a.axhline(1.0, ls=":", color="k")
    a.set_ylim(0.8, 1.2)
    a.set_xlabel("time [min]")
    a.set_ylabel("omega^ / omega")
    a.set_title(f"Frequency estimates, {m} modes (cf. seed Fig. 5)")
    fig.savefig(folder / f"modal_structure{m}_fig5.png", dpi=110)
    fig, a = plt.subplots(figsize=(8, 4))
    a.semilogy(np.arange(len(t)), tr["shape_rms_m"], label="estimator")
    a.semilogy(np.arange(len(t)), tr["shape_rms_oracle_m"], label="known omega (floor)")
    a.semilogy(np.arange(len(t)), tr["shape_sigma_m"], ls="--", label="eq. 9 1-sigma (RMS)")
    a.set_xlabel("measurement")
    a.set_ylabel("shape RMS error [m]")
    a.legend()
    a.set_title(f"Shape error over the whole plate, {m} modes (cf. seed Fig. 6)")
    fig.savefig(folder / f"modal_structure{m}_fig6.png", dpi=110)
    plt.close("all")


# ---------------------------------------------------------------------------
# Timing


def _flight_bindings(m, n, kind, repeats):
    """Seconds per image through the bindings (decompose + step), M in MODAL_SIZES."""
    import fsw_bindings as fb

    rng = np.random.default_rng(1)
    x, y = rng.uniform(size=n), rng.uniform(size=n)
    p = 1 + np.arange(m) % 7
    q = 1 + np.arange(m) // 7
    phi = np.ascontiguousarray(np.sin(p * np.pi * x[:, None]) * np.sin(q * np.pi * y[:, None]))
    z = phi @ (0.1 * np.cos(np.arange(m))) + 0.01 * rng.standard_normal(n)
    from bench.campaigns.modal_campaign import make_filter

    w = 0.01 * (1 + np.arange(m))
    f = make_filter(kind, m, w, np.zeros(m), w, 0.1 * w, 1e-5, 1e-8, 1e-10)
    dec = getattr(fb, f"ModalDecomposition{m}")(sigma_e_m=0.01)
    f.step(60.0, dec.decompose(phi, z))
    times = []
    for _ in range(repeats):
        k, t0 = 0, time.perf_counter()
        while True:
            f.step(60.0, dec.decompose(phi, z))
            k += 1
            if time.perf_counter() - t0 >= 0.05:
                break
        times.append((time.perf_counter() - t0) / k)
    return float(np.median(times))


# Only the grid benchmarks (the per-point and frozen-base references are not part of Table I).
GRID_FILTER = "^BM_(Decomposition|Decoupled|Joint)<[0-9]+>/[0-9]+$"


def _run_bench_exe(exe):
    out = subprocess.run(
        [
            exe,
            "--benchmark_repetitions=9",
            "--benchmark_report_aggregates_only=true",
            f"--benchmark_filter={GRID_FILTER}",
            "--benchmark_format=json",
        ],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    res = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") != "median":
            continue
        name = b["run_name"]  # BM_Joint<10>/1000
        kind, rest = name.split("<", 1)
        m = int(rest.split(">")[0])
        n = int(name.split("/")[-1])
        scale = {"us": 1e-6, "ms": 1e-3, "ns": 1e-9, "s": 1.0}[b["time_unit"]]
        res[(kind.replace("BM_", "").lower(), m, n)] = b["real_time"] * scale
    return res


def _labelled_exes(specs):
    """[LABEL=]PATH -> {label: path}; one unlabelled exe is "flight"."""
    out = {}
    for spec in specs:
        label, sep, path = spec.partition("=")
        if not sep:
            label, path = "flight", spec
        if not label.isidentifier():
            raise SystemExit(f"--bench-exe {spec!r}: the label must be a word (letters, digits, _)")
        if label in out:
            raise SystemExit(f"--bench-exe: label {label!r} given twice")
        if not Path(path).is_file():
            raise SystemExit(f"--bench-exe {spec!r}: no such file {path}")
        out[label] = path
    return out


def _fit(cells):
    """Least-squares c1, c2 of t = c1 m n + c2 m^3 over (m, n, t) cells."""
    a = np.array([[m * n, m**3] for m, n, _ in cells], float)
    t = np.array([c[2] for c in cells], float)
    w = 1.0 / t  # relative residuals
    c, *_ = np.linalg.lstsq(a * w[:, None], t * w, rcond=None)
    return float(c[0]), float(c[1])


def timing_main(args):
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from bench.perf import modal_numpy as mn

    ns = [n for n in GRID_N if n <= args.max_points]
    exes = _labelled_exes(args.bench_exe)
    flight = {}
    for label, exe in exes.items():
        print(f"flight grid, {label}: {exe} (9 repetitions per cell)", flush=True)
        flight[label] = _run_bench_exe(exe)
    labels = list(exes) or ["flight"]
    rows = []
    for m in sorted(PAPER_TABLE):
        for j, n in enumerate(ns):
            row = {"modes": m, "points": n, "paper_s": PAPER_TABLE[m][j]}
            for kind in ("bank", "joint"):
                row[f"numpy_{kind}_s"] = mn.time_cell(m, n, kind, repeats=args.repeats)
                key = ("decoupled" if kind == "bank" else "joint", m, n)
                for label in exes:
                    if key in flight[label]:
                        row[f"{label}_{kind}_s"] = flight[label][key]
                if not exes and m in (10, 50):
                    row[f"flight_{kind}_bindings_s"] = _flight_bindings(m, n, kind, args.repeats)
            for label in exes:
                if ("decomposition", m, n) in flight[label]:
                    row[f"{label}_decomposition_s"] = flight[label][("decomposition", m, n)]
            rows.append(row)
            cols = "".join(
                f"  {label} bank {_s(_cell(row, label, 'bank'))} joint {_s(_cell(row, label, 'joint'))}"
                for label in labels
            )
            print(
                f"m={m:2d} n={n:6d}  paper {_s(row['paper_s'])}  numpy bank {_s(row['numpy_bank_s'])} "
                f"joint {_s(row['numpy_joint_s'])}{cols}",
                flush=True,
            )
    out = {"rows": rows, "builds": exes, "paper_fit": {"c1": 1.4e-6, "c2": 3.6e-5}}
    for kind in ("bank", "joint"):
        for src in ["numpy"] + labels:
            cells = [(r["modes"], r["points"], _cell(r, src, kind)) for r in rows]
            cells = [c for c in cells if c[2] is not None]
            if len(cells) >= 2:
                out[f"fit_{src}_{kind}"] = dict(zip(("c1", "c2"), _fit(cells)))
                print(
                    f"fit {src} {kind}: c1 = {out[f'fit_{src}_{kind}']['c1']:.3e} s, "
                    f"c2 = {out[f'fit_{src}_{kind}']['c2']:.3e} s"
                )
    if args.json:
        write_json(args.json, out, strict=True)
    return 0


def _cell(row, src, kind):
    return row.get(f"{src}_{kind}_s", row.get(f"{src}_{kind}_bindings_s"))


def _s(v):
    if v is None:
        return "     -    "
    return f"{v * 1e3:9.3f}ms" if v >= 1e-3 else f"{v * 1e6:9.1f}us"
