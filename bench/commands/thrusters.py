"""`proxops thrusters`: online thruster learning, BLR (flight code) against
GPR, on the protocol of section 3.4 of "Online Dynamic Modeling and Localization
for Small-Spacecraft Proximity Operations" (Rogers-Marcovitz; bench/campaigns/thrusters.py)."""

from __future__ import annotations

import numpy as np

from bench.campaigns import thrusters as th
from bench.commands.args import HelpFormatter, number, one_line_errors, seed
from bench.commands.campaign_args import add_campaign_arguments, campaign_from
from bench.report import matplotlib_agg, report_dir, write_json

LEARNERS = ("blr", "gpr", "gpr_tuned")
# The paper's section 3.4: BLR window 30 and GPR window 100 (hand-tuned).
PAPER = {"blr": {"corr_linear": 0.959, "corr_angular": 0.925}, "gpr": {"corr_linear": 0.952, "corr_angular": 0.881}}
TITLES = {
    "blr": "BLR, window 30",
    "gpr": "GPR, window 100, hand-tuned",
    "gpr_tuned": "GPR, window 100, marginal-likelihood fit",
    "blr_pairs": "BLR + valve pairs, window 30",
    "blr_w100": "BLR, window 100",
}


def register(sub):
    p = sub.add_parser(
        "thrusters",
        help="online thruster learning: BLR (flight code) against GPR, correlation "
        "of predicted and measured velocity changes",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops thrusters")
    p.add_argument("--seed", type=seed, default=0, help="first seed, any integer >= 0")
    p.add_argument(
        "--seeds",
        type=number(int, 1, 1000),
        default=1,
        help="run seeds S..S+N-1 and report mean and spread (1 to 1000)",
    )
    p.add_argument("--json", default=None, help="write results here")
    p.add_argument("--plots", default=None, help="folder for predicted-vs-measured plots (first seed)")
    p.add_argument(
        "--samples", type=number(int, 50, 100000), default=th.N_SAMPLES, help="samples per run (50 to 100000)"
    )
    p.add_argument(
        "--noise-model",
        choices=("component", "norm"),
        default="component",
        help="measurement noise: a fraction of each component's true value, or of the vector's norm (harsher)",
    )
    p.add_argument(
        "--extra",
        nargs="*",
        default=[],
        choices=("blr_pairs", "blr_w100"),
        help="also run BLR with pairwise valve products and/or BLR with window 100",
    )
    add_campaign_arguments(p)
    p.set_defaults(func=main)


def plot(data, preds, results, folder):
    plt = matplotlib_agg()
    out = report_dir(folder)
    files = []
    for name, pred in preds.items():
        for kind, sl in th.KINDS.items():
            unit = "m/s" if kind == "linear" else "rad/s"
            fig, ax = plt.subplots(figsize=(4.5, 4.5))
            meas, p = data["y_meas"][:, sl], pred[:, sl]
            for a, c in zip(range(3), ("C0", "C1", "C2")):
                ax.scatter(meas[:, a], p[:, a], s=3, alpha=0.4, color=c, label="xyz"[a])
            lim = [min(meas.min(), p.min()), max(meas.max(), p.max())]
            ax.plot(lim, lim, "k-", lw=0.8)
            ax.set_xlabel(f"measured change in {kind} velocity [{unit}]")
            ax.set_ylabel(f"predicted (one step ahead) [{unit}]")
            ax.set_title(f"{TITLES[name]}\ncorrelation {results[name]['corr_' + kind]:.3f}", fontsize=9)
            ax.legend(markerscale=3, fontsize=8)
            fig.tight_layout()
            f = out / f"thrusters_{name}_{kind}.png"
            fig.savefig(f, dpi=110)
            plt.close(fig)
            files.append(str(f))
    return files


def summarise(per_seed, learners):
    summary = {}
    for name in learners:
        s = {}
        for key in ("corr_linear", "corr_angular", "corr_linear_truth", "corr_angular_truth", "step_us_median"):
            v = np.array([r[name][key] for r in per_seed])
            s[key] = {
                "mean": float(v.mean()),
                "std": float(v.std(ddof=1)) if len(v) > 1 else 0.0,
                "min": float(v.min()),
                "max": float(v.max()),
            }
        summary[name] = s
    return summary


def evaluate_seed(item: dict, protocol) -> dict:
    """One seed of the protocol (a campaign task); the data and predictions
    too when they are plotted."""
    cfg, learners = protocol
    res, data, preds = th.evaluate(item["seed"], cfg, learners)
    return {"results": res, "data": data if item["plot"] else None, "preds": preds if item["plot"] else None}


def main(args):
    cfg = th.ProtocolConfig(n_samples=args.samples, noise_model=args.noise_model)
    learners = LEARNERS + tuple(args.extra)
    print(f"{'seed':>5s} " + " ".join(f"{n + ' lin':>14s} {n + ' ang':>14s}" for n in learners))
    # One seed per run of a campaign (bench/runner): a Dask task each, kept in the results store.
    from bench.runner.runner import all_failed, failures, results

    campaign = campaign_from(args, "thrusters", {"seed": args.seed, "config": cfg, "learners": list(learners)})
    items = [
        {"seed": seed, "plot": bool(args.plots) and seed == args.seed}
        for seed in range(args.seed, args.seed + args.seeds)
    ]
    recs = campaign.map("seed", evaluate_seed, items, shared=(cfg, learners), label="thrusters")
    all_failed(recs)
    per_seed = []
    for item, r in zip(items, results(recs)):
        if r is None:
            continue
        res = r["results"]
        per_seed.append(res)
        print(
            f"{item['seed']:5d} "
            + " ".join(f"{res[n]['corr_linear']:14.4f} {res[n]['corr_angular']:14.4f}" for n in learners)
        )
        if item["plot"]:
            res["plots"] = plot(r["data"], r["preds"], res, args.plots)
    for f in failures(recs):
        print(f"seed {f['seed']} failed: {f['error']}")
    out = dict(per_seed[0]) if args.seeds == 1 else {}
    out["protocol"] = {
        "n_samples": cfg.n_samples,
        "dt_s": cfg.dt_s,
        "noise_linear": cfg.noise_linear,
        "noise_angular": cfg.noise_angular,
        "noise_model": cfg.noise_model,
        "blr_window": th.BLR_WINDOW,
        "gpr_window": th.GPR_WINDOW,
        "gpr_hand": th.GPR_HAND,
        "tune_prefix": th.TUNE_PREFIX,
        "correlation": "Pearson, one-step-ahead prediction vs measured change, pooled over all "
        "samples and the 3 axes of a kind",
    }
    out["paper"] = PAPER
    if args.seeds > 1:
        out["seeds"] = list(range(args.seed, args.seed + args.seeds))
        out["per_seed"] = per_seed
        out["summary"] = summarise(per_seed, learners)
        for name in learners:
            out[name] = {k: v["mean"] for k, v in out["summary"][name].items()}
        print("mean +- std (min):")
        for name in learners:
            s = out["summary"][name]
            tgt = PAPER.get(name, {})
            line = (
                f"  {name:10s} linear {s['corr_linear']['mean']:.4f} +- {s['corr_linear']['std']:.4f} "
                f"({s['corr_linear']['min']:.4f})  angular {s['corr_angular']['mean']:.4f} +- "
                f"{s['corr_angular']['std']:.4f} ({s['corr_angular']['min']:.4f})  "
                f"step {s['step_us_median']['mean']:.1f} us"
            )
            if tgt:
                line += f"  paper {tgt['corr_linear']:.3f}/{tgt['corr_angular']:.3f}"
            print(line)
    if args.json:
        write_json(args.json, out, strict=True)
    return 0
