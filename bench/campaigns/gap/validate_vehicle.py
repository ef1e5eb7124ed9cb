"""Blind validation on logs of another vehicle, written as a user's logs are:
``proxops validate-gap --vehicle 12kg``.

The logs are flown by the 12 kg, twelve-thruster inspector of
bench/sim/vehicles.py through its characterisation (bench/sim/plans.py: every
thruster alone, pulse-width modulated, then a coast; three runs), with time
stamps as real logs have them: IMU samples 20 Hz with 5 % jitter and 2 %
dropped, pose captures anywhere between IMU samples on a clock 0.25 s off
the IMU's, a stated known latency; one run in ten has no valves stream. The
campaign is drawn, pre-registered and scored exactly as the bench vehicle's
(bench/campaigns/gap/validate.py): null, in-library and out-of-library runs at 1x and
2x each run's own minimum detectable size (bench/campaigns/gap/detectable.py with this
vehicle's open-loop flight), keys hashed before any diagnosis.

Thresholds: a null calibration of this vehicle's flight family
(``calibrate``: the same generator with nothing unmodelled, Frechet tails as
bench/gap/log_null.py), stored in bench/gap/data/null_calibration_12kg.json
with the description it holds for; the diagnosis refuses it for a log of
any other vehicle or sensors.

Effects that the vehicle simulator does not produce (a drifting IMU clock,
LED occlusion, a lens) are not drawn.
"""

from __future__ import annotations

import json
import time

import numpy as np

from bench.campaigns.gap.validate import FRACTIONS, SCALES, new_campaign, score, sized_and_diagnosed
from bench.gap.null import DATA

VEHICLE = "12kg"
CAL_PATH = DATA.with_name("null_calibration_12kg.json")  # run-time data, beside the other null calibrations
NO_VALVES_FRACTION = 0.1
IN_LIBRARY = (
    "accel_bias",
    "camera_latency",
    "camera_lever_arm",
    "com_offset",
    "differential_drag",
    "differential_j2",
    "gyro_bias",
    "gyro_scale",
    "host_eccentricity",
    "imu_misalignment",
    "mass_depletion",
    "thrust_loss",
    "thruster_misalignment",
)
OUT_OF_LIBRARY = ("flex_mode", "fuel_slosh")


def description() -> dict:
    from bench.sim.vehicles import VEHICLES

    return VEHICLES[VEHICLE]()


def clocks_for(seed: int):
    from bench.sim.vehicle_sim import Clocks

    rng = np.random.default_rng([int(seed), 0xC10C])
    return Clocks(
        imu_jitter_s=0.05 * 0.05,
        imu_drop_frac=0.02,
        pose_phase_s=float(rng.uniform(0.05, 0.95)),
        pose_jitter_s=0.005,
        pose_delay_s=0.2,
    )


def unit_draw(rng, name: str, k: int) -> list:
    """A draw at size 1 for a vehicle with k thrusters (per-valve effects sized to it)."""
    from bench.sim.effects import EFFECTS

    if name == "thrust_loss":
        u = rng.uniform(0.2, 1.0, k)
        return (u / np.sqrt(np.mean(u**2))).tolist()
    if name == "thruster_misalignment":
        v = rng.normal(size=(k, 3))
        v /= np.sqrt(np.mean(np.sum(v**2, axis=1)))
        return v.ravel().tolist()
    return [float(x) for x in EFFECTS[name].draw_fn(rng, 1.0)]


def simulate_key(key: dict, effects: dict | None = None):
    """The log of ``key``'s run (with ``effects``, default the key's)."""
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import simulate

    desc = description()
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=key["seed"]),
        key["effects"] if effects is None else effects,
        seed=key["seed"],
        clocks=clocks_for(key["seed"]),
        with_truth=False,
    )
    if key.get("no_valves"):
        log.streams.pop("valves")
    log.config = {}
    return log


def draw_campaign(n_runs: int, seed: int) -> list:
    rng = np.random.default_rng(seed)
    k = len(description()["vehicle"]["thrusters"])
    n_null = int(round(FRACTIONS["null"] * n_runs))
    n_out = int(round(FRACTIONS["out_of_library"] * n_runs))
    n_in = n_runs - n_null - n_out
    plan = [("null", None, 0.0)] * n_null
    plan += [("in_library", IN_LIBRARY[i % len(IN_LIBRARY)], SCALES[(i // len(IN_LIBRARY)) % 2]) for i in range(n_in)]
    plan += [
        ("out_of_library", OUT_OF_LIBRARY[i % len(OUT_OF_LIBRARY)], SCALES[(i // len(OUT_OF_LIBRARY)) % 2])
        for i in range(n_out)
    ]
    keys = []
    for run, j in enumerate(rng.permutation(len(plan))):
        cat, eff, scale = plan[j]
        unit = None if eff is None else unit_draw(rng, eff, k)
        keys.append(
            {
                "run": run,
                "seed": int(rng.integers(0, 2**31)),
                "category": cat,
                "effect": eff,
                "scale": scale,
                "unit": unit,
                "effects": {},
                "vehicle": VEHICLE,
                "no_valves": bool(rng.uniform() < NO_VALVES_FRACTION),
            }
        )
    return keys


def size_run(key, calibration):
    """The key of one drawn run with its effect's size: ``scale`` times the
    smallest size the diagnosis detects on this run's flight by the bench's
    plant (``calibration`` thresholding it), never beyond what the vehicle
    can carry; unchanged for an effect-free run."""
    from bench.campaigns.gap.detectable import min_detectable_size
    from bench.sim.effects import EFFECTS, max_size_for
    from bench.sim.log_description import resolve

    key = dict(key)
    if key["effect"] is None:
        return key
    spec = EFFECTS[key["effect"]]
    top = max_size_for(key["effect"], resolve(description()))

    def sim(effects, scripts=None):
        return simulate_key(key, effects), None

    md = min_detectable_size(key["seed"], key["effect"], key["unit"], 0.0, calibration, simulate=sim, max_size=top)
    key["min_detectable"] = md["size"]
    key["detectable"] = md["detectable"]
    key["lambda_at_min_detectable"] = md.get("lambda_at_size")
    size = key["scale"] * md["size"] if md["detectable"] else top
    size = float(min(size, top))
    key["effects"] = {key["effect"]: [float(x) for x in spec.at(key["unit"], size)]}
    key["size"] = size
    return key


def diagnose_run(key, calibration, simulate=None, source: str = "the 12 kg vehicle's null calibration", null_runs=None):
    """The diagnosis of one run's log, scored against its key: the answer's
    verdict and ranking, the forced fits of the true and of a wrong
    candidate, and the separability of the key's effect. ``simulate(key,
    effects)`` flies the key's run (default: this vehicle on the bench's
    plant); ``calibration`` None makes one for the log (``null_runs`` runs),
    ``source`` names it in the answer."""
    simulate = simulate or simulate_key
    from bench.campaigns.gap.separability import separability_of_logs
    from bench.campaigns.gap.validate import forced_fit
    from bench.gap.candidates import candidates_of
    from bench.gap.diagnose import diagnose, public

    t0 = time.time()
    log = simulate(key)
    t_sim = time.time() - t0
    res = diagnose(log, calibration=calibration, calibration_source=source, calibration_runs=null_runs)
    pub = public(res)
    out = {
        "run": key["run"],
        "gap_detected": pub["gap_detected"],
        "verdict": pub["verdict"],
        "top1": pub["attribution"][0]["effect"] if pub["attribution"] else None,
        "ranking": [r["effect"] for r in pub["attribution"]],
        "map_max_abs_z": pub["statistics"]["map_max_abs_z"],
        "screen_logp_max": pub["statistics"]["screen_logp_max"],
        "not_examined": pub["examined"]["not_examined"],
        "t_sim_s": t_sim,
        "t_diagnose_s": pub["elapsed_s"],
    }
    it = res["_internal"]
    eff = key["effect"]
    cands = candidates_of(it["d"])
    if key["category"] == "in_library":
        out["true_fit"] = forced_fit(it, eff)
        wrong = [n for n in cands if n != eff]
        w = wrong[np.random.default_rng(key["seed"]).integers(len(wrong))]
        out["wrong_fit"] = {"effect": w, **forced_fit(it, w)}
    if eff is not None:
        sep = separability_of_logs(simulate(key, {}), log, eff, key["category"] == "in_library")
        out["separability"] = {k: sep.get(k) for k in ("lambda", "closest", "delta2_min", "separable")}
    return out


def load_calibration() -> dict:
    if not CAL_PATH.exists():
        raise FileNotFoundError(
            f"no null calibration for the {VEHICLE} vehicle (python -m bench.commands.null_calibration --vehicle 12kg)"
        )
    return json.loads(CAL_PATH.read_text())


def run_campaign(
    n_runs: int, seed: int, out: str | None, workers: int | None = None, progress: bool = True, campaign=None
) -> dict:
    cal = load_calibration()
    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    keys, answers, hashes, info = sized_and_diagnosed(
        campaign,
        draw_campaign(n_runs, seed),
        size_run,
        diagnose_run,
        cal,
        out,
        {"seed": seed, "runs": n_runs, "vehicle": VEHICLE},
        "validate-gap",
    )
    res = score(keys, answers)
    no_valves = [(k, a) for k, a in zip(keys, answers) if k["no_valves"]]
    res["no_valves_stream"] = {
        "n": len(no_valves),
        "said_dynamics_not_examined": int(
            sum(any(x.startswith("dynamics") for x in a["not_examined"]) for _, a in no_valves)
        ),
        "answers": [
            {"effect": k["effect"], "verdict": a["verdict"] if a["gap_detected"] else "no_gap", "top1": a["top1"]}
            for k, a in no_valves
        ],
    }
    res.update(
        {
            "seed": seed,
            "vehicle": VEHICLE,
            "workers": workers,
            "elapsed_s": time.time() - t0,
            "campaign": info,
            "calibration": {"runs": cal.get("runs"), "thresholds": cal.get("thresholds")},
            "keys_match_preregistration": True,
            "key_sha256": hashes,
            "keys": keys,
            "answers": answers,
            "command": f"proxops validate-gap --vehicle {VEHICLE} --runs {n_runs} --seed {seed}",
        }
    )
    return res


def _null_stats(seed: int) -> dict:
    from bench.gap.detection import null_statistics

    t0 = time.time()
    key = {"seed": int(seed), "effects": {}, "no_valves": False}
    return {"seed": int(seed), **null_statistics(simulate_key(key)), "elapsed_s": time.time() - t0}


def calibrate(runs: int, seed: int, workers: int | None = None, progress: bool = True, campaign=None) -> dict:
    """The null calibration of this vehicle's flight family."""
    from bench.gap.log_null import FA_EACH, frechet_threshold
    from bench.runner.runner import all_failed, failures, results
    from bench.sim.log_description import resolve

    campaign = new_campaign(campaign, workers, progress)
    t0 = time.time()
    seeds = [int(s) for s in np.random.default_rng(seed).integers(0, 2**31, runs)]
    recs = campaign.map(
        "null", _null_stats, seeds, idents=[{"seed": s} for s in seeds], label=f"null calibration ({VEHICLE})"
    )
    all_failed(recs)
    rows = [r for r in results(recs) if r is not None]
    if not rows:
        raise ValueError("no finished null runs")
    z = np.array([r["map_max_abs_z"] for r in rows])
    b = np.array([r["screen_logp"] for r in rows])
    thr = {"map_max_abs_z": frechet_threshold(z), "screen_logp": frechet_threshold(b)}
    desc = description()
    resolve(desc)
    return {
        "thresholds": thr,
        "method": "Frechet tail per statistic (bench/gap/log_null.py)",
        "false_alarm_target_each": FA_EACH,
        "runs": len(rows),
        "seed": int(seed),
        "false_alarm_rate": float(np.mean((z > thr["map_max_abs_z"]) | (b > thr["screen_logp"]))),
        "manoeuvres": "characterisation",
        "description": desc,
        "vehicle": VEHICLE,
        "null_map_max_abs_z": z.tolist(),
        "null_screen_logp": b.tolist(),
        "elapsed_s": time.time() - t0,
        **({"failed_runs": failures(recs)} if failures(recs) else {}),
        "command": f"python -m bench.commands.null_calibration --vehicle 12kg --runs {runs} --seed {seed}",
    }
