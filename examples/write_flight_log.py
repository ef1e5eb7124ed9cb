"""Write a flight log (format version 2) from plain numpy arrays, as a team
with its own vehicle and data would: only numpy, h5py and json, nothing from
this project. docs/FLIGHT_LOG.md is the contract.

    python examples/write_flight_log.py OUT.h5

writes a log of a 12 kg inspector from stand-in arrays (made here by the
project's simulator, in place of your own telemetry), then prints what
`proxops diagnose OUT.h5` would be run on. Replace ``stand_in_arrays`` by
your own.
"""

from __future__ import annotations

import json
import sys

import h5py


def write_log(
    path,
    description: dict,
    imu_t,
    accel,
    gyro,
    pose_t,
    pose_delivered,
    r_hill,
    q_hb,
    r_sigma,
    att_sigma,
    valve_t=None,
    on_time=None,
) -> None:
    """Every array as the format asks: float64 seconds, (N, 3) vectors,
    [w, x, y, z] unit quaternions, one on-time column per described thruster."""
    with h5py.File(path, "w") as h:
        h.attrs["format"] = "proxops-flight-log"
        h.attrs["format_version"] = 2
        h.attrs["quaternion_order"] = "wxyz"
        h.attrs["description_json"] = json.dumps(description)
        h.attrs["config_json"] = json.dumps({"source": "examples/write_flight_log.py"})
        g = h.create_group("imu")
        g["t_s"], g["accel_b_mps2"], g["omega_bi_b_rps"] = imu_t, accel, gyro
        g = h.create_group("pose")
        g["t_capture_s"], g["t_delivered_s"] = pose_t, pose_delivered
        g["r_hill_m"], g["q_hb"] = r_hill, q_hb
        g["r_sigma_m"], g["att_sigma_rad"] = r_sigma, att_sigma
        if valve_t is not None:
            g = h.create_group("valves")
            g["t_s"], g["on_time_s"] = valve_t, on_time


def stand_in_arrays(seed: int = 3):
    """Arrays of a simulated 12 kg inspector with jittered IMU stamps, pose
    captures between IMU samples on a clock of their own, and pulse-width
    modulated valves, standing in for a team's own telemetry."""
    from bench.sim.plans import characterisation_plan
    from bench.sim.vehicle_sim import Clocks, simulate
    from bench.sim.vehicles import inspector_12kg

    desc = inspector_12kg()
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=seed),
        {},
        seed=seed,
        clocks=Clocks(imu_jitter_s=0.002, pose_phase_s=0.537, pose_jitter_s=0.01),
        with_truth=False,
    )
    imu, pose, valves = log["imu"], log["pose"], log["valves"]
    return (
        log.description,
        imu["t_s"],
        imu["accel_b_mps2"],
        imu["omega_bi_b_rps"],
        pose["t_capture_s"],
        pose["t_delivered_s"],
        pose["r_hill_m"],
        pose["q_hb"],
        pose["r_sigma_m"],
        pose["att_sigma_rad"],
        valves["t_s"],
        valves["on_time_s"],
    )


if __name__ == "__main__":
    import time

    out = sys.argv[1] if len(sys.argv) > 1 else "flight_log_v2.h5"
    # The stand-in flight can take the simulator a while on a first run; say so first.
    print(
        "simulating a 12 kg inspector's characterisation as stand-in arrays "
        "(your own arrays replace stand_in_arrays)...",
        file=sys.stderr,
        flush=True,
    )
    t0 = time.perf_counter()
    arrays = stand_in_arrays()
    print(f"simulated in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    write_log(out, *arrays)
    print(f"wrote {out}; diagnose it with: proxops diagnose {out} --report report_v2")
