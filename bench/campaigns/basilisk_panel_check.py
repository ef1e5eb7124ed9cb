"""Is a flexible appendage a thrust loss? The signature of ``flex_mode`` in
each engine (Basilisk's hinged panel, bench/sim/basilisk_sim.py; the bench's
mode, bench/sim/plant.py) and the share of it that the best non-negative
per-thruster thrust loss reproduces.

The signature is the IMU's samples (gyro and accelerometer, noise-free) with
the effect minus without, in units of the described sensor noise; the
thrust-loss columns are the bench's signature of a loss on each thruster
alone (the two engines agree on them to 2e-5, docs/BASILISK.md). Cases:

- the panel as Basilisk flies it, and the same panel started at rest (what
  the thruster pulses alone make it do);
- the panel added on top of the described vehicle as a rigid part, as the
  engine's first mapping did (its mass taken from the hub, its inertia
  added to the described one), flown by Basilisk without a panel: the
  rigid-body error of a panel not taken out of the described inertia;
- the bench's mode, and the same mode started at rest.

    python -m bench.campaigns.basilisk_panel_check --freq 0.139 --amplitude 0.00213 --seed 800763998 [--seconds S] [--json OUT]

flies the 12 kg inspector's characterisation of that seed (or its first S
seconds) and prints the table recorded in docs/BASILISK.md.
"""

from __future__ import annotations

import copy
import time

import numpy as np

from bench.sim.vehicle_sim import Clocks

AT_REST = 1e-12  # a start amplitude that leaves the mode to the thrusters


def panel_added_on_top(description: dict) -> dict:
    """The description of the rigid vehicle the first mapping flew: a hub of
    the described mass less the panel's, at the described centre of mass
    with the described inertia, and the panel (at rest) on it."""
    from bench.sim.basilisk_sim import PANEL_ARM_M, PANEL_MASS_FRACTION

    d = copy.deepcopy(description)
    v = d["vehicle"]
    m = float(v["mass_kg"])
    mp, arm = PANEL_MASS_FRACTION * m, PANEL_ARM_M
    ip = mp * arm * arm / 3.0
    r = np.array([-arm, 0.0, 0.0])  # the panel's centre of mass from the hinge, at the centre of mass

    def parallel(mass, x):
        return mass * (x @ x * np.eye(3) - np.outer(x, x))

    j = np.asarray(v["inertia_kgm2"], float) + np.diag([ip / 10.0, ip, ip]) + parallel(mp, r)
    shift = mp * r / m
    v["com_b_m"] = (np.asarray(v["com_b_m"], float) + shift).tolist()
    v["inertia_kgm2"] = (j - parallel(m, shift)).tolist()
    return d


def _imu(engine: str, description: dict, plan: list, effects: dict) -> np.ndarray:
    from bench.sim import basilisk_sim, vehicle_sim

    if engine == "bench":
        log, _ = vehicle_sim.simulate(description, plan, effects, seed=0, clocks=Clocks(), with_truth=False)
    else:
        log, _ = basilisk_sim.simulate(
            description, plan, effects, seed=0, clocks=Clocks(), with_truth=False, noise=False
        )
    i = log.streams["imu"]
    return np.concatenate([i["omega_bi_b_rps"].ravel(), i["accel_b_mps2"].ravel()])


def panel_projection(description: dict, plan: list, freq_hz: float, amplitude_rad: float) -> dict:
    """Each case's signature energy (sum of squares in noise units) and the
    share of it a non-negative per-thruster thrust loss captures, per stream."""
    from scipy.optimize import nnls

    from bench.campaigns.basilisk_crosscheck import quiet
    from bench.sim.log_description import resolve

    desc = resolve(description)
    k = desc.n_thrusters
    d = quiet(description)
    base = {e: _imu(e, d, plan, {}) for e in ("bench", "basilisk")}
    cols = []
    for i in range(k):
        p = np.zeros(k)
        p[i] = 0.01
        cols.append((_imu("bench", d, plan, {"thrust_loss": p.tolist()}) - base["bench"]) / 0.01)
    s = np.column_stack(cols)
    n = base["bench"].size // 2
    w = np.concatenate([np.full(n, 1.0 / desc.gyro_sigma_rps), np.full(n, 1.0 / desc.accel_sigma_mps2)])
    flex, rest = {"flex_mode": [freq_hz, amplitude_rad]}, {"flex_mode": [freq_hz, AT_REST]}
    cases = {
        "basilisk panel": _imu("basilisk", d, plan, flex) - base["basilisk"],
        "basilisk panel started at rest": _imu("basilisk", d, plan, rest) - base["basilisk"],
        "panel added on top, rigid": _imu("basilisk", panel_added_on_top(d), plan, {}) - base["basilisk"],
        "bench mode": _imu("bench", d, plan, flex) - base["bench"],
        "bench mode started at rest": _imu("bench", d, plan, rest) - base["bench"],
    }
    out = {}
    for name, sig in cases.items():
        out[name] = {}
        for stream, sl in (("gyro", slice(0, n)), ("accel", slice(n, 2 * n)), ("both", slice(0, 2 * n))):
            a, y = s[sl] * w[sl, None], sig[sl] * w[sl]
            loss, _ = nnls(a, y)
            e2 = float(y @ y)
            out[name][stream] = {
                "energy": e2,
                "captured": float(1.0 - np.sum((a @ loss - y) ** 2) / e2) if e2 > 0 else 0.0,
                "loss": loss.tolist(),
            }
    return out


def main(argv=None):
    import argparse
    import json

    from bench.campaigns.basilisk_crosscheck import short_plan
    from bench.sim.basilisk_sim import basilisk_version
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicles import VEHICLES

    ap = argparse.ArgumentParser(description="flex_mode in each engine against a thrust loss")
    ap.add_argument("--freq", type=float, required=True, help="flex_mode frequency (Hz)")
    ap.add_argument("--amplitude", type=float, required=True, help="flex_mode amplitude (rad)")
    ap.add_argument("--seed", type=int, default=0, help="the characterisation plan's seed")
    ap.add_argument("--seconds", type=float, default=None, help="only the first seconds of the first run")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    t0 = time.time()
    desc = VEHICLES["12kg"]()
    plan = short_plan(desc, a.seconds, seed=a.seed) if a.seconds else characterisation_plan(desc, seed=a.seed)
    res = panel_projection(desc, plan, a.freq, a.amplitude)
    print(f"{'case':32s} {'energy':>10s} {'captured':>9s} {'gyro':>9s} {'accel':>9s}  largest loss")
    for name, r in res.items():
        print(
            f"{name:32s} {r['both']['energy']:10.4g} {r['both']['captured']:9.4f} {r['gyro']['captured']:9.4f} "
            f"{r['accel']['captured']:9.4f}  {max(r['both']['loss']):.3f}"
        )
    print(f"{time.time() - t0:.0f} s")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(
                {
                    "freq_hz": a.freq,
                    "amplitude_rad": a.amplitude,
                    "seed": a.seed,
                    "seconds": a.seconds,
                    "basilisk_version": basilisk_version(),
                    "cases": res,
                },
                f,
                indent=1,
            )


if __name__ == "__main__":
    main()
