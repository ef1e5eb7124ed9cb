"""Reality logs: docking runs with physical effects switched on, written as
flight logs whose configuration does not reveal the effects.

``simulate_log_with_key(seed, effects, duration_s)`` chains docking runs
(seed, seed + 1, ...; each a fresh approach and a reset of the flight filter,
time tags running on, as hil_sim/run.py does) until ``duration_s`` of
simulated time, drives the flight filter (fsw_bindings.NavUkf) in-process,
and returns the FlightLog (docs/FLIGHT_LOG.md, with the valve stream) and,
apart from it, the key: the effects and their parameters. ``nominal_logs``
gives effect-free logs for null calibration.

The smallest magnitude of each effect that shows as a gap is measured on
these runs by bench/campaigns/detect.py (docs/EFFECTS.md).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np

from bench.sim.effects import EffectSet, true_anomaly_after
from bench.sim.flight_log import FlightLog
from bench.sim.plant import N_RADPS
from bench.sim.scenario_docking import ScenarioConfig, run_docking
from bench.sim.vehicle import Vehicle

DT_S = 0.1


def _scenario(scenario: ScenarioConfig | None, effects: EffectSet | None, t_max_s: float) -> ScenarioConfig:
    base = scenario or ScenarioConfig()
    return ScenarioConfig(**{**base.__dict__, "t_max_s": min(base.t_max_s, t_max_s), "effects": effects or None})


def _effects_at(effects: EffectSet, t_s: float) -> EffectSet:
    """The effects for a run that starts t_s into the log: the host orbit keeps its phase."""
    e = EffectSet(effects)
    if "host_eccentricity" in e and t_s > 0.0:
        ecc, f0 = e["host_eccentricity"]
        e["host_eccentricity"] = [ecc, true_anomaly_after(ecc, f0, N_RADPS * t_s)]
    return e


def simulate_runs(
    seed: int,
    effects: dict | None,
    duration_s: float = 120.0,
    scenario: ScenarioConfig | None = None,
    scripts: list | None = None,
    then_scripts: list | None = None,
) -> list:
    """Docking runs (DockingRun, run_docking) chained to fill duration_s. With
    ``scripts`` (each run's valve configurations, from an earlier call) the
    runs replay those valves open loop, so the chain splits where it did.
    ``then_scripts``: after the docking runs, one run per valve script, open
    loop (a thruster characterisation, bench/campaigns/gap/characterise.py); with
    ``scripts`` they are the last len(then_scripts) of the replayed runs."""
    eff = EffectSet(effects or {})
    then = [list(sc) for sc in then_scripts or []]
    n_dock = None if scripts is None else len(scripts) - len(then)
    runs, t_done, k = [], 0.0, 0
    while t_done < duration_s - 1e-9:
        cfg = _scenario(scenario, _effects_at(eff, t_done) if eff else None, duration_s - t_done)
        if scripts is not None:
            if k >= n_dock:
                break
            cfg = ScenarioConfig(**{**cfg.__dict__, "valve_script": tuple(int(c) for c in scripts[k])})
        run = run_docking(int(seed) + k, cfg)
        runs.append(run)
        t_done += float(run.summary.t_end_s) + cfg.dt_s
        k += 1
    for sc in then if scripts is None else scripts[k:]:
        # Long enough for the script after the wait for the first pose; the run ends with its script.
        cfg = _scenario(scenario, _effects_at(eff, t_done) if eff else None, len(sc) * DT_S + 60.0)
        cfg = ScenarioConfig(**{**cfg.__dict__, "valve_script": tuple(int(c) for c in sc)})
        run = run_docking(int(seed) + k, cfg)
        runs.append(run)
        t_done += float(run.summary.t_end_s) + cfg.dt_s
        k += 1
    return runs


def clock_rate(effects: EffectSet) -> float:
    return 1.0 + float(effects["clock_drift"][0]) if "clock_drift" in effects else 1.0


def runs_to_log(runs: list, config: dict, clock_rate: float = 1.0, with_truth: bool = True) -> FlightLog:
    """Flight log of chained runs, with the valve stream. With a drifting
    IMU clock every stream is tagged by the flight (IMU) clock."""
    from bench.sim.flight_log import runs_to_flight_log

    if clock_rate != 1.0:
        runs = [replace(r, t=r.t * clock_rate) for r in runs]
    log = runs_to_flight_log(runs, config)
    t_v, mask, offset = [], [], 0.0
    for r in runs:
        n = r.config.size
        t_v.append(r.t[:n] + offset)
        mask.append(np.asarray(r.config, dtype=np.int64))
        offset = r.t[-1] + offset + DT_S
    t_v = np.concatenate(t_v) if t_v else np.zeros(0)
    log.streams["valves"] = {
        "t_s": t_v,
        "interval_s": np.full(t_v.size, DT_S * clock_rate),
        "mask": np.concatenate(mask) if mask else np.zeros(0, dtype=np.int64),
    }
    if not with_truth:
        log.streams.pop("truth", None)
    return log


def log_config(seed: int, duration_s: float, scenario: ScenarioConfig | None = None) -> dict:
    """What a user would know about the run: orbit, vehicle, sensor settings (no effects)."""
    sc = scenario or ScenarioConfig()
    v = Vehicle()
    p = sc.profile
    return {
        "source": "proxops reality",
        "seed": int(seed),
        "duration_s": float(duration_s),
        "orbit_radius_m": 6378137.0 + 500e3,
        "dt_imu_s": sc.dt_s,
        "pose_period_s": sc.pose_period_s,
        "vehicle": {"mass_kg": v.mass_kg, "inertia_kgm2": np.diag(v.inertia_kgm2).tolist(), "thrust_n": v.thrust_n},
        "noise": {
            "accel_sigma_mps2": p.accel_sigma_mps2,
            "gyro_sigma_rps": p.gyro_sigma_rps,
            "pose_pos_frac": p.pose_pos_frac,
            "pose_att_sigma_rad": p.pose_att_sigma_rad,
        },
        "gate_chi2": sc.gate_chi2,
    }


def effect_key(seed: int, effects: dict | None, duration_s: float) -> dict:
    e = EffectSet(effects or {})
    body = {"seed": int(seed), "duration_s": float(duration_s), "effects": e.to_json()}
    body["sha256"] = hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()
    return body


def simulate_log_with_key(
    seed: int,
    effects: dict | None,
    duration_s: float = 120.0,
    with_truth: bool = True,
    config_extra: dict | None = None,
    scenario: ScenarioConfig | None = None,
    scripts: list | None = None,
    then_scripts: list | None = None,
):
    """(FlightLog, key): the log carries no trace of the effects; the key
    names them with their parameters (and a sha256 of itself). ``scripts``,
    ``then_scripts``: see simulate_runs."""
    eff = EffectSet(effects or {})
    runs = simulate_runs(seed, eff, duration_s, scenario, scripts, then_scripts)
    cfg = log_config(seed, duration_s, scenario)
    cfg.update(config_extra or {})
    log = runs_to_log(runs, cfg, clock_rate(eff), with_truth)
    return log, effect_key(seed, eff, duration_s)


def simulate_log(
    seed: int,
    effects: dict | None,
    duration_s: float = 120.0,
    with_truth: bool = True,
    config_extra: dict | None = None,
) -> FlightLog:
    return simulate_log_with_key(seed, effects, duration_s, with_truth, config_extra)[0]


def nominal_logs(seeds, duration_s: float = 120.0, with_truth: bool = True) -> list:
    """Effect-free logs (simulated-on-simulated) for null calibration."""
    return [simulate_log(int(s), None, duration_s, with_truth) for s in seeds]
