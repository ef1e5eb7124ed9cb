"""`proxops run`: the main job behind `make run`."""
from __future__ import annotations

import argparse

from bench.commands import cw_check


def register(sub):
    p = sub.add_parser("run", help="the main end-to-end job (make run)")
    p.add_argument("--report", default="report", help="report folder")
    p.set_defaults(func=main)


def main(args):
    from pathlib import Path

    Path(args.report).mkdir(parents=True, exist_ok=True)
    return cw_check.main(argparse.Namespace(altitude_km=500.0, separation_m=10.0,
                                            json=str(Path(args.report) / "cw_check.json")))
