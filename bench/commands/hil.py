"""`proxops hil`: the docking scenario with the flight executable behind a
pseudo-terminal link."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from bench.report import report_dir, write_json


def register(sub):
    p = sub.add_parser("hil", help="docking over a pseudo-terminal link with the flight executable (fsw_node)")
    p.add_argument("--scenario", choices=["docking"], default="docking")
    p.add_argument("--duration", type=float, default=60.0, help="simulated seconds (docking runs are chained)")
    p.add_argument("--realtime", action="store_true", help="pace the loop at 10 Hz by the wall clock")
    p.add_argument("--ber", type=float, default=0.0, help="bit error rate on both directions")
    p.add_argument("--drop-rate", type=float, default=0.0, help="probability that a byte is lost")
    p.add_argument("--burst-rate", type=float, default=0.0, help="probability of a burst per frame")
    p.add_argument("--duplicate-rate", type=float, default=0.0)
    p.add_argument("--reorder-rate", type=float, default=0.0)
    p.add_argument("--stall-rate", type=float, default=0.0, help="probability of a stall per chunk")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--learner", action="store_true",
                   help="send the valve commands so the flight thruster learner learns (tm_learner telemetry)")
    p.add_argument("--json", default=None, help="write the summary JSON here")
    p.add_argument("--report", default=None, help="report folder: plots, JSON, flight log")
    p.set_defaults(func=main)


def hil_summary(res: dict, args) -> dict:
    from hil_sim.run import nav_errors

    errs = nav_errors(res["runs"])
    nis = np.concatenate([r["updates"]["nis"][np.asarray(r["updates"]["fused"], bool)]
                          for r in res["runs"] if len(r["updates"]["nis"])] or [np.zeros(0)])
    return {
        "scenario": args.scenario,
        "duration_s": args.duration,
        "realtime": bool(args.realtime),
        "faults": {"ber": args.ber, "drop_rate": args.drop_rate, "burst_rate": args.burst_rate,
                   "duplicate_rate": args.duplicate_rate, "reorder_rate": args.reorder_rate,
                   "stall_rate": args.stall_rate},
        "seed": args.seed,
        "docking_runs": len(res["runs"]),
        "docked": int(sum(r["summary"]["docked"] for r in res["runs"])),
        "real_time_factor": res["real_time_factor"],
        "wall_s": res["wall_s"],
        "sim_time_s": res["sim_time_s"],
        "steps": res["steps"],
        "step_latency_p50_ms": res["step_latency_p50_ms"],
        "step_latency_p99_ms": res["step_latency_p99_ms"],
        "step_latency_max_ms": float(np.max(res["step_latency_ms"])) if res["steps"] else None,
        "step_timeouts": res["step_timeouts"],
        "realtime_overruns": res["realtime_overruns"],
        "packets_sent": res["packets_sent"],
        "packets_rejected_by_reason": res["flight_rejected_by_reason"],
        "telemetry_rejected_by_reason": res["bench_rejected_by_reason"],
        "telemetry_packets_accepted": res["bench_packets_accepted"],
        "bad_crc_delivered": res["bad_crc_delivered"],
        "learner_telemetry_packets": len(res["learner_outputs"]),
        "learner_last": (None if not res["learner_outputs"] else
                         {"t_s": res["learner_outputs"][-1][0], "n_samples": res["learner_outputs"][-1][1][0],
                          "dv_b_mps": list(res["learner_outputs"][-1][1][2:5]),
                          "dw_b_rps": list(res["learner_outputs"][-1][1][5:8])}),
        "faults_injected_up": res["faults_up"],
        "faults_injected_down": res["faults_down"],
        "max_pos_err_m": errs["max_pos_err_m"],
        "max_vel_err_mps": errs["max_vel_err_mps"],
        "worst_pos_err_m": max(errs["max_pos_err_m"], default=None),
        "worst_vel_err_mps": max(errs["max_vel_err_mps"], default=None),
        "nis_mean": float(np.mean(nis)) if nis.size else None,
        "fsw_node_exit_code": res["fsw_node_exit_code"],
        "fsw_node_summary": res["fsw_node_summary"],
    }


def print_summary(s: dict):
    print(f"HIL {s['scenario']}: {s['sim_time_s']:.1f} s simulated in {s['wall_s']:.2f} s "
          f"(real-time factor {s['real_time_factor']:.1f}), {s['docking_runs']} docking run(s), {s['docked']} docked")
    print(f"  steps {s['steps']}, latency p50 {s['step_latency_p50_ms']:.3f} ms, p99 {s['step_latency_p99_ms']:.3f} ms, "
          f"timeouts {s['step_timeouts']}")
    print(f"  navigation: worst per-axis error {s['worst_pos_err_m']:.4f} m, {s['worst_vel_err_mps']:.4f} m/s; "
          f"mean NIS {s['nis_mean']:.2f} (6 dof)")
    rej = {k: v for k, v in s["packets_rejected_by_reason"].items() if v}
    trej = {k: v for k, v in s["telemetry_rejected_by_reason"].items() if v}
    print(f"  link: {s['packets_sent']} packets sent; flight rejected {sum(rej.values())} {rej or ''}; "
          f"bench rejected {sum(trej.values())} telemetry {trej or ''}; bad CRC delivered {s['bad_crc_delivered']}")
    print(f"  fsw_node: {s['fsw_node_summary']} (exit code {s['fsw_node_exit_code']})")


def main(args):
    from hil_sim.faults import FaultConfig
    from hil_sim.run import HilConfig, run_hil

    faults = FaultConfig(ber=args.ber, drop_rate=args.drop_rate, burst_rate=args.burst_rate,
                         duplicate_rate=args.duplicate_rate, reorder_rate=args.reorder_rate,
                         stall_rate=args.stall_rate)
    timeout = 0.05 if faults.clean else 0.02

    def progress(t_done, total, run):
        print(f"  [{min(t_done, total):7.1f} / {total:.0f} s] docking run: "
              f"{'docked' if run['summary']['docked'] else 'not docked'} at t = {run['summary']['t_end_s']:.1f} s",
              file=sys.stderr, flush=True)

    cfg = HilConfig(duration_s=args.duration, realtime=args.realtime, seed=args.seed, faults=faults,
                    step_timeout_s=timeout, learner=getattr(args, "learner", False))
    res = run_hil(cfg, progress=progress)
    s = hil_summary(res, args)
    print_summary(s)
    if args.report:
        out = report_dir(args.report)
        write_json(out / "hil.json", s)
        from hil_sim.report import write_hil_report

        write_hil_report(res, s, out)
        print(f"  report: {out}/ (hil.json, flight_log.h5, plots)")
    if args.json:
        write_json(args.json, s)
    return 0
