"""Blind validation on vehicles unlike ours: ``proxops validate-gap --vehicle
random [--engine basilisk]``.

Every run draws its own vehicle (bench/sim/random_vehicle.py: 2 to 50 kg, a
full inertia tensor, 6 to 16 canted valves spanning force and torque, an IMU
at 10 to 50 Hz turned and up to 0.2 m off the centre of mass, a pose
reference point off the centre of mass on its own clock, the centre of mass
off the body origin), its own clocks (jitter, dropped samples, pose captures
between IMU samples, time stamps on a Unix epoch) and flies its
characterisation (bench/sim/plans.py, pulse-width-modulated valves), by the
bench's truth plant or by Basilisk. Nothing about the vehicle is committed:
the diagnosis thresholds each log with the null calibration made for it
(bench/gap/log_null.py), as for a team's first log, and the minimum
detectable size of each run is measured with that calibration on the
engine that flies the run (bench/campaigns/gap/detectable.py): Basilisk's own slosh
and hinged panel move a vehicle otherwise than the bench's at the same
size, so a size found on the bench's flight was below what a Basilisk log
shows (three fuel sloshes undetected at seed 3403).

The draw, pre-registration and scoring are the other campaigns'
(bench/campaigns/gap/validate.py): null, in-library and out-of-library runs at 1x and
2x, keys hashed before any diagnosis. A drifting clock, LED occlusion and a
lens are not flown by the vehicle simulators and are not drawn.
"""

from __future__ import annotations

import time

import numpy as np

from bench.campaigns.gap import validate_vehicle as vv
from bench.campaigns.gap.validate import FRACTIONS, SCALES, new_campaign, score, sized_and_diagnosed

VEHICLE = "random"
ENGINES = ("bench", "basilisk")


def description_of(key: dict) -> dict:
    from bench.sim.random_vehicle import random_description

    return random_description(key["vehicle_seed"])


def clocks_of(key: dict):
    from bench.sim.log_description import resolve
    from bench.sim.random_vehicle import random_clocks

    return random_clocks(key["vehicle_seed"], resolve(description_of(key)).imu_rate_hz)


def simulate_key(key: dict, effects: dict | None = None, engine: str | None = None):
    """The log of ``key``'s run (with ``effects``, default the key's), flown
    by ``engine`` (default the key's)."""
    from bench.sim.plans import characterisation_plan

    engine = engine or key.get("engine", "bench")
    if engine == "basilisk":
        from bench.sim.basilisk_sim import simulate
    else:
        from bench.sim.vehicle_sim import simulate
    desc = description_of(key)
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=key["seed"]),
        key["effects"] if effects is None else effects,
        seed=key["seed"],
        clocks=clocks_of(key),
        with_truth=False,
    )
    if key.get("no_valves"):
        log.streams.pop("valves")
    log.config = {}
    return log


def draw_campaign(n_runs: int, seed: int, engine: str = "bench", null_runs: int | None = None) -> list:
    from bench.sim.random_vehicle import random_description

    rng = np.random.default_rng([seed, 0x7A4D])
    n_null = int(round(FRACTIONS["null"] * n_runs))
    n_out = int(round(FRACTIONS["out_of_library"] * n_runs))
    n_in = n_runs - n_null - n_out
    lib, out = vv.IN_LIBRARY, vv.OUT_OF_LIBRARY
    plan = [("null", None, 0.0)] * n_null
    plan += [("in_library", lib[i % len(lib)], SCALES[(i // len(lib)) % 2]) for i in range(n_in)]
    plan += [("out_of_library", out[i % len(out)], SCALES[(i // len(out)) % 2]) for i in range(n_out)]
    keys = []
    for run, j in enumerate(rng.permutation(len(plan))):
        cat, eff, scale = plan[j]
        vseed = int(rng.integers(0, 2**31))
        k = len(random_description(vseed)["vehicle"]["thrusters"])
        keys.append(
            {
                "run": run,
                "seed": int(rng.integers(0, 2**31)),
                "vehicle_seed": vseed,
                "category": cat,
                "effect": eff,
                "scale": scale,
                "unit": None if eff is None else vv.unit_draw(rng, eff, k),
                "effects": {},
                "vehicle": VEHICLE,
                "engine": engine,
                "no_valves": False,
                **({"null_runs": int(null_runs)} if null_runs else {}),
            }
        )
    return keys


def calibration_of(key: dict) -> dict:
    """The null calibration made for the run's effect-free flight by its
    engine (from the cache once made: the same vehicle, plan and timing
    whatever the effect)."""
    from bench.gap.log_null import DEFAULT_RUNS, calibrate_for_log

    runs = key.get("null_runs", DEFAULT_RUNS)
    return calibrate_for_log(simulate_key(key, {}), runs=runs, progress=False)


def size_one(key: dict, _shared=None) -> dict:
    """The run's effect at its scale times its minimum detectable size,
    measured on its engine's flights of it against its own calibration."""
    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS, max_size_for
    from bench.sim.log_description import resolve

    key = dict(key)
    if key["effect"] is None:
        return key
    cal = calibration_of(key)
    spec = EFFECTS[key["effect"]]
    top = max_size_for(key["effect"], resolve(description_of(key)))

    def sim(effects, scripts=None):
        return simulate_key(key, effects), None

    md = min_detectable_size(key["seed"], key["effect"], key["unit"], 0.0, cal, simulate=sim, max_size=top)
    key.update(
        min_detectable=md["size"], detectable=md["detectable"], lambda_at_min_detectable=md.get("lambda_at_size")
    )
    size = float(min(key["scale"] * md["size"] if md["detectable"] else top, top))
    key["effects"] = {key["effect"]: [float(x) for x in spec.at(key["unit"], size)]}
    key["size"] = size
    return key


def run_one(key: dict, _shared=None) -> dict:
    """The diagnosis of one run's log as a team's first log: thresholded by
    the calibration made for that log (or found in the cache), its making
    included in the answer's wall time."""
    return vv.diagnose_run(key, None, lambda k, e=None: simulate_key(k, e), None, key.get("null_runs"))


def run_campaign(
    n_runs: int,
    seed: int,
    out: str | None,
    engine: str = "bench",
    workers: int | None = None,
    progress: bool = True,
    campaign=None,
    null_runs: int | None = None,
) -> dict:
    if engine not in ENGINES:
        raise ValueError(f"engine {engine!r} is not one of {', '.join(ENGINES)}")
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    keys, answers, hashes, info = sized_and_diagnosed(
        campaign,
        draw_campaign(n_runs, seed, engine, null_runs),
        size_one,
        run_one,
        None,
        out,
        {"seed": seed, "runs": n_runs, "vehicle": VEHICLE, "engine": engine},
        f"validate-gap (random vehicles, {engine} logs)",
    )
    res = score(keys, answers)
    res.update(
        {
            "seed": seed,
            "vehicle": VEHICLE,
            "engine": engine,
            "workers": workers,
            "elapsed_s": time.time() - t0,
            "campaign": info,
            "first_answer_s": _quantiles([a["t_diagnose_s"] for a in answers]),
            "keys_match_preregistration": True,
            "key_sha256": hashes,
            "keys": keys,
            "answers": answers,
            "command": f"proxops validate-gap --vehicle random --engine {engine} --runs {n_runs} --seed {seed}",
        }
    )
    return res


def _quantiles(x: list) -> dict:
    a = np.asarray(x, float)
    if a.size == 0:
        return {}
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)), "max": float(a.max())}
