"""`proxops cw-check`: CW against exact two-body motion over one orbit."""

from __future__ import annotations

from bench.campaigns import cw_check
from bench.commands.args import HelpFormatter, number, one_line_errors
from bench.report import write_json
from bench.sim import orbit


def register(sub):
    p = sub.add_parser(
        "cw-check",
        help="CW propagator vs two-body truth at 10 m over one orbit",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops cw-check")
    p.add_argument(
        "--altitude-km",
        type=number(float, 100.0, 100000.0),
        default=500.0,
        help="host circular-orbit altitude [km] (100 to 100000)",
    )
    p.add_argument(
        "--separation-m",
        type=number(float, 0.0, 100000.0, lo_open=True),
        default=10.0,
        help="initial separation [m] (> 0 to 100000)",
    )
    p.add_argument("--json", default=None, help="write results here")
    p.set_defaults(func=main)


def main(args):
    radius = orbit.EARTH_RADIUS + args.altitude_km * 1e3
    n = orbit.orbit_rate(radius)
    print(f"host orbit radius {radius / 1e3:.1f} km, n = {n:.6e} rad/s, period {2 * 3.141592653589793 / n:.1f} s")
    print(f"{'case':28s} {'max |err| [m]':>14s} {'bound [m]':>12s}  within")
    out = {}
    for name, s0 in cw_check.cases(n, args.separation_m).items():
        r = cw_check.run_case(s0, radius)
        ok = r["max_pos_err_m"] <= r["bound_m"]
        print(f"{name:28s} {r['max_pos_err_m']:14.3e} {r['bound_m']:12.3e}  {'yes' if ok else 'NO'}")
        out[name] = {k: r[k] for k in ("max_pos_err_m", "bound_m", "rho_max_m")}
    if args.json:
        write_json(args.json, out, strict=True)
    return 0
