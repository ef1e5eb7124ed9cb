"""`proxops run`: the main job behind `make run`: the docking scenario with
the flight executable behind the pseudo-terminal link, a printed summary
and a report folder (plots, JSON, the flight log); range images of the
vibrating plate to the same executable's modal estimator (three periods of
the lowest mode, a second of wall time); then the sim-to-real gap
diagnosis of the bundled reality run (bench/gap/bundled.py), whose effect
the diagnoser is not told, with its three answers: where, which, how far."""

from __future__ import annotations

import argparse
from pathlib import Path

from bench.commands.args import SEED_HELP, HelpFormatter, number, one_line_errors, seed


def register(sub):
    p = sub.add_parser(
        "run",
        help="the main end-to-end job (make run): HIL docking over a pseudo-terminal",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops run")
    p.add_argument("--report", default="report", help="report folder")
    p.add_argument(
        "--duration",
        type=number(float, 0.0, 86400.0, lo_open=True),
        default=120.0,
        help="simulated seconds (> 0 to 86400)",
    )
    p.add_argument("--seed", type=seed, default=1, help=SEED_HELP)
    p.set_defaults(func=main)


def main(args):
    from bench.commands import hil

    print(
        f"proxops run: docking over the HIL link (fsw_node behind a pseudo-terminal), "
        f"{args.duration:.0f} s simulated, seed {args.seed}"
    )
    hil_args = argparse.Namespace(
        scenario="docking",
        duration=args.duration,
        realtime=False,
        ber=0.0,
        drop_rate=0.0,
        burst_rate=0.0,
        duplicate_rate=0.0,
        reorder_rate=0.0,
        stall_rate=0.0,
        seed=args.seed,
        json=None,
        report=args.report,
        learner=True,
    )
    rc = hil.main(hil_args)
    if rc:
        return rc
    print("\nproxops run: range images of the vibrating plate to the flight modal estimator over the link")
    plate_args = argparse.Namespace(
        scenario="plate",
        images=120,
        ber=0.0,
        drop_rate=0.0,
        burst_rate=0.0,
        duplicate_rate=0.0,
        reorder_rate=0.0,
        stall_rate=0.0,
        seed=args.seed,
        json=None,
        report=args.report,
    )
    rc = hil.main(plate_args)
    if rc:
        return rc
    return diagnose_bundled(Path(args.report) / "gap")


def diagnose_bundled(report_dir: Path) -> int:
    """Diagnose the bundled reality run, blind, then open its sealed key."""
    from bench.commands.diagnose import print_answers
    from bench.gap import bundled
    from bench.gap.diagnose import diagnose, public
    from bench.gap.report import write_report
    from bench.report import write_json
    from bench.sim.flight_log import read_flight_log

    print(
        f"\nproxops run: sim-to-real gap diagnosis of the bundled reality run ({bundled.LOG.name}, "
        f"effect sealed in {bundled.KEY.name})"
    )
    res = diagnose(read_flight_log(bundled.LOG), progress=False)
    page = write_report(res, report_dir, bundled.LOG.name)
    out = public(res)
    write_json(report_dir / "diagnosis.json", out)
    print_answers(out, indent="  ")
    print(f"  diagnosed in {out['elapsed_s']:.1f} s; report {page}")
    plan_if_ambiguous(bundled.LOG, out, report_dir)
    key = bundled.sealed_key()
    print(f"  sealed key, opened after the answer: {key['effects']}")
    return 0


def plan_if_ambiguous(log_path: Path, out: dict, report_dir: Path) -> None:
    """An ambiguous answer comes with the test that would settle it: the
    valve plan designed for the log's own vehicle within the default limits
    (`proxops plan LOG --separate`, bench/gap/design.py; docs/GAP.md),
    written beside the diagnosis with its figure, and each pair's predicted
    distance printed against the fixed characterisation's."""
    if out.get("verdict") != "ambiguous" or not out.get("ambiguous_with"):
        return
    from bench.gap.design import plot, separate
    from bench.report import write_json
    from bench.sim.flight_log import read_flight_log

    print("  ambiguous: designing the valve plan that would separate the look-alikes (about 30 s) ...", flush=True)
    path, fig = report_dir / "plan.json", report_dir / "plan.png"
    command = f"proxops plan {log_path} --separate --diagnosis {report_dir / 'diagnosis.json'} --json {path}"
    res = {"command": command, **separate(read_flight_log(log_path, relative_time=True), out)}
    write_json(path, res, strict=True)
    plot(res, str(fig))
    d, f = res["designed"], res["fixed"]
    fired = sorted({int(v) for run in d["schedule"] for v in run["valves"]})
    print(
        f"  plan it would fly: {d['runs']} runs from rest, valves {', '.join(map(str, fired))} "
        f"({res['passes']} passes), {d['duration_s']:.0f} s and {d['delta_v_mps']:.3g} m/s "
        f"(fixed characterisation: {f['duration_s']:.0f} s, {f['delta_v_mps']:.3g} m/s)"
    )
    for pd, pf in zip(d["pairs"], f["pairs"]):
        told = "passes" if pd["reached"] else "short of it within the limits"
        print(
            f"    {pd['a']} vs {pd['b']}: {pd['delta2_half']:.3g} on a half (fixed plan {pf['delta2_half']:.3g}; "
            f"its {pd['test'].split(':')[0]} test asks {pd['required_half']:.3g}): {told}"
        )
    if not all(p["reached"] for p in d["pairs"]):
        print(
            "    for the sizes listed, the shortest plan reaching every level: proxops plan LOG --separate "
            "--as-listed --reach --max-duration-s 600 --max-delta-v 0.8; a hidden member along every one of its "
            "directions may be out of any plan's reach (docs/GAP.md, the selection table)"
        )
    print(f"  plan {path}; figure {fig}")
