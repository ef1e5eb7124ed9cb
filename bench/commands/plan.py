"""`proxops plan LOG --separate`: a short open-loop valve plan, for the log's
described vehicle, that tells apart the sets of effects the log could not
(bench/gap/design.py; docs/GAP.md, "Designing the test that separates")."""

from __future__ import annotations

import json
from pathlib import Path

from bench.commands.args import HelpFormatter, number, one_line_errors, seed


def register(sub):
    from bench.gap.design import DEFAULT_MAX_DURATION_S, DEFAULT_MIN_ON_TIME_S, DEFAULT_PASSES

    p = sub.add_parser(
        "plan",
        help="design a short valve plan that separates the sets of effects a log cannot tell apart",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops plan")
    p.add_argument("log", help="flight log (HDF5, format version 1 or 2, docs/FLIGHT_LOG.md)")
    p.add_argument(
        "--separate",
        action="store_true",
        help="design the test that separates the hypotheses (the one plan this command designs)",
    )
    p.add_argument(
        "--diagnosis",
        default=None,
        help="the log's diagnosis JSON (proxops diagnose --json) to take the sets from (default: diagnose the log)",
    )
    p.add_argument("--hypotheses", default=None, help="the sets to separate instead: a,b+c (',' between sets)")
    p.add_argument(
        "--hypothesis", action="append", default=[], help="one set to separate, e.g. thrust_loss+gyro_bias (repeat)"
    )
    p.add_argument(
        "--max-duration-s",
        type=number(float, 0.0, 1e5, lo_open=True),
        default=DEFAULT_MAX_DURATION_S,
        help="longest plan, every run's time from rest to its end summed (> 0 and <= 1e5 s)",
    )
    p.add_argument(
        "--max-delta-v",
        type=number(float, 0.0, 100.0, lo_open=True),
        default=None,
        help="most delta-v the plan's firings may add up to [m/s] (> 0; default: the fixed characterisation's)",
    )
    p.add_argument(
        "--min-on-time-s",
        type=number(float, 0.0, 3.0),
        default=DEFAULT_MIN_ON_TIME_S,
        help="shortest valve opening the plan may command (0 to 3 s; each valve's own is kept too)",
    )
    _add_criterion(p)
    p.add_argument(
        "--as-listed",
        action="store_true",
        help="separate the sets at their listed sizes only, not also a larger set's extra member along each "
        "of its directions at that size",
    )
    p.add_argument(
        "--passes",
        type=number(int, 1, 4),
        default=DEFAULT_PASSES,
        help="fly the designed schedule this many times over (1 to 4): the diagnosis trains on alternate time "
        "blocks and scores on the others, so each firing must fall in both halves",
    )
    p.add_argument(
        "--check", action="store_true", help="fly both plans on the bench's plant with each hypothesis and measure"
    )
    p.add_argument("--seed", type=seed, default=0, help="noise of the --check flights, any integer >= 0")
    p.add_argument("--json", required=True, help="write the plan here (JSON)")
    p.add_argument("--plot", default=None, help="write the figure here (PNG; default: next to --json)")
    p.set_defaults(func=main)


def _add_criterion(p) -> None:
    """The criterion the plan is designed for, and what it reaches."""
    from bench.gap.design import CRITERIA

    p.add_argument(
        "--criterion",
        choices=CRITERIA,
        default=None,
        help="selection: every direction at the level the diagnosis's own test asks of it (a member beside the "
        "others passing the screening threshold over its parameters, a listed look-alike 10.8 away), on the "
        "half of the rows it trains on; pairwise: every direction against one distance (default: selection, "
        "pairwise with --target-delta2)",
    )
    p.add_argument(
        "--reach",
        action="store_true",
        help="design the shortest plan that reaches every test's level (selection criterion) instead of the "
        "largest smallest share of the levels within the limits",
    )
    p.add_argument(
        "--target-delta2",
        type=number(float, 0.0, 1e9, lo_open=True),
        default=None,
        help="pairwise criterion: design the shortest plan whose smallest pair distance reaches this (noise "
        "variances; 10.8 separates 95 %% of the time) instead of the largest distance within the limits",
    )


def main(args):
    from bench.gap.design import plot, separate, shortest_block_s
    from bench.report import write_json
    from bench.sim.flight_log import read_flight_log

    if not args.separate:
        raise ValueError("give --separate: the plan that separates hypotheses is the one this command designs")
    shortest = shortest_block_s(args.min_on_time_s, args.passes)
    if args.max_duration_s < shortest:
        raise ValueError(
            f"--max-duration-s {args.max_duration_s:g}: shorter than the shortest block times --passes ({shortest:g} s)"
        )
    if Path(args.json).is_dir():
        raise ValueError(f"--json {args.json}: is a folder; give a file name")
    if (args.hypotheses or args.hypothesis) and args.diagnosis:
        raise ValueError("give --diagnosis or name the hypotheses, not both")
    criterion = args.criterion or ("pairwise" if args.target_delta2 is not None else "selection")
    if criterion == "selection" and args.target_delta2 is not None:
        raise ValueError("--target-delta2 is the pairwise criterion's distance; with --criterion selection, --reach")
    if criterion == "pairwise" and args.reach:
        raise ValueError("--reach reaches the selection criterion's levels; with --criterion pairwise, --target-delta2")
    diagnosis = None
    if args.diagnosis:
        if not Path(args.diagnosis).is_file():
            raise FileNotFoundError(f"--diagnosis {args.diagnosis}: no such file")
        try:
            diagnosis = json.loads(Path(args.diagnosis).read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"--diagnosis {args.diagnosis}: not a JSON file ({exc})") from None
    res = separate(
        read_flight_log(args.log, relative_time=True),
        diagnosis,
        (args.hypotheses, args.hypothesis),
        args.max_duration_s,
        args.max_delta_v,
        args.min_on_time_s,
        args.target_delta2,
        args.seed if args.check else None,
        worst_case=not args.as_listed,
        passes=args.passes,
        criterion=criterion,
        reach=args.reach,
    )
    res = {"command": _command(args), **res}
    write_json(args.json, res, strict=True)
    fig = args.plot or str(Path(args.json).with_suffix(".png"))
    plot(res, fig)
    _print(res, args.json, fig)
    return 0


def _command(args) -> str:
    """The command that reproduces the plan."""
    parts = ["proxops plan", args.log, "--separate"]
    for opt in ("diagnosis", "hypotheses", "max_duration_s", "max_delta_v", "min_on_time_s", "target_delta2"):
        v = getattr(args, opt)
        if v is not None:
            parts += [f"--{opt.replace('_', '-')}", f"{v:g}" if isinstance(v, float) else str(v)]
    parts += [f"--hypothesis {h}" for h in args.hypothesis]
    if args.criterion:
        parts += ["--criterion", args.criterion]
    if args.reach:
        parts += ["--reach"]
    if args.as_listed:
        parts += ["--as-listed"]
    parts += ["--passes", str(args.passes)]
    if args.check:
        parts += ["--check", "--seed", str(args.seed)]
    return " ".join(parts + ["--json", args.json])


def _print(res: dict, out: str, fig: str) -> None:
    d, f = res["designed"], res["fixed"]
    print(f"hypotheses ({res['hypotheses_from']}): " + "; ".join(" + ".join(h["set"]) for h in res["hypotheses"]))
    print(f"objective: {res['objective']}")
    selection = res.get("criterion") == "selection"
    print(f"{'':46}{'designed':>12}{'fixed':>12}")
    print(f"{'duration [s]':46}{d['duration_s']:12.1f}{f['duration_s']:12.1f}")
    print(f"{'delta-v [m/s]':46}{d['delta_v_mps']:12.4g}{f['delta_v_mps']:12.4g}")
    if selection:
        print(f"{'smallest share of a test level':46}{d['level_min']:12.3g}{f['level_min']:12.3g}")
    flown = res.get("flown") or {}
    for pd, pf in zip(d["pairs"], f["pairs"]):
        label = f"{pd['a']} vs {pd['b']}"
        if selection:
            print(
                f"{label[:46]:46}{pd['delta2_half']:12.4g}{pf['delta2_half']:12.4g}  (on a half, predicted; the "
                f"{pd['test'].split(':')[0]} test asks {pd['required_half']:.3g})"
            )
        else:
            print(f"{label[:46]:46}{pd['delta2']:12.4g}{pf['delta2']:12.4g}  (delta2, predicted)")
    for key in ("designed", "fixed"):
        for fl in flown.get(key, []):
            for p in fl["pairs"]:
                print(f"flown, {key}: {p['a']} vs {p['b']}: delta2 {p['delta2']:.4g}")
    if res.get("target_reached") is False:
        what = "smallest share of a level" if selection else "smallest distance"
        print(f"target not reached within the limits: {what} {d['level_min'] if selection else d['delta2_min']:.4g}")
    if selection:
        print(f"plan: {out}; figure: {fig} (each test's level: 95 % of the time at the screening threshold)")
    else:
        print(f"plan: {out}; figure: {fig} (10.8 separates 95 % of the time)")
