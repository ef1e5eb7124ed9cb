"""`proxops simulate --engine {bench,basilisk} --vehicle V --manoeuvres characterisation
--effects JSON --seed S --out LOG.h5`: a flight log (format version 2) of a
described vehicle flying a characterisation open loop, from the bench's own
plant (bench/sim/vehicle_sim.py) or from Basilisk (bench/sim/basilisk_sim.py, the
optional extra `pip install .[basilisk]`)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from bench.commands.args import SEED_HELP, HelpFormatter, one_line_errors, seed


def register(sub):
    p = sub.add_parser(
        "simulate",
        help="write a simulated flight log from the bench's plant or from Basilisk",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops simulate")
    p.add_argument(
        "--engine",
        default="bench",
        choices=("bench", "basilisk"),
        help="bench: the bench's plant; basilisk: Basilisk's spacecraft, thrusters and IMU "
        "(needs pip install '.[basilisk]')",
    )
    p.add_argument(
        "--vehicle", default="12kg", choices=("3kg", "12kg"), help="the described vehicle (bench/sim/vehicles.py)"
    )
    p.add_argument(
        "--description",
        default=None,
        help="a flight-log description JSON file (docs/FLIGHT_LOG.md) instead of --vehicle",
    )
    p.add_argument(
        "--manoeuvres",
        default="characterisation",
        choices=("characterisation",),
        help="every thruster alone, pulse-width modulated, then a coast (bench/sim/plans.py), flown open loop",
    )
    p.add_argument(
        "--effects",
        default="{}",
        help="effects as JSON, name -> parameters (docs/EFFECTS.md), or a JSON file holding them",
    )
    p.add_argument("--seed", type=seed, default=0, help=SEED_HELP)
    p.add_argument(
        "--clocks",
        default="regular",
        choices=("regular", "as-real-logs"),
        help="regular: IMU on its ticks, a pose a second; as-real-logs: the 12 kg campaign's jittered "
        "IMU stamps, dropped samples and pose captures between samples",
    )
    p.add_argument("--no-truth", action="store_true", help="leave the truth stream out (a blind log)")
    p.add_argument("--out", required=True, help="the flight log to write (HDF5)")
    p.add_argument("--key", default=None, help="write the effects and seed (not in the log) to this JSON file")
    p.set_defaults(func=main)


def _description(args) -> dict:
    """The description to fly: --description's file, or --vehicle's."""
    if not args.description:
        from bench.sim.vehicles import VEHICLES

        return VEHICLES[args.vehicle]()
    path = Path(args.description)
    if not path.is_file():
        raise FileNotFoundError(f"--description {path}: no such file")
    try:
        description = json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"--description {path}: not JSON ({exc})") from None
    if not isinstance(description, dict):
        raise ValueError(f"--description {path}: expected a JSON object (docs/FLIGHT_LOG.md)")
    return description


def _check_outputs(args) -> None:
    for opt, path in (("--out", args.out), ("--key", args.key)):
        if path is not None and Path(path).is_dir():
            raise ValueError(f"{opt} {path}: is a folder; give a file name")


def main(args):
    from bench.commands.effect_args import check_effects, read_effects
    from bench.sim.flight_log import validate_log, write_flight_log
    from bench.sim.log_description import DescriptionError, resolve
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import Clocks

    _check_outputs(args)
    description = _description(args)
    try:
        desc = resolve(description)
    except DescriptionError as exc:
        raise ValueError(f"--description {args.description}: {exc}" if args.description else str(exc)) from None
    if args.engine == "basilisk":
        from bench.sim.basilisk_sim import EFFECTS_HERE as known
    else:
        from bench.sim.vehicle_sim import KNOWN as known
    effects = check_effects(read_effects(args.effects), desc, known)
    if args.clocks == "as-real-logs":
        from bench.campaigns.gap.validate_vehicle import clocks_for

        clocks = clocks_for(args.seed)
    else:
        clocks = Clocks()
    plan = characterisation_plan(description, seed=args.seed)
    t0 = time.time()
    if args.engine == "basilisk":
        from bench.sim.basilisk_sim import simulate
    else:
        from bench.sim.vehicle_sim import simulate
    log, key = simulate(description, plan, effects, seed=args.seed, clocks=clocks, with_truth=not args.no_truth)
    log.config = dict(log.config or {}, engine=args.engine, manoeuvres=args.manoeuvres)
    problems = validate_log(log)
    if problems:
        raise ValueError("the simulated log does not validate: " + "; ".join(str(x) for x in problems[:5]))
    write_flight_log(args.out, log)
    if args.key:
        Path(args.key).parent.mkdir(parents=True, exist_ok=True)
        Path(args.key).write_text(json.dumps(dict(key, engine=args.engine), indent=1) + "\n")
    n = log.streams["imu"]["t_s"].size
    print(
        f"{args.out}: {args.engine} engine, {len(plan)} runs, {n} IMU samples, "
        f"{log.streams['pose']['t_capture_s'].size} poses, {time.time() - t0:.1f} s"
    )
    return 0
