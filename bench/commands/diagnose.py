"""`proxops diagnose LOG --report DIR --json OUT`: where the sim-to-real gap
lies, which unmodelled effect causes it, how far it shrinks on held-out data."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def register(sub):
    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap of a flight log (where, which, how far)")
    p.add_argument("log", help="flight log (HDF5, docs/FLIGHT_LOG.md)")
    p.add_argument("--report", default=None, help="write the Markdown report and plots into this folder")
    p.add_argument("--json", default=None, help="write the diagnosis as JSON here")
    p.add_argument("--calibration", default=None,
                   help="null calibration JSON (default: the committed one for docking logs; "
                        "bench/gap/data/null_calibration_characterisation.json for logs that also fly the "
                        "thruster characterisation)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=main)


def main(args):
    from bench.flight_log import read_flight_log
    from bench.gap import null as nullmod
    from bench.gap.diagnose import diagnose, public
    from bench.report import write_json

    log = read_flight_log(args.log)
    cal = nullmod.load(args.calibration) if args.calibration else nullmod.load()
    if not cal:
        print("warning: no null calibration found; detection thresholds are infinite")
    res = diagnose(log, calibration=cal, progress=not args.quiet)
    if args.report:
        from bench.gap.report import write_report

        page = write_report(res, args.report, Path(args.log).name)
        print(f"report: {page}")
    out = public(res)
    if args.json:
        write_json(args.json, out)
    print_answers(out)
    print(f"diagnosed in {out['elapsed_s']:.1f} s")
    return 0


def print_answers(out: dict, indent: str = "") -> None:
    """The three answers: where, which, how far."""
    w = (out["location"]["where"] or {})
    print(f"{indent}gap detected: {'yes' if out['gap_detected'] else 'no'}")
    if out["gap_detected"]:
        acts = out["location"].get("effect_acts_while")
        # While which regime: from the fitted effect's signature when one explains
        # the gap, else from the gap map's strongest regime cell.
        regime = (f"acting while {acts['peak']}" if acts and acts["peak"]
                  else f"strongest while {w.get('regime_peak')}")
        print(f"{indent}  where:   {w.get('stream')} {w.get('axis')} ({w.get('stat')}), {regime}; "
              f"a {out['location']['dynamics_or_sensor']} gap")
        best = out["attribution"][0] if out["attribution"] else None
        which = best["effect"] if best is not None and out["verdict"] != "unexplained" else "unexplained"
        print(f"{indent}  which:   {which} ({out['verdict']})")
        if best is not None and out["verdict"] != "unexplained":
            pars = ", ".join(f"{k} {v['value']:.3g} +/- {v['sigma']:.2g}" for k, v in best["parameters"].items()
                             if abs(v["value"]) > 2 * v["sigma"])
            if pars:
                print(f"{indent}           fitted (beyond 2 sigma): {pars}")
        if out["shrink_heldout"]:
            s = out["shrink_heldout"]
            print(f"{indent}  how far: held-out deficit shrinks {100 * s['fraction']:.0f} % "
                  f"[{100 * s['ci95'][0]:.0f}, {100 * s['ci95'][1]:.0f}] with {s['effect']}")
        r = out.get("shrink_heldout_runs")
        if r and r.get("fraction") is not None and np.isfinite(r["fraction"]):
            print(f"{indent}           on held-out runs ({r['heldout_runs']} of {r['runs']}, fitted on the others): "
                  f"{100 * r['fraction']:.0f} % [{100 * r['ci95'][0]:.0f}, {100 * r['ci95'][1]:.0f}]")
