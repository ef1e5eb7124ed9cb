"""`proxops validate-gap --runs N --seed S --json OUT`: blind validation of the
gap diagnoser on drawn null, in-library and out-of-library runs."""

from __future__ import annotations

from bench.commands.args import HelpFormatter, number, one_line_errors, seed
from bench.commands.campaign_args import add_campaign_arguments, campaign_from, report_campaign


def register(sub):
    p = sub.add_parser(
        "validate-gap",
        help="blind validation campaign of the gap diagnoser",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops validate-gap")
    p.add_argument("--runs", type=number(int, 1, 100000), default=40, help="drawn runs (1 to 100000)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the drawn campaign, any integer >= 0")
    p.add_argument("--json", default=None, help="write the scores here (and OUT.prereg.json with the key hashes first)")
    p.add_argument(
        "--duration",
        type=number(float, 10.0, 86400.0),
        default=120.0,
        help="simulated seconds of docking per run (10 to 86400)",
    )
    p.add_argument(
        "--manoeuvres",
        default="docking",
        choices=("docking", "docking+characterisation"),
        help="what each run flies: docking alone, or docking then a thruster characterisation "
        "(each valve alone 3 s, then 20 s without firing)",
    )
    p.add_argument(
        "--vehicle",
        default="3kg",
        choices=("3kg", "12kg", "random"),
        help="3kg: the bench inspector's docking logs; 12kg: the twelve-thruster 6U-class inspector's "
        "characterisation logs with jittered time stamps, pulse-width-modulated valves and pose on "
        "its own clock; random: a vehicle drawn for every run (2-50 kg, 6-16 valves, IMU turned and "
        "off the centre of mass, Unix-epoch clocks), each log thresholded by a calibration made for it "
        "(--duration and --manoeuvres do not apply)",
    )
    p.add_argument(
        "--engine",
        default="bench",
        choices=("bench", "basilisk"),
        help="basilisk: the 12 kg campaign (or with --vehicle random, the random vehicles') with every "
        "scored log flown by Basilisk (needs pip install '.[basilisk]'; docs/BASILISK.md)",
    )
    p.add_argument(
        "--mixtures",
        action="store_true",
        help="runs with two or three effects at once (in-library pairs and triples, in-library plus "
        "out-of-library), each at 1x or 2x its own minimum detectable size (the logs fly --manoeuvres)",
    )
    p.add_argument(
        "--plans",
        action="store_true",
        help="designed plans, checked: mixture runs at 2x on docking logs whose answer is ambiguous get the "
        "plan designed from it, flown after the docking log with the true effects and without, and "
        "diagnosed again (bench/campaigns/gap/validate_plans.py)",
    )
    p.add_argument(
        "--plans-from",
        action="append",
        metavar="JSON",
        help="with --plans: the 2x runs of this recorded mixture campaign at their recorded sizes instead of "
        "--runs drawn (repeat for several)",
    )
    p.add_argument(
        "--basilisk-runs",
        type=number(int, 0, 100000),
        default=0,
        help="with --plans: this many planned runs also fly their plan alone on Basilisk (and on the bench's "
        "vehicle simulator), diagnosed alone",
    )
    add_campaign_arguments(p)
    p.set_defaults(func=main)


def _campaign(args):
    """The campaign's store is keyed by every argument its runs depend on,
    and by the null calibration it scores against."""
    from bench.runner.records import sha256

    if args.plans:
        from bench.gap import null as nullmod

        kind = {
            "plans": True,
            "duration_s": args.duration,
            "plans_from": [sha256_file(f) for f in args.plans_from or []],
        }
        return campaign_from(
            args,
            "validate-gap",
            {"runs": args.runs, "seed": args.seed, **kind, "calibration_sha256": sha256(nullmod.load())},
        )
    if args.vehicle == "random":
        # No committed calibration: each log's is made for it (and keyed by it).
        return campaign_from(
            args, "validate-gap", {"runs": args.runs, "seed": args.seed, "vehicle": "random", "engine": args.engine}
        )
    if args.vehicle == "12kg" or args.engine == "basilisk":
        from bench.campaigns.gap.validate_vehicle import load_calibration

        # The engine keys the store too: Basilisk's runs are not the bench plant's.
        cal, kind = (
            load_calibration(),
            {"vehicle": "12kg", **({"engine": "basilisk"} if args.engine == "basilisk" else {})},
        )
    else:
        from bench.gap import null as nullmod

        cal = nullmod.load(manoeuvres="docking" if args.mixtures else args.manoeuvres)
        kind = (
            {"mixtures": True, "duration_s": args.duration}
            if args.mixtures
            else {"manoeuvres": args.manoeuvres, "duration_s": args.duration}
        )
    return campaign_from(
        args, "validate-gap", {"runs": args.runs, "seed": args.seed, **kind, "calibration_sha256": sha256(cal)}
    )


def main(args):
    from bench.report import write_json

    if args.engine == "basilisk" and args.mixtures:
        raise ValueError("--engine basilisk runs the 12 kg single-effect campaign, not --mixtures")
    campaign = _campaign(args)
    where = campaign.where()
    if args.plans:
        return _plans(args, campaign, where)
    if args.mixtures:
        from bench.campaigns.gap import validate_mixtures

        res = validate_mixtures.run_campaign(
            args.runs, args.seed, args.json, duration_s=args.duration, campaign=campaign, manoeuvres=args.manoeuvres
        )
        if args.json:
            write_json(args.json, res, strict=True)
        print(f"mixture runs {res['runs']} (seed {res['seed']}, {res['elapsed_s']:.0f} s on {where})")
        report_campaign(res)
        for line in validate_mixtures.summary_lines(res):
            print(line)
        return 0
    res = _single_effects(args, campaign)
    if args.json:
        from pathlib import Path

        from bench.campaigns.gap.validate import runs_table

        write_json(args.json, res, strict=True)
        Path(str(args.json) + ".runs.csv").write_text(runs_table(res))
    print(f"runs {res['runs']} (seed {res['seed']}, {res['manoeuvres']}, {res['elapsed_s']:.0f} s on {where})")
    report_campaign(res)
    for line in score_lines(res):
        print(line)
    return 0


def _value(v, fmt: str = ".2f", none: str = "none measured") -> str:
    """A score, or what stands for a score that has no runs behind it."""
    return none if v is None else format(v, fmt)


def score_lines(res: dict) -> list:
    """The single-effect campaign's scores as printed, in words where a score
    has no runs behind it."""
    lines = [f"false alarms on null runs: {_value(res['false_alarm_rate'], '.3f')} (n = {res['n_null']})"]
    for s, v in res["in_library_by_scale"].items():
        lines.append(f"in-library {s}: detection {v['detection']:.2f}, top-1 {v['top1']:.2f} (n = {v['n']})")
    for s, v in res.get("in_library_by_scale_separable", {}).items():
        lines.append(
            f"  {s}, runs whose data separate the effect from every other candidate: top-1 "
            f"{_value(v['top1_separable'], none='-')} "
            f"(n = {v['n_separable']}; not separable: {v['n_not_separable']}, "
            + ", ".join(f"{e} {n}" for e, n in v["not_separable_by_effect"].items())
            + ")"
        )
    if "out_of_library" in res:
        o = res["out_of_library"]
        lines.append(
            f"out-of-library: unexplained {o['unexplained_rate']:.2f}, not detected {o['not_detected_rate']:.2f}, "
            f"confident misattribution {o['confident_misattribution_rate']:.2f} (n = {o['n']})"
        )
    b = res["beyond_detection_limit"]
    lines.append(
        f"beyond the detection limit of their run (scored apart): {b['n']} runs"
        + "".join(f", {e} {v['detected']}/{v['n']} detected" for e, v in b["by_effect"].items())
    )
    sh = res["shrink_heldout"]
    lines.append(
        f"held-out shrink median: true effect fitted {_value(sh['true_effect_median'], '.4f')} "
        f"(n = {sh['n_true']}), wrong effect fitted {_value(sh['wrong_effect_median'], '.4f')} (n = {sh['n_wrong']})"
    )
    cov = res["interval_coverage_95"]
    lines.append(f"95 % interval coverage: {_value(cov['fraction'])} ({cov['n_parameters']} parameters)")
    if "no_valves_stream" in res:
        nv = res["no_valves_stream"]
        lines.append(
            f"runs without a valves stream: {nv['n']}, answer said the dynamics were not examined in "
            f"{nv['said_dynamics_not_examined']}"
        )
    return lines


def _single_effects(args, campaign) -> dict:
    """The single-effect campaign the arguments name."""
    from bench.campaigns.gap.validate import run_campaign

    if args.vehicle == "random":
        from bench.campaigns.gap import validate_random

        res = validate_random.run_campaign(args.runs, args.seed, args.json, engine=args.engine, campaign=campaign)
        res["manoeuvres"] = f"characterisation (random vehicles, {args.engine} logs)"
    elif args.engine == "basilisk":
        from bench.campaigns.gap import validate_basilisk

        res = validate_basilisk.run_campaign(args.runs, args.seed, args.json, campaign=campaign)
        res["manoeuvres"] = f"characterisation (12 kg, Basilisk {res['basilisk_version']})"
    elif args.vehicle == "12kg":
        from bench.campaigns.gap import validate_vehicle

        res = validate_vehicle.run_campaign(args.runs, args.seed, args.json, campaign=campaign)
        res["manoeuvres"] = "characterisation (12 kg)"
    else:
        res = run_campaign(
            args.runs, args.seed, args.json, duration_s=args.duration, manoeuvres=args.manoeuvres, campaign=campaign
        )
    return res


def sha256_file(path) -> str:
    import hashlib
    from pathlib import Path

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _plans(args, campaign, where) -> int:
    """``--plans``: the designed plans' campaign (bench/campaigns/gap/validate_plans.py)."""
    from bench.campaigns.gap import validate_plans
    from bench.report import write_json

    if args.plans_from:
        drawn = validate_plans.recorded_keys(args.plans_from)
        source = {"plans_from": [str(f) for f in args.plans_from], "runs": len(drawn)}
        command = " ".join(f"--plans-from {f}" for f in args.plans_from)
    else:
        drawn = validate_plans.draw_keys(args.runs, args.seed)
        source = {"seed": args.seed, "runs": args.runs}
        command = f"--runs {args.runs} --seed {args.seed}"
    res = validate_plans.run_campaign(
        drawn,
        args.json,
        {**source, "plans": True},
        duration_s=args.duration,
        campaign=campaign,
        basilisk_runs=args.basilisk_runs,
    )
    res.update(source)
    res["command"] = f"proxops validate-gap --plans {command}" + (
        f" --basilisk-runs {args.basilisk_runs}" if args.basilisk_runs else ""
    )
    if args.json:
        write_json(args.json, res, strict=True)
    print(f"designed plans: {res['docking_runs']} docking runs ({res['elapsed_s']:.0f} s on {where})")
    report_campaign(res)
    for line in validate_plans.summary_lines(res):
        print(line)
    return 0
