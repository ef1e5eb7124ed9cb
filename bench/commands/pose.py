"""`proxops pose`: the LED pose pipeline's accuracy campaign on rendered
images (bench/campaigns/pose_campaign.py, docs/VISION.md), and the dual-quaternion paper's feature
comparison (points, lines, circles, all; EKF and UKF) on the flight feature
filters (bench/campaigns/feature_pose.py, docs/FEATURES.md)."""

from __future__ import annotations

import time

from bench.commands.args import SEED_HELP, HelpFormatter, number, one_line_errors, seed
from bench.report import write_json


def register(sub):
    p = sub.add_parser(
        "pose",
        help="pose from images (LED campaign) or from image features (points, lines, circles)",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops pose")
    p.add_argument(
        "--experiment",
        choices=["images", "features"],
        required=True,
        help="images: LED pose from rendered images; features: relative pose from points, lines, circles",
    )
    p.add_argument("--seed", type=seed, default=0, help=SEED_HELP)
    p.add_argument(
        "--runs",
        type=number(int, 1, 100000),
        default=200,
        help="random poses (each rendered under every condition; 1 to 100000)",
    )
    p.add_argument(
        "--distortion-runs",
        type=number(int, 1, 100000),
        default=60,
        help="poses per k1 value in the distortion experiment (1 to 100000)",
    )
    p.add_argument(
        "--duration",
        type=number(float, 10.0, 86400.0),
        default=300.0,
        help="features: seconds of flight per run (1 s sampling; 10 to 86400, the last third scored as steady state)",
    )
    p.add_argument(
        "--feature-runs", type=number(int, 1, 1000), default=3, help="features: noise realisations per case (1 to 1000)"
    )
    p.add_argument("--json", default=None, help="write the results here (JSON)")
    p.add_argument("--plots", default=None, help="folder for the figures")
    p.set_defaults(func=main)


def _print(result):
    print(
        f"pose images: seed {result['seed']}, {result['images']['runs']} poses, 0.3-5 m, "
        "centroid sigma per blob from the calibrated centroid error model"
    )
    print(
        f"{'condition':<9} {'ok':>4} {'fail%':>6} {'pos med [mm]':>12} {'pos p95':>8} {'att med [deg]':>13} "
        f"{'NEES mean':>9} {'band95':>13} {'gross':>5}  failures"
    )
    for name, s in result["images"]["summary"].items():
        if s["ok"]:
            band = "{:.2f}-{:.2f}".format(*s["nees_mean_band95"])
            print(
                f"{name:<9} {s['ok']:>4} {100 * s['failure_rate']:>6.1f} {1e3 * s['pos_err_m']['median']:>12.2f} "
                f"{1e3 * s['pos_err_m']['p95']:>8.1f} {s['att_err_deg']['median']:>13.3f} "
                f"{s['nees_mean_without_gross']:>9.2f} {band:>13} {s['gross_errors']:>5}  {s['failures_by_reason']}"
            )
        else:
            print(f"{name:<9} {0:>4} {100 * s['failure_rate']:>6.1f}  {s['failures_by_reason']}")
    print("Ok poses by range [m] (mean NEES without gross errors):")
    for name, s in result["images"]["summary"].items():
        cells = [
            f"{r['range_m'][0]:g}-{r['range_m'][1]:g} {r['ok']}/{r['cases']}"
            + (f" ({r['nees_mean_without_gross']:.2f})" if r["nees_mean_without_gross"] is not None else "")
            for r in s["by_range"]
        ]
        print(f"  {name:<9} " + ", ".join(cells))
    if "distortion" in result:
        print("unmodelled distortion: k1, median position error measured / predicted [mm], slope, corr")
        for r in result["distortion"]["rows"]:
            if "pos_err_m_median" not in r:
                continue
            extra = ""
            if "pos_slope_measured_on_predicted" in r:
                extra = f"  slope {r['pos_slope_measured_on_predicted']:.2f}  corr {r['pos_correlation']:.3f}"
            print(
                f"  k1 {r['k1']:+.2f}: {1e3 * r['pos_err_m_median']:8.2f} / {1e3 * r['pos_pred_m_median']:8.2f}"
                f"{extra}  (ok {r['ok']}, failed {r['failures']})"
            )


def _fmt(v, spec):
    return "   -" if v is None else format(v, spec)


def _print_features(result):
    print(
        f"pose features: seed {result['seed']}, {result['runs']} runs x {result['duration_s']:.0f} s, 1 s sampling; "
        f"steady state = last third; converged = pos < {result['scenario']['convergence']['pos_m']} m and "
        f"att < {result['scenario']['convergence']['att_deg']} deg to the end"
    )
    print(
        f"{'case':<22} {'pos [m]':>9} {'att [deg]':>10} {'conv [s]':>9} {'conv runs':>9} {'NEES6':>8} "
        f"{'NIS/rows':>11}  failures"
    )
    for name, s in result["cases"].items():
        nis = "   -" if s["nis_mean"] is None else f"{s['nis_mean']:.1f}/{s['nis_dof']}"
        print(
            f"{name:<22} {s['steady_pos_err_m']:>9.4f} {s['steady_att_err_deg']:>10.4f} "
            f"{_fmt(s['convergence_time_s'], '9.0f'):>9} {s['converged_runs']:>4}/{s['runs']:<4} "
            f"{s['nees_pose_mean']:>8.1f} {nis:>11}  {s['failures_by_reason'] or ''}"
        )


def _main_features(args):
    from bench.campaigns import feature_pose as fp

    t0 = time.perf_counter()
    result = fp.comparison(args.seed, duration_s=args.duration, runs=args.feature_runs)
    result["experiment"] = "features"
    result["wall_s"] = time.perf_counter() - t0
    _print_features(result)
    if args.plots:
        result["plots"] = fp.plots(result, args.plots)
    if args.json:
        write_json(args.json, {k: v for k, v in result.items() if not k.startswith("_")}, strict=True)
    return 0


def main(args):
    if args.experiment == "features":
        return _main_features(args)
    from bench.campaigns import pose_campaign as pc

    if args.runs < 1:
        raise ValueError("--runs must be >= 1")
    t0 = time.perf_counter()
    result = {"experiment": "images", "seed": args.seed, "images": pc.image_campaign(args.seed, args.runs)}
    if args.distortion_runs > 0:
        result["distortion"] = pc.distortion_experiment(args.seed, args.distortion_runs)
    result["wall_s"] = time.perf_counter() - t0
    _print(result)
    if args.plots:
        result["plots"] = pc.plots(result, args.plots)
    if args.json:
        write_json(args.json, result, strict=True)
    return 0
