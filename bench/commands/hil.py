"""`proxops hil`: the docking scenario (navigation) or the vibrating plate
(modal estimator, range images) with the flight software behind a serial
link: fsw_node started here on a pseudo-terminal (with optional link
faults), or a flight computer on a real serial port (--device)."""

from __future__ import annotations

import contextlib
import sys

import numpy as np

from bench.commands.args import SEED_HELP, HelpFormatter, number, one_line_errors, seed
from bench.report import json_text, staged_report_dir, write_json

BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)  # fsw_node's (serial_port.cpp)


def register(sub):
    p = sub.add_parser(
        "hil",
        help="docking or plate range images over a serial link with the flight "
        "executable (fsw_node on a pseudo-terminal, or a flight computer on a port)",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops hil")
    p.add_argument(
        "--scenario",
        choices=["docking", "plate"],
        default="docking",
        help="docking: navigation at 10 Hz; plate: range images of the vibrating plate to the modal estimator",
    )
    p.add_argument(
        "--images",
        type=number(int, 1, 100000),
        default=120,
        help="plate: images, one per simulated minute (120 = 3 periods of the lowest mode; 1 to 100000)",
    )
    p.add_argument(
        "--duration",
        type=number(float, 0.0, 1e6, lo_open=True),
        default=60.0,
        help="docking: simulated seconds, docking runs chained (> 0, <= 1e6)",
    )
    p.add_argument("--realtime", action="store_true", help="pace the loop at 10 Hz by the wall clock")
    _fault_options(p)
    p.add_argument("--seed", type=seed, default=1, help=SEED_HELP)
    p.add_argument(
        "--learner",
        action="store_true",
        help="send the valve commands so the flight thruster learner learns (tm_learner telemetry)",
    )
    p.add_argument(
        "--plan",
        default=None,
        metavar="FILE",
        help="fly this valve plan (the JSON of proxops plan --separate --json) open loop: uplinked to the "
        "flight side, checked and run by it, the plant firing the valves it commands "
        '(docs/LINK.md, "Valve plans"); the plan\'s length replaces --duration',
    )
    p.add_argument(
        "--device",
        default=None,
        metavar="PATH",
        help="a flight computer running fsw_node on this serial port (e.g. /dev/ttyUSB0) instead of "
        "fsw_node started here on a pseudo-terminal; no link faults then (docs/LINK.md)",
    )
    p.add_argument(
        "--baud",
        type=int,
        choices=BAUDS,
        default=921600,
        metavar="N",
        help=f"baud rate of --device, as fsw_node --baud on the flight computer ({', '.join(map(str, BAUDS))})",
    )
    p.add_argument(
        "--json",
        default=None,
        metavar="FILE",
        help="write the summary here as strict JSON (a non-finite number is null, listed under "
        "non_finite_as_null); - writes it to standard output and the printed summary to stderr",
    )
    p.add_argument("--report", default=None, help="report folder: plots, JSON, flight log")
    p.set_defaults(func=main)


def _fault_options(p):
    """The link faults the relay injects (both directions)."""
    prob = number(float, 0.0, 1.0)
    p.add_argument(
        "--ber", type=number(float, 0.0, 0.5), default=0.0, help="bit error rate on both directions (0 to 0.5)"
    )
    p.add_argument(
        "--drop-rate",
        type=number(float, 0.0, 1.0, hi_open=True),
        default=0.0,
        help="probability that a byte is lost (0 to < 1)",
    )
    p.add_argument("--burst-rate", type=prob, default=0.0, help="probability of a burst per frame (0 to 1)")
    p.add_argument("--duplicate-rate", type=prob, default=0.0, help="probability a frame is duplicated (0 to 1)")
    p.add_argument(
        "--reorder-rate", type=prob, default=0.0, help="probability a frame is held back behind the next (0 to 1)"
    )
    p.add_argument("--stall-rate", type=prob, default=0.0, help="probability of a stall per chunk (0 to 1)")


def hil_summary(res: dict, args) -> dict:
    from hil_sim.run import nav_errors

    errs = nav_errors(res["runs"])
    nis = np.concatenate(
        [r.updates.nis[np.asarray(r.updates.fused, bool)] for r in res["runs"] if len(r.updates.nis)] or [np.zeros(0)]
    )
    return {
        "scenario": args.scenario,
        "duration_s": args.duration,
        "realtime": bool(args.realtime),
        "faults": {
            "ber": args.ber,
            "drop_rate": args.drop_rate,
            "burst_rate": args.burst_rate,
            "duplicate_rate": args.duplicate_rate,
            "reorder_rate": args.reorder_rate,
            "stall_rate": args.stall_rate,
        },
        "seed": args.seed,
        "docking_runs": len(res["runs"]),
        "docked": int(sum(r.summary.docked for r in res["runs"])),
        "docking_runs_cut_by_duration": int(sum(r.summary.cut_by_duration for r in res["runs"])),
        "real_time_factor": res["real_time_factor"],
        "wall_s": res["wall_s"],
        "sim_time_s": res["sim_time_s"],
        "steps": res["steps"],
        "step_latency_p50_ms": res["step_latency_p50_ms"],
        "step_latency_p99_ms": res["step_latency_p99_ms"],
        "step_latency_max_ms": float(np.max(res["step_latency_ms"])) if res["steps"] else None,
        "step_timeouts": res["step_timeouts"],
        "poses_not_sent": res.get("poses_not_sent", 0),
        "realtime_overruns": res["realtime_overruns"],
        "packets_sent": res["packets_sent"],
        "packets_rejected_by_reason": res["flight_rejected_by_reason"],
        "telemetry_rejected_by_reason": res["bench_rejected_by_reason"],
        "telemetry_packets_accepted": res["bench_packets_accepted"],
        "bad_crc_delivered": res["bad_crc_delivered"],
        "learner_telemetry_packets": len(res["learner_outputs"]),
        "learner_last": (
            None
            if not res["learner_outputs"]
            else {
                "t_s": res["learner_outputs"][-1][0],
                "n_samples": res["learner_outputs"][-1][1][0],
                "dv_b_mps": list(res["learner_outputs"][-1][1][2:5]),
                "dw_b_rps": list(res["learner_outputs"][-1][1][5:8]),
            }
        ),
        "faults_injected_up": res["faults_up"],
        "faults_injected_down": res["faults_down"],
        "max_pos_err_m": errs["max_pos_err_m"],
        "max_vel_err_mps": errs["max_vel_err_mps"],
        "worst_pos_err_m": max(errs["max_pos_err_m"], default=None),
        "worst_vel_err_mps": max(errs["max_vel_err_mps"], default=None),
        "nis_mean": float(np.mean(nis)) if nis.size else None,
        "fsw_node_exit_code": res["fsw_node_exit_code"],
        "fsw_node_summary": res["fsw_node_summary"],
        "degraded": _degraded(res, errs, nis),
    }


def _degraded(res: dict, errs: dict, nis) -> str | None:
    """Why the link made this run's figures degraded (None: it did not):
    steps the flight side's answer never reached, poses that could not be
    sent, runs without a navigation error (no estimate came back)."""
    why = []
    if res["step_timeouts"]:
        why.append(f"{res['step_timeouts']} of {res['steps']} steps unanswered")
    if res.get("poses_not_sent"):
        why.append(f"{res['poses_not_sent']} poses not sent (no estimate back to size their covariance)")
    if len(errs["max_pos_err_m"]) < len(res["runs"]):
        why.append(f"{len(res['runs']) - len(errs['max_pos_err_m'])} docking run(s) without a navigation estimate")
    if not nis.size:
        why.append("no answer of a fused pose update came back")
    return "; ".join(why) or None


def _fmt(value, spec: str, missing: str = "n/a") -> str:
    """A figure the link may have left without a value (None or NaN)."""
    return missing if value is None or not np.isfinite(value) else format(value, spec)


def _device(args):
    return getattr(args, "device", None)  # callers such as `proxops run` build args without it


def _baud(args):
    return getattr(args, "baud", 921600)


def _node_line(s: dict) -> str:
    # fsw_node's own summary starts with its name; the line already says it.
    text = s["fsw_node_summary"].removeprefix("fsw_node: ")
    if s["fsw_node_exit_code"] is None:
        return text
    return f"{text} (exit code {s['fsw_node_exit_code']})"


def _rejected(what: str, by_reason: dict) -> str:
    """ "flight rejected 0" or "flight rejected 3 (bad_crc 2, seq_gap 1)"."""
    counts = {k: v for k, v in by_reason.items() if v}
    detail = ", ".join(f"{k} {v}" for k, v in counts.items())
    return f"{what} {sum(counts.values())}" + (f" ({detail})" if detail else "")


def print_summary(s: dict):
    print(
        f"HIL {s['scenario']}: {s['sim_time_s']:.1f} s simulated in {s['wall_s']:.2f} s "
        f"(real-time factor {s['real_time_factor']:.1f}), {s['docking_runs']} docking run(s), {s['docked']} docked"
        + (
            f", {s['docking_runs_cut_by_duration']} cut short by the end of the {s['duration_s']:g} s"
            if s["docking_runs_cut_by_duration"]
            else ""
        )
    )
    print_link_lines(s)


def print_link_lines(s: dict):
    """The summary's lines after its first: steps, navigation, link, fsw_node."""
    print(
        f"  steps {s['steps']}, latency p50 {s['step_latency_p50_ms']:.3f} ms, p99 {s['step_latency_p99_ms']:.3f} ms, "
        f"timeouts {s['step_timeouts']}"
    )
    print(
        f"  navigation: worst per-axis error {_fmt(s['worst_pos_err_m'], '.4f')} m, "
        f"{_fmt(s['worst_vel_err_mps'], '.4f')} m/s; mean NIS {_fmt(s['nis_mean'], '.2f')} (6 dof)"
    )
    if s.get("degraded"):
        print(f"  degraded by the link: {s['degraded']}")
    print(
        f"  link: {s['packets_sent']} packets sent; "
        f"{_rejected('flight rejected', s['packets_rejected_by_reason'])}; "
        f"{_rejected('bench rejected telemetry', s['telemetry_rejected_by_reason'])}; "
        f"bad CRC delivered {s['bad_crc_delivered']}"
    )
    print(f"  fsw_node: {_node_line(s)}")


def plate_main(args, faults) -> int:
    from hil_sim.modal_link import PlateHilConfig, plate_hil_summary, run_plate_hil

    def progress(done, total):
        print(f"  [{done:4d} / {total} images]", file=sys.stderr, flush=True)

    res = run_plate_hil(
        PlateHilConfig(images=args.images, seed=args.seed, faults=faults, device=_device(args), baud=_baud(args)),
        progress=progress,
    )
    s = plate_hil_summary(res)
    s["scenario"] = "plate"
    s["seed"] = args.seed
    s["faults"] = faults.as_dict()
    print(
        f"HIL plate: {s['images_sent']} range images ({s['lowest_mode_periods']:.1f} periods of the lowest mode), "
        f"{s['points_sent']} points, a priori frequencies {100 * s['prior_frequency_error']:+.1f} %"
    )
    print(
        f"  answered {s['images_answered']}, fused {s['images_fused']}; images with points lost on the link "
        f"{s['images_with_points_lost']} ({s['points_sent'] - s['points_used']} points)"
    )
    rel = np.array(s["final_frequency_rel_error"])
    print(
        f"  modes excited >= 0.2: {len(s['strong_modes'])}, within 1 % of their frequency at the end: "
        f"{s['strong_modes_within_1pct']}; worst {_fmt(100 * np.max(np.abs(rel[s['strong_modes']])), '.2f')} %"
        if s["strong_modes"]
        else "  no mode excited >= 0.2"
    )
    print(
        f"  answer latency p50 {_fmt(s['answer_latency_p50_ms'], '.2f')} ms, "
        f"p99 {_fmt(s['answer_latency_p99_ms'], '.2f')} ms; wall {s['wall_s']:.1f} s"
    )
    if s["images_answered"] < s["images_sent"] or s["images_with_points_lost"]:
        print(
            f"  degraded by the link: {s['images_sent'] - s['images_answered']} of {s['images_sent']} images "
            f"unanswered, {s['images_with_points_lost']} with points lost"
        )
    print(f"  fsw_node: {_node_line(s)}")
    if args.json:
        _write_summary(args, s)
    if args.report:
        with staged_report_dir(args.report) as tmp:
            write_json(tmp / "hil_plate.json", s, strict=True)
        print(f"  report: {args.report}/hil_plate.json")
    return 0 if s["fsw_node_exit_code"] == 0 or _device(args) else 1


def _plan_lines(s: dict) -> list:
    p = s["plan"]
    head = (
        f"HIL plan {s['plan_file']}: {p['entries']} valve openings over {p['duration_s']:g} s "
        f"(on-time {p['on_time_s']:g} s); flight side: {p['verdict']}"
    )
    if not p["started"]:
        return [head + ("; nothing flown" if p["verdict"] == "accepted" else ", refused; nothing flown")]
    return [
        head + f", started, {p['ended'] or 'not seen to end'}",
        f"  valves: the plant fired {p['intervals_firing'] - p['intervals_differing']} of the plan's "
        f"{p['intervals_firing']} firing intervals as planned, {p['intervals_differing']} of {p['intervals']} "
        f"intervals differing, {p['firing_outside_the_plan']} firing outside it; valve-seconds "
        f"{p['valve_seconds_planned']:g} planned, {p['valve_seconds_flown']:g} flown "
        f"({p['commands_received']} commands received)",
        f"  {s['sim_time_s']:.1f} s simulated in {s['wall_s']:.2f} s (real-time factor {s['real_time_factor']:.1f})",
    ]


def plan_main(args, faults) -> int:
    """--plan FILE: the plan flown over the link (hil_sim/plan_link.py).
    Exit code 1 when the flight side refused it or the plant did not fly it
    as planned."""
    from hil_sim.plan_link import PlanHilConfig, read_plan, run_plan_hil

    if args.scenario != "docking":
        raise ValueError("--plan flies the plan on the docking plant; it cannot be used with --scenario plate")
    entries, duration = read_plan(args.plan)
    cfg = PlanHilConfig(
        entries,
        duration,
        seed=args.seed,
        realtime=args.realtime,
        faults=faults,
        step_timeout_s=0.05 if faults.clean else 0.02,
        device=_device(args),
        baud=_baud(args),
    )
    res = run_plan_hil(cfg)
    args.duration = duration
    s = hil_summary(res, args)
    s.update({"scenario": "plan", "plan_file": str(args.plan), "plan": res["plan"]})
    p = s["plan"]
    for line in _plan_lines(s):
        print(line)
    if p["started"]:
        print_link_lines(s)
    else:
        print(f"  fsw_node: {_node_line(s)}")
    if args.report and p["started"]:
        _write_report(args.report, res, s)
    if args.json:
        _write_summary(args, s)
    flown = p["started"] and p["ended"] == "finished" and p["intervals_differing"] == 0
    return 0 if flown else 1


def _write_report(report: str, res, s: dict) -> None:
    """hil.json, the flight log and the plots, written whole into ``report``."""
    from hil_sim.report import write_hil_report

    with staged_report_dir(report) as tmp:
        write_json(tmp / "hil.json", s, strict=True)
        not_written = write_hil_report(res, s, tmp)
    print(f"  report: {report}/ (hil.json, " + ("" if not_written else "flight_log.h5, ") + "plots)")
    if not_written:
        print(f"  {not_written}")


def _write_summary(args, s: dict):
    """--json FILE (written atomically), or --json - (to standard output;
    the printed summary then went to standard error). Strict JSON."""
    if args.json == "-":
        args.json_stream.write(json_text(s, strict=True))
        args.json_stream.flush()
    else:
        write_json(args.json, s, strict=True)


def main(args):
    from hil_sim.pty_link import FlightSideLost

    args.json_stream = sys.stdout
    try:
        if getattr(args, "json", None) == "-":
            with contextlib.redirect_stdout(sys.stderr):
                return _main(args)
        return _main(args)
    except FlightSideLost as exc:
        # Nothing has been written: the user's earlier outputs stay as they were.
        print(f"proxops hil: {exc}; run abandoned, no output written", file=sys.stderr)
        return 1


def _main(args):
    from hil_sim.faults import FaultConfig
    from hil_sim.run import HilConfig, run_hil

    faults = FaultConfig(
        ber=args.ber,
        drop_rate=args.drop_rate,
        burst_rate=args.burst_rate,
        duplicate_rate=args.duplicate_rate,
        reorder_rate=args.reorder_rate,
        stall_rate=args.stall_rate,
    )
    if getattr(args, "plan", None):
        return plan_main(args, faults)
    if args.scenario == "plate":
        return plate_main(args, faults)
    timeout = 0.05 if faults.clean else 0.02

    def progress(t_done, total, run):
        summ = run.summary
        how = "docked" if summ.docked else "cut short by the end of the run" if summ.cut_by_duration else "not docked"
        print(
            f"  [{min(t_done, total):7.1f} / {total:.0f} s] docking run: {how} at t = {summ.t_end_s:.1f} s",
            file=sys.stderr,
            flush=True,
        )

    cfg = HilConfig(
        duration_s=args.duration,
        realtime=args.realtime,
        seed=args.seed,
        faults=faults,
        step_timeout_s=timeout,
        learner=getattr(args, "learner", False),
        device=_device(args),
        baud=_baud(args),
    )
    res = run_hil(cfg, progress=progress)
    s = hil_summary(res, args)
    print_summary(s)
    if args.report:
        _write_report(args.report, res, s)
    if args.json:
        _write_summary(args, s)
    return 0
