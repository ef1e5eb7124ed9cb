"""`proxops nav`: seeded Monte Carlo of the docking scenario with the flight
navigation filter; summary table, JSON metrics and the paper's Figs. 3-6."""

from __future__ import annotations

import sys

import numpy as np

from bench.campaigns.nav_campaign import run_campaign
from bench.commands.args import HelpFormatter, number, one_line_errors, seed
from bench.commands.campaign_args import add_campaign_arguments, campaign_from
from bench.report import matplotlib_agg, report_dir, write_json
from bench.sim.scenario_docking import ScenarioConfig, errors_from_first_update
from bench.sim.sensors import NoiseProfile


def register(sub):
    p = sub.add_parser(
        "nav",
        help="navigation Monte Carlo over the docking scenario",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops nav")
    p.add_argument("--runs", type=number(int, 1, 10000), default=50, help="number of docking runs (1 to 10000)")
    p.add_argument("--seed", type=seed, default=1, help="campaign seed, any integer >= 0 (run i uses seed*1000 + i)")
    p.add_argument("--json", default=None, help="write the metrics here")
    p.add_argument("--plots", default=None, help="folder for the figures")
    p.add_argument("--dynamics", choices=("nonlinear", "cw"), default="nonlinear", help="truth translation model")
    p.add_argument("--profile", choices=("paper", "biased"), default="paper", help="sensor noise profile")
    p.add_argument(
        "--pose-latency-s", type=number(float, 0.0, 10.0), default=0.0, help="delivery delay of each pose [s] (0 to 10)"
    )
    p.add_argument(
        "--pose-r-from",
        choices=("estimate", "measurement"),
        default="estimate",
        help="range the pose covariance handed to the filter is built from",
    )
    p.add_argument("--init", choices=("pose", "truth_draw"), default="pose", help="filter initialisation")
    p.add_argument(
        "--accel-source",
        choices=("imu", "blr"),
        default="imu",
        help="specific force for predict during firings: accelerometer, or the online BLR's prediction",
    )
    p.add_argument(
        "--pose-source",
        choices=("synthetic", "images"),
        default="synthetic",
        help="1 Hz pose: synthetic (5 %% of range) or rendered images through the flight vision pipeline",
    )
    p.add_argument(
        "--pcrb",
        default=None,
        metavar="DIR",
        help="also the posterior Cramer-Rao bound over the same runs, and the errors of the flight UKF (double "
        "and float), FilterPy's UKF and an EKF against it: nav_pcrb.json and plots in DIR (docs/perf/nav.md)",
    )
    p.add_argument(
        "--pcrb-t-conv",
        type=number(float, 0.0, 200.0),
        default=20.0,
        help="start of the window of the figures of merit (after convergence) [s]",
    )
    add_campaign_arguments(p)
    p.set_defaults(func=main)


def _yes_no(b) -> str:
    return "yes" if b else "NO"


def _summary_rows(s: dict) -> list:
    """(metric, value, required, pass) for each of the campaign's checks."""
    c = s["checks"]
    return [
        ("max position error p95 [m]", s["max_pos_err_m"]["p95"], "<= 0.10", _yes_no(c["pos_p95_le_0.10"])),
        ("max position error median [m]", s["max_pos_err_m"]["median"], "<= 0.05", _yes_no(c["pos_median_le_0.05"])),
        ("max velocity error p95 [m/s]", s["max_vel_err_mps"]["p95"], "<= 0.03", _yes_no(c["vel_p95_le_0.03"])),
        (
            "max velocity error median [m/s]",
            s["max_vel_err_mps"]["median"],
            "<= 0.015",
            _yes_no(c["vel_median_le_0.015"]),
        ),
        (
            "NEES mean (9 dof), N-run band",
            s["nees_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nees_band"]),
            _yes_no(c["nees_in_band"]),
        ),
        (
            "NIS mean (6 dof), N-run band",
            s["nis_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nis_band"]),
            _yes_no(c["nis_in_band"]),
        ),
        (
            "NEES mean, per-sample band",
            s["nees_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nees_band_per_sample"]),
            _yes_no(c["nees_in_per_sample_band"]) + " (samples correlated)",
        ),
        (
            "NIS mean, per-sample band",
            s["nis_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nis_band_per_sample"]),
            _yes_no(c["nis_in_per_sample_band"]),
        ),
        (
            "NEES mean after updates (1 Hz)",
            s["nees_post_update_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nees_post_update_band"]),
            "",
        ),
        (
            "NEES mean every 10 s",
            s["nees_thinned_mean"],
            "[{:.3f}, {:.3f}]".format(*s["nees_thinned_band"]),
            _yes_no(s["nees_thinned_band"][0] <= s["nees_thinned_mean"] <= s["nees_thinned_band"][1]),
        ),
        (
            "NEES N-run average: epochs in band",
            s["nees_ensemble"]["in_band_fraction"],
            "about 0.95 (1 Hz)",
            _yes_no(c["nees_ensemble_in_band_ge_0.95"]),
        ),
        (
            "NIS N-run average: epochs in band",
            s["nis_ensemble"]["in_band_fraction"],
            "about 0.95 (1 Hz)",
            _yes_no(c["nis_ensemble_in_band_ge_0.95"]),
        ),
    ]


def print_summary(s: dict) -> None:
    """The campaign's checks as a table, then its diagnostics."""
    rows = _summary_rows(s)
    print(f"\n{s['runs']} runs, seed {s['seed']}, {s['dynamics']} truth, docked {s['docked']}/{s['runs']}")
    print(f"{'metric':34s} {'value':>10s}  {'required':>18s}  pass")
    for name, v, req, p in rows:
        print(f"{name:34s} {v:10.4f}  {req:>18s}  {p}")
    if s["nees_mean_std_error"] is not None:
        print(f"NEES mean standard error from the per-run means: {s['nees_mean_std_error']:.3f}")
    nb, ib = s["nees_block_means"], s["nis_block_means"]
    print(
        f"NEES blocks (3 dof each): pos {nb['pos']:.3f} vel {nb['vel']:.3f} att {nb['att']:.3f}; "
        f"NIS blocks: pos {ib['pos']:.3f} att {ib['att']:.3f}"
    )
    for name in ("nees", "nis"):
        e = s[f"{name}_ensemble"]
        if e["epochs"]:
            print(
                f"{name.upper()} N-run average over {e['epochs']} epochs ({e['runs_per_epoch_min']}-"
                f"{e['runs_per_epoch_max']} runs each): mean {e['mean_of_epoch_means']:.3f}, "
                f"{e['below_band']} below and {e['above_band']} above the band"
            )
    print(f"gated {s['gated_count']}, statuses " + ", ".join(f"{k} {v}" for k, v in s["status_counts"].items()))
    if "vision_status_counts" in s:
        print(
            f"vision: {s['vision_frames']} frames, statuses {s['vision_status_counts']}, "
            f"{s['fused_pose_count']} poses fused, {s['runs_started_late']} runs started after t = 0"
        )


# Per state block: its columns of P and its unit.
BLOCKS = (("pos", 0, "m", "position"), ("vel", 3, "m/s", "velocity"), ("att", 6, "rad", "attitude (body frame)"))


def _sigma_plot(plt, runs, path) -> None:
    """The filter's 1-sigma per block (RMS over its three axes), each in its
    own unit, every kept run: no sum of variances of different units."""
    fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    for ax, (_, c0, unit, name) in zip(axes, BLOCKS):
        for r in runs:
            var = np.trace(r.P[:, c0 : c0 + 3, c0 : c0 + 3], axis1=1, axis2=2) / 3.0
            ax.semilogy(r.t, np.sqrt(var), lw=0.7, label=f"seed {r.summary.seed}")
        ax.set_ylabel(f"{name.split()[0]} 1-sigma [{unit}]")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_title(f"UKF uncertainty, RMS over axes, {len(runs)} run(s)")
    axes[0].legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _error_plots(plt, runs, out) -> None:
    """Errors per axis with each run's own 3-sigma bounds, every kept run."""
    errs = [errors_from_first_update(r) for r in runs]
    for key, c0, unit, name in BLOCKS:
        fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
        for j, ax in enumerate(axes):
            for k, (r, e) in enumerate(zip(runs, errs)):
                color = f"C{k % 10}"
                ax.plot(e.t, e.block(key)[:, j], lw=0.8, color=color, label=f"seed {r.summary.seed}")
                sig = 3 * e.sigma[:, c0 + j]
                ax.plot(e.t, sig, "--", lw=0.6, color=color)
                ax.plot(e.t, -sig, "--", lw=0.6, color=color)
            ax.set_ylabel(f"{'xyz'[j]} [{unit}]")
            ax.grid(alpha=0.3)
        axes[0].set_title(f"UKF {name} error, {len(runs)} run(s) (dashed: +/- 3 sigma)")
        axes[0].legend(loc="upper right", fontsize=7)
        axes[-1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(out / f"nav_{key}_err.png", dpi=120)
        plt.close(fig)


def make_plots(runs, summary, folder) -> None:
    plt = matplotlib_agg()
    out = report_dir(folder)
    _sigma_plot(plt, runs, out / "nav_sigma.png")
    _error_plots(plt, runs, out)
    # NIS of the kept runs against the per-sample 95 % band.
    from scipy.stats import chi2

    fig, ax = plt.subplots(figsize=(7, 3.5))
    for r in runs:
        u = r.updates
        ax.plot(u.t_capture, u.nis, ".", ms=3)
    lo, hi = chi2.ppf([0.025, 0.975], 6)
    ax.axhline(lo, color="k", ls="--", lw=0.6)
    ax.axhline(hi, color="k", ls="--", lw=0.6)
    ax.set(
        xlabel="capture time [s]",
        ylabel="NIS (6 dof)",
        title=f"NIS per pose update; campaign mean {summary['nis_mean']:.2f}",
    )
    fig.tight_layout()
    fig.savefig(out / "nav_nis.png", dpi=120)
    plt.close(fig)
    # N-run averages per 1 Hz epoch against their exact 95 % bands.
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for ax, name, dof in ((axes[0], "nees", 9), (axes[1], "nis", 6)):
        e = summary[f"{name}_ensemble"]
        if not e["epochs"]:
            continue
        t = np.array(e["epoch_keys"], float) * (0.1 if name == "nees" else 1.0)
        ax.plot(t, e["epoch_means"], ".-", ms=3, lw=0.6, label=f"{summary['runs']}-run average")
        ax.plot(t, e["band_lo"], "k--", lw=0.6, label="95 % band")
        ax.plot(t, e["band_hi"], "k--", lw=0.6)
        ax.set_ylabel(f"{name.upper()} ({dof} dof)")
        ax.set_title(
            f"{name.upper()}: {100 * e['in_band_fraction']:.1f} % of epochs in band (95 % expected)", fontsize=9
        )
    axes[0].legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(out / "nav_consistency.png", dpi=120)
    plt.close(fig)


def main(args):
    if args.runs < 1:
        raise ValueError("--runs must be at least 1")
    import fsw_bindings

    if not hasattr(fsw_bindings, "NavUkf"):
        raise ValueError(f"{fsw_bindings.__file__} has no NavUkf: rebuild the bindings with bind_nav")
    profile = NoiseProfile.paper() if args.profile == "paper" else NoiseProfile.biased()
    profile = profile.with_(pose_latency_s=args.pose_latency_s)
    cfg = ScenarioConfig(
        profile=profile,
        dynamics=args.dynamics,
        pose_R_from=args.pose_r_from,
        init=args.init,
        accel_source=args.accel_source,
        pose_source=args.pose_source,
    )
    keep = args.runs if args.pcrb else (min(args.runs, 5) if args.plots else 0)
    # Run i depends on the seed and the configuration, not on --runs: a longer campaign reuses a shorter one's runs.
    campaign = campaign_from(args, "nav", {"seed": args.seed, "config": cfg})
    summary, runs = run_campaign(args.runs, args.seed, cfg, keep_runs=keep, campaign=campaign)
    if "store" in summary:
        print(f"results store: {summary['store']}")
    print_summary(summary)
    if summary.get("failed_runs") or summary.get("missing_runs"):
        print(
            f"summary of {summary['runs']} of {summary['runs_requested']} runs: "
            f"{len(summary.get('failed_runs', []))} failed, {len(summary.get('missing_runs', []))} not stored"
        )
        for f in summary.get("failed_runs", [])[:5]:
            print(f"  run {f['run']} (seed {f['seed']}) failed: {f['error']}")
    if args.json:
        write_json(args.json, summary, strict=True)
        print(f"wrote {args.json}")
    if args.plots:
        make_plots(runs[:5], summary, args.plots)
        print(f"plots in {args.plots}")
    if args.pcrb:
        _pcrb(runs, cfg, args)
    sys.stdout.flush()
    return 0


def _pcrb(runs, cfg, args) -> None:
    """The bound and the four filters against it (bench/campaigns/nav_pcrb.py)."""
    from bench.campaigns.nav_pcrb import BLOCKS, FILTERS, compare, plot

    # FilterPy's UKF and the EKF fuse each pose on time; with a latency only the flight filters compare.
    filters = FILTERS if args.pose_latency_s == 0 else ("ukf", "ukf_float")
    out, series = compare(runs, cfg, filters=filters, t_conv_s=args.pcrb_t_conv, seed=args.seed)
    out["campaign_seed"] = args.seed
    print(
        f"\nRMSE / sqrt(PCRB) over {out['window_s'][0]:.0f}-{out['window_s'][1]:.0f} s, {out['runs']} runs "
        f"(95 % bootstrap interval over the runs); sqrt(PCRB) there: "
        + ", ".join(f"{b} {out['bound_sqrt_in_window'][b]:.3g}" for b in BLOCKS)
    )
    print(f"{'filter':14s} " + " ".join(f"{b:>20s}" for b in BLOCKS) + f" {'NEES':>7s}")
    for f, r in out["filters"].items():
        cells = " ".join(f"{r[b]:6.3f} [{r['interval95'][b][0]:.3f}, {r['interval95'][b][1]:.3f}]" for b in BLOCKS)
        print(f"{f:14s} {cells} {r['nees_mean_window']:7.3f}")
    folder = report_dir(args.pcrb)
    write_json(str(folder / "nav_pcrb.json"), out, strict=True)
    paths = plot(series, out, folder)
    print(f"wrote {folder / 'nav_pcrb.json'}, " + ", ".join(paths))
