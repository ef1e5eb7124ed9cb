"""The committed null calibrations, made again (not a ``proxops`` command:
the maintainers' command line of the campaigns that make them):

    python -m bench.commands.null_calibration --runs 1000 --seed 1000 --workers 2
    python -m bench.commands.null_calibration --runs 1000 --seed 1001 --manoeuvres docking+characterisation
    python -m bench.commands.null_calibration --vehicle 12kg --runs 200 --seed 1200

The bench inspector's docking logs (and docking then its characterisation):
bench/campaigns/gap/null_calibration.py, written to bench/gap/null.py's
files; the 12 kg inspector's flight family (Frechet tails):
bench/campaigns/gap/validate_vehicle.py, written to its CAL_PATH. Each run
is a Dask task kept in a results store as it finishes (docs/CAMPAIGNS.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bench.commands.campaign_args import add_campaign_arguments, campaign_from

DEFAULTS = {"3kg": (1000, 1000), "12kg": (200, 1200)}  # vehicle -> (runs, seed)


def parser() -> argparse.ArgumentParser:
    from bench.gap.null import DATA_BY_MANOEUVRES

    ap = argparse.ArgumentParser(description="Null calibration of the gap diagnoser")
    ap.add_argument("--vehicle", default="3kg", choices=tuple(DEFAULTS), help="3kg: the bench inspector's logs")
    ap.add_argument("--runs", type=int, default=None, help="default: 1000 (3kg), 200 (12kg)")
    ap.add_argument("--seed", type=int, default=None, help="default: 1000 (3kg), 1200 (12kg)")
    ap.add_argument("--duration", type=float, default=120.0, help="3kg: simulated seconds of docking")
    ap.add_argument(
        "--manoeuvres",
        default="docking",
        choices=tuple(DATA_BY_MANOEUVRES),
        help="3kg: what the null logs fly (bench/sim/plans.py)",
    )
    ap.add_argument("--out", default=None, help="3kg: default the committed calibration for --manoeuvres")
    add_campaign_arguments(ap)
    return ap


def bench_inspector(a) -> None:
    from bench.campaigns.gap.null_calibration import calibrate
    from bench.gap.null import DATA_BY_MANOEUVRES

    campaign = campaign_from(
        a, "null-calibration", {"runs": a.runs, "seed": a.seed, "duration_s": a.duration, "manoeuvres": a.manoeuvres}
    )
    seeds = np.random.default_rng(a.seed).integers(0, 2**31, a.runs)
    cal = calibrate(seeds, a.duration, manoeuvres=a.manoeuvres, campaign=campaign)
    cal["command"] = (
        f"python -m bench.commands.null_calibration --runs {a.runs} --seed {a.seed} --duration {a.duration:g}"
        + (f" --manoeuvres {a.manoeuvres}" if a.manoeuvres != "docking" else "")
    )
    out = Path(a.out) if a.out else DATA_BY_MANOEUVRES[a.manoeuvres]
    if a.summarise_only and cal["runs"] < a.runs:
        print(f"{cal['runs']} of {a.runs} runs stored: {out} left as it is")
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(cal, indent=1) + "\n")
    print(f"thresholds {cal['thresholds']}, false-alarm rate {cal['false_alarm_rate']:.3f} over {cal['runs']} runs")


def vehicle_12kg(a) -> None:
    from bench.campaigns.gap.validate_vehicle import CAL_PATH, VEHICLE, calibrate

    campaign = campaign_from(a, f"null-calibration-{VEHICLE}", {"runs": a.runs, "seed": a.seed})
    cal = calibrate(a.runs, a.seed, campaign=campaign)
    if a.summarise_only and cal["runs"] < a.runs:
        print(f"{cal['runs']} of {a.runs} runs stored: {CAL_PATH} left as it is")
    else:
        CAL_PATH.write_text(json.dumps(cal, indent=1) + "\n")
    print(
        f"thresholds {cal['thresholds']}, false-alarm rate {cal['false_alarm_rate']:.3f} over {cal['runs']} runs, "
        f"{cal['elapsed_s']:.0f} s"
    )


def main(argv=None):
    a = parser().parse_args(argv)
    runs, seed = DEFAULTS[a.vehicle]
    a.runs = runs if a.runs is None else a.runs
    a.seed = seed if a.seed is None else a.seed
    (vehicle_12kg if a.vehicle == "12kg" else bench_inspector)(a)


if __name__ == "__main__":
    main()
