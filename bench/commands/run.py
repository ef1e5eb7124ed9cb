"""`proxops run`: the main job behind `make run`: the docking scenario with
the flight executable behind the pseudo-terminal link, a printed summary
and a report folder (plots, JSON, the flight log)."""
from __future__ import annotations

import argparse


def register(sub):
    p = sub.add_parser("run", help="the main end-to-end job (make run): HIL docking over a pseudo-terminal")
    p.add_argument("--report", default="report", help="report folder")
    p.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    p.add_argument("--seed", type=int, default=1)
    p.set_defaults(func=main)


def main(args):
    from bench.commands import hil

    print(f"proxops run: docking over the HIL link (fsw_node behind a pseudo-terminal), "
          f"{args.duration:.0f} s simulated, seed {args.seed}")
    hil_args = argparse.Namespace(scenario="docking", duration=args.duration, realtime=False, ber=0.0,
                                  drop_rate=0.0, burst_rate=0.0, duplicate_rate=0.0, reorder_rate=0.0,
                                  stall_rate=0.0, seed=args.seed, json=None, report=args.report, learner=True)
    return hil.main(hil_args)
