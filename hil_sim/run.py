"""The HIL loop: the docking scenario with its navigation running in the
flight executable behind a pseudo-terminal link.

The bench (plant, sensors, controller) runs in this process; every IMU
sample, pose and reset crosses the link as a CCSDS packet, and the
controller steers on the estimate that comes back as telemetry. Lockstep
mode runs as fast as the link answers; real-time mode paces the loop at the
IMU rate by the wall clock. A run longer than one docking chains docking
runs (each one a cmd_reset of the flight filter, time tags running on).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from bench.sim.scenario_docking import ScenarioConfig, errors_from_first_update, nav_config, run_docking
from hil_sim.faults import FaultConfig
from hil_sim.link_nav import LinkNav
from hil_sim.pty_link import BAUD, open_link


@dataclass
class HilConfig:
    duration_s: float = 60.0
    realtime: bool = False
    seed: int = 0
    faults: FaultConfig = field(default_factory=FaultConfig)
    step_timeout_s: float = 0.05
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    # Send each firing interval's valve command so the flight app's thruster
    # learner learns (one more packet up, tm_learner down, per firing step).
    learner: bool = False
    # A flight computer on this serial port instead of fsw_node on a
    # pseudo-terminal (hil_sim/pty_link.py, DeviceLink).
    device: str | None = None
    baud: int = BAUD


class Pacer:
    """Holds the loop to the wall clock in real-time mode."""

    def __init__(self, realtime: bool, t_offset: float, wall0: float):
        self.realtime = realtime
        self.t_offset = t_offset
        self.wall0 = wall0
        self.overruns = 0

    def __call__(self, t_s: float):
        if not self.realtime:
            return
        target = self.wall0 + self.t_offset + t_s
        delay = target - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        elif delay < -0.1:
            self.overruns += 1


def run_hil(cfg: HilConfig, progress=None) -> dict:
    """Runs docking scenarios over the link until cfg.duration_s of
    simulated time have passed. Returns the runs, link statistics and timing."""
    link = open_link(faults_up=cfg.faults, faults_down=cfg.faults, seed=cfg.seed, device=cfg.device, baud=cfg.baud)
    nav = LinkNav(link, step_timeout_s=cfg.step_timeout_s, send_valves=cfg.learner)
    runs = []
    wall0 = time.perf_counter()
    t_done = 0.0
    pacers = []
    try:
        k = 0
        while t_done < cfg.duration_s - 1e-9:
            sc = ScenarioConfig(
                **{**cfg.scenario.__dict__, "t_max_s": min(cfg.scenario.t_max_s, cfg.duration_s - t_done)}
            )
            nav.time_offset_s = t_done
            nav.configure_nav(nav_config(sc), t_s=0.0)
            pacer = Pacer(cfg.realtime, t_done, wall0)
            pacers.append(pacer)
            run = run_docking(cfg.seed + k, sc, nav=nav, on_step=pacer)
            # A run not docked when the time left ran out was cut by the
            # end of the HIL run, not failed by the scenario's own limit.
            run.summary.cut_by_duration = bool(
                not run.summary.docked
                and sc.t_max_s < cfg.scenario.t_max_s
                and run.summary.t_end_s >= sc.t_max_s - sc.dt_s
            )
            runs.append(run)
            t_done += float(run.summary.t_end_s) + sc.dt_s
            k += 1
            if progress:
                progress(t_done, cfg.duration_s, run)
    finally:
        wall = time.perf_counter() - wall0
        ended = link.close()
    return link_result(nav, link, runs, wall, t_done, pacers, ended)


def link_result(nav: LinkNav, link, runs: list, wall: float, sim_time: float, pacers: list, ended: dict) -> dict:
    """A HIL run's figures: its runs, timing, step latency and the link's
    statistics on both sides (run_hil's answer)."""
    lat = np.array(nav.step_latency_s) * 1e3
    steps = len(lat)
    return {
        "runs": runs,
        "wall_s": wall,
        "sim_time_s": sim_time,
        "real_time_factor": sim_time / wall if wall > 0 else float("inf"),
        "steps": steps,
        "step_latency_ms": lat,
        "step_latency_p50_ms": float(np.percentile(lat, 50)) if steps else float("nan"),
        "step_latency_p99_ms": float(np.percentile(lat, 99)) if steps else float("nan"),
        "step_timeouts": nav.timeouts,
        "poses_not_sent": nav.poses_not_sent,
        "bad_crc_delivered": nav.delivered_not_sent,
        "packets_sent": nav.packets_sent,
        "bytes_up": link.bytes_up,
        "bytes_down": link.bytes_down,
        "flight_rejected_by_reason": nav.rejected_by_reason(),
        "bench_rejected_by_reason": dict(nav.deframer.rejected),
        "bench_packets_accepted": nav.deframer.accepted,
        "learner_outputs": nav.learner_outputs,
        "faults_up": link.up.counts.__dict__,
        "faults_down": link.down.counts.__dict__,
        "realtime_overruns": sum(p.overruns for p in pacers),
        "flight_telemetry_dropped": (nav.housekeeping or {}).get("tx_dropped"),
        "fsw_node_exit_code": ended["exit_code"],
        "fsw_node_summary": ended["stderr"].strip(),
    }


def nav_errors(runs) -> dict:
    """Largest per-axis position and velocity error of each run from its
    first pose update on."""
    pos, vel = [], []
    for run in runs:
        e = errors_from_first_update(run)
        if len(e.t) == 0:
            continue
        pos.append(float(np.max(np.abs(e.pos))))
        vel.append(float(np.max(np.abs(e.vel))))
    return {"max_pos_err_m": pos, "max_vel_err_mps": vel}
