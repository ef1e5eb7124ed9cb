"""Which manoeuvre tells thruster misalignment from thrust loss, measured.

In docking the two are near-indistinguishable (43 of 46 misalignment runs
below the separability distance in the docking campaign of
docs/results/2026-11-25-docking-seed2030.md; the manoeuvre's figures:
docs/results/2026-11-24-separating-manoeuvre.md). The reason is in the
dynamics channel (bench/gap/dyn.py): its gyro rows carry the accumulated
torque impulse error, and a rate change persists until the run ends. A
nozzle tilt turns valve i's torque across its nominal direction (for this
vehicle r_i is perpendicular to d_i, so a tilt about r_i gives a torque
along d_i, a loss one along r_i x d_i); but the later firings of the other
valves, each with its own loss, rebuild the same accumulated rate, and only
the short stretch between valve i's firing and the next firings tells the
two apart.

A characterisation that holds each rate change through a coast does: each
valve fired alone, then no firing until the segment ends (8 segments, one
per valve, each a short run of its own). This module measures, on the same
simulated vehicle and sensors, the separability (bench/campaigns/gap/separability.py:
the signature's distance delta2 from everything the closest competitor can
produce, 10.8 needed for 95 % between two hypotheses) in docking and in
that characterisation, at the same effect:

    python -m bench.campaigns.gap.characterise --effect thruster_misalignment --size 0.004 --seeds 3

Both lambda (the signature's energy) and delta2 grow as size^2, so the
size at which the characterisation separates is size * sqrt(10.8 / delta2).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from bench.sim.plans import scripts_duration_s, single_valve_scripts

RIVAL = {"thruster_misalignment": "thrust_loss", "thrust_loss": "thruster_misalignment"}


def compare(seed: int, effect: str, size: float, fire_s: float, coast_s: float, docking_s: float = 120.0) -> dict:
    """delta2 of ``effect`` at ``size`` (a random direction from ``seed``) in
    the docking run of ``seed`` and in the single-valve characterisation."""
    from bench.campaigns.gap.separability import separability
    from bench.sim.effects import EFFECTS

    spec = EFFECTS[effect]
    params = [float(x) for x in spec.draw_fn(np.random.default_rng(seed), size)]
    effects = {effect: params}
    dock = separability(seed, effect, effects, docking_s, True)
    scripts = single_valve_scripts(fire_s, coast_s)
    # duration: long enough for every script (each run also waits for its first pose)
    char = separability(seed, effect, effects, scripts_duration_s(scripts) + 8 * 5.0, True, scripts=scripts)
    rival = RIVAL[effect]
    out = {"seed": seed, "effect": effect, "size": size}
    for name, r in (("docking", dock), ("characterisation", char)):
        lam, d2 = r["lambda"], r["delta2_min"]
        out[name] = {
            "lambda": lam,
            "closest": r["closest"],
            "delta2": d2,
            f"delta2_{rival}": r["delta2"][rival],
            "fraction": d2 / lam if lam > 0 else float("nan"),
            "size_to_separate": size * float(np.sqrt(10.8 / d2)) if d2 > 0 else float("inf"),
        }
    out["characterisation"]["duration_s"] = scripts_duration_s(scripts)
    out["docking"]["duration_s"] = docking_s
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.campaigns.gap.characterise", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--effect", default="thruster_misalignment", choices=("thruster_misalignment", "thrust_loss"))
    ap.add_argument("--size", type=float, default=0.004, help="effect size (RMS angle [rad] or RMS loss [1])")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed0", type=int, default=1)
    ap.add_argument("--fire", type=float, default=2.0, help="seconds each valve fires alone")
    ap.add_argument("--coast", type=float, default=10.0, help="seconds without firing after it")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = []
    print(
        f"{a.effect} at size {a.size:g}; characterisation: each valve alone {a.fire:g} s, then {a.coast:g} s coast",
        file=sys.stderr,
    )
    print(
        f"seed | run | s | lambda | closest | delta2 | delta2/lambda | size for delta2 = 10.8 | "
        f"delta2 against {RIVAL[a.effect]}"
    )
    for seed in range(a.seed0, a.seed0 + a.seeds):
        r = compare(seed, a.effect, a.size, a.fire, a.coast)
        rows.append(r)
        for name in ("docking", "characterisation"):
            x = r[name]
            print(
                f"{seed} | {name} | {x['duration_s']:.0f} | {x['lambda']:.1f} | {x['closest']} | {x['delta2']:.2f} | "
                f"{x['fraction']:.3f} | {x['size_to_separate']:.3g} | {x['delta2_' + RIVAL[a.effect]]:.2f}",
                flush=True,
            )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(
                {
                    "command": "python -m bench.campaigns.gap.characterise " + " ".join(argv or sys.argv[1:]),
                    "rows": rows,
                },
                f,
                indent=1,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
