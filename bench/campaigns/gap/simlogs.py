"""Simulated flight logs for the diagnoser: the bench's docking scenario
written as a flight log (with the valve stream), optionally with the effect
library of bench/sim/reality.py when it is available."""

from __future__ import annotations

import numpy as np

from bench.sim.flight_log import FlightLog


def run_to_log(run, dt_s: float = 0.1, config: dict | None = None) -> FlightLog:
    """The flight log of one docking run, with its valve stream."""
    from bench.sim.flight_log import runs_to_flight_log

    cfg = {"orbit_radius_m": 6378137.0 + 500e3, "dt_imu_s": dt_s, "source": "bench docking"}
    cfg.update(config or {})
    log = runs_to_flight_log([run], cfg)
    n = run.config.size
    log.streams["valves"] = {
        "t_s": np.arange(n) * dt_s,
        "interval_s": np.full(n, dt_s),
        "mask": np.asarray(run.config, dtype=np.int64),
    }
    return log


def docking_log(seed: int, profile=None, t_max_s: float = 120.0) -> FlightLog:
    """One docking run (sensor options through ``profile``, a NoiseProfile)."""
    from bench.sim.scenario_docking import ScenarioConfig, run_docking
    from bench.sim.sensors import NoiseProfile

    prof = profile or NoiseProfile.paper()
    # The filter runs with the nominal (paper) noise: the profile's biases are
    # reality the model does not know about.
    cfg = ScenarioConfig(
        profile=prof,
        t_max_s=t_max_s,
        nav_accel_sigma_mps2=NoiseProfile.paper().accel_sigma_mps2,
        nav_gyro_sigma_rps=NoiseProfile.paper().gyro_sigma_rps,
    )
    return run_to_log(run_docking(seed, cfg))


def reality_available() -> bool:
    try:
        import bench.sim.effects  # noqa: F401
        import bench.sim.reality  # noqa: F401
    except Exception:
        return False
    return True
