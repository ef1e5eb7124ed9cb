"""Wall time of one diagnosis of a 10-minute log of the 12 kg inspector
(its characterisation flown again and again, time stamps as real logs have
them), with the committed calibration of its flight family:

    python -m bench.campaigns.gap.perf_diagnose [--minutes 10] [--repeats 3] [--effects JSON]

``--effects`` flies the log with effects (bench/sim/effects.py names and
parameters), so the timing covers the attribution and, with two or more,
the selection of a set. Prints the log's size, the answer and the median
wall time of the repeats.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def long_log(minutes: float, seed: int = 5, effects: dict | None = None):
    from bench.campaigns.gap import validate_vehicle as vv
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import simulate

    desc = vv.description()
    plan = []
    s = seed
    while sum(p.duration_s + 2.0 for p in plan) < 60.0 * minutes:
        plan += characterisation_plan(desc, seed=s)
        s += 1
    log, _ = simulate(desc, plan, effects or {}, seed=seed, clocks=vv.clocks_for(seed), with_truth=False)
    log.config = {}
    return log


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--effects", default="{}", help="effects in the log, e.g. '{\"gyro_bias\": [1e-3, 0, 0]}'")
    a = ap.parse_args(argv)
    import json

    effects = json.loads(a.effects)
    from bench.campaigns.gap import validate_vehicle as vv
    from bench.gap.diagnose import diagnose

    log = long_log(a.minutes, effects=effects)
    cal = vv.load_calibration()
    t = log["imu"]["t_s"]
    times = []
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        r = diagnose(log, calibration=cal, calibration_source="12 kg calibration")
        times.append(time.perf_counter() - t0)
    print(
        f"log: {t[-1] - t[0]:.0f} s, {t.size} IMU samples, {log['pose']['t_capture_s'].size} poses, "
        f"{log['valves']['t_s'].size} valve commands; verdict {r['verdict']}"
        + (f" ({' + '.join(m['effect'] for m in r['effects'])})" if r["effects"] else "")
    )
    print(
        f"diagnosis wall time: median {np.median(times):.1f} s over {a.repeats} (min {min(times):.1f}, "
        f"max {max(times):.1f})"
    )


if __name__ == "__main__":
    main()
