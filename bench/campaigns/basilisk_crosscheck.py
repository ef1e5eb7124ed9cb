"""The bench's plant (bench/sim/vehicle_sim.py) against Basilisk
(bench/sim/basilisk_sim.py): the same described vehicle, the same valve
commands and time stamps, the sensors without noise.

- ``null_agreement``: with no effect, the largest difference of the truth
  (Hill-frame position, velocity, attitude, rate) and of the IMU samples.
- ``signature_agreement``: with one effect, its signature in each engine
  (the sensor streams with the effect minus without) and how far the two
  signatures differ, as a share of the bench's signature (RMS over the log).
- ``impulse_check``: one thruster pulse through Basilisk's thruster model,
  commanded by its own on-time countdown and by explicit switches, against
  the commanded impulse; the IMU's delta-v and delta-angle against it.

    python -m bench.campaigns.basilisk_crosscheck [--vehicle 12kg] [--seconds 20]

prints the table recorded in docs/BASILISK.md.
"""

from __future__ import annotations

import time

import numpy as np

from bench.sim.vehicle_sim import Clocks

# The in-library effects at the sizes the cross-check flies (large enough to
# stand far above both engines' numerical floor), and the stream that shows each.
CROSSCHECK_EFFECTS = {
    "thrust_loss": ([0.05], "accel_b_mps2"),
    "thruster_misalignment": (None, "omega_bi_b_rps"),  # 0.02 rad on every nozzle, drawn per vehicle
    "com_offset": ([0.004, -0.003, 0.005], "omega_bi_b_rps"),
    "mass_depletion": ([2e-3], "accel_b_mps2"),
    "accel_bias": ([3e-4, -2e-4, 1e-4], "accel_b_mps2"),
    "gyro_bias": ([5e-4, -3e-4, 2e-4], "omega_bi_b_rps"),
    "gyro_scale": ([0.05, -0.03, 0.04], "omega_bi_b_rps"),
    "imu_misalignment": ([0.02, -0.01, 0.015], "accel_b_mps2"),
    "camera_latency": ([0.3], "pose_r"),
    "camera_lever_arm": ([0.02, -0.03, 0.01], "pose_r"),
    "host_eccentricity": ([0.01, 0.7], "truth_r"),
    "differential_drag": ([20.0, 5.0], "accel_b_mps2"),
    "differential_j2": ([1.08262668e-3], "truth_r"),
}


def quiet(description: dict) -> dict:
    """The description with (practically) noise-free IMU: 1e-15 sigma."""
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in description.items()}
    imu = d.setdefault("imu", {})
    for k in ("accel_noise_density_mps2_rthz", "gyro_noise_density_rps_rthz"):
        imu.pop(k, None)
    imu["accel_sigma_mps2"] = imu["gyro_sigma_rps"] = 1e-15
    return d


def short_plan(description: dict, seconds: float, seed: int = 3) -> list:
    """The first ``seconds`` of the first run of the characterisation plan
    (bench/sim/plans.py): two thrusters fired alone, with coasts."""
    from bench.sim.plans import characterisation_plan

    seg = characterisation_plan(description, seed=seed, fire_s=1.0, coast_s=2.0, per_run=2, passes=1)[0]
    keep = seg.cmd_t_s + seg.cmd_on_s.max(axis=1) <= seconds
    seg.cmd_t_s, seg.cmd_on_s = seg.cmd_t_s[keep], seg.cmd_on_s[keep]
    seg.duration_s = float(seconds)
    return [seg]


def _streams(log) -> dict:
    i, p, t = log.streams["imu"], log.streams["pose"], log.streams["truth"]
    return {
        "accel_b_mps2": i["accel_b_mps2"],
        "omega_bi_b_rps": i["omega_bi_b_rps"],
        "pose_r": p["r_hill_m"],
        "truth_r": t["r_hill_m"],
        "truth_v": t["v_hill_mps"],
        "truth_q": t["q_hb"],
        "truth_w": t["omega_bi_b_rps"],
    }


def _fly(engine: str, description: dict, plan: list, effects: dict) -> dict:
    from bench.sim import basilisk_sim, vehicle_sim

    clocks = Clocks(pose_period_s=0.5, pose_phase_s=0.4)
    if engine == "bench":
        log, _ = vehicle_sim.simulate(description, plan, effects, seed=0, clocks=clocks)
        # The bench's pose carries its noise: take it out with the same seed's null noise.
        return _streams(log)
    log, _ = basilisk_sim.simulate(description, plan, effects, seed=0, clocks=clocks, noise=False)
    return _streams(log)


def _noise_free_bench_pose(description, plan, effects) -> np.ndarray:
    """The bench's pose without noise: its truth at the captures, moved to the reference point."""
    from bench.sim import vehicle_sim

    clocks = Clocks(pose_period_s=0.5, pose_phase_s=0.4)
    log, _ = vehicle_sim.simulate(description, plan, effects, seed=0, clocks=clocks, noise_scale=0.0)
    return log.streams["pose"]["r_hill_m"]


def null_agreement(description: dict, plan: list) -> dict:
    d = quiet(description)
    b, k = _fly("bench", d, plan, {}), _fly("basilisk", d, plan, {})
    b["pose_r"] = _noise_free_bench_pose(d, plan, {})
    res = {}
    for f in ("truth_r", "truth_v", "truth_w", "accel_b_mps2", "omega_bi_b_rps", "pose_r"):
        res[f] = {"max_abs_diff": float(np.max(np.abs(b[f] - k[f]))), "max_abs": float(np.max(np.abs(b[f])))}
    # Attitude: the angle between the two engines' q_hb.
    dots = np.abs(np.sum(b["truth_q"] * k["truth_q"], axis=1))
    res["truth_q"] = {"max_angle_rad": float(np.max(2.0 * np.arccos(np.clip(dots, 0.0, 1.0))))}
    return res


def effect_params(name: str, n_thrusters: int) -> list:
    p, _ = CROSSCHECK_EFFECTS[name]
    if name == "thruster_misalignment":
        v = np.random.default_rng(11).normal(size=(n_thrusters, 3))
        v *= 0.02 / np.linalg.norm(v, axis=1)[:, None]
        return v.ravel().tolist()
    return list(p)


def signature_agreement(
    description: dict, plan: list, name: str, nulls: dict | None = None, stream: str | None = None
) -> dict:
    """The effect's signature in each engine and their difference as a share
    of the bench's signature, on the stream that shows it (``nulls``: each
    engine's streams without the effect, when already flown)."""
    k = len(description["vehicle"]["thrusters"])
    params = effect_params(name, k)
    stream = stream or CROSSCHECK_EFFECTS[name][1]
    d = quiet(description)
    eff = {name: params}
    if nulls is None:
        nulls = {e: _fly(e, d, plan, {}) for e in ("bench", "basilisk")}
        nulls["bench"]["pose_r"] = _noise_free_bench_pose(d, plan, {})
    with_eff = {e: _fly(e, d, plan, eff) for e in ("bench", "basilisk")}
    with_eff["bench"]["pose_r"] = _noise_free_bench_pose(d, plan, eff)
    sig = {e: with_eff[e][stream] - nulls[e][stream] for e in ("bench", "basilisk")}
    rms_b = float(np.sqrt(np.mean(sig["bench"] ** 2)))
    rms_d = float(np.sqrt(np.mean((sig["basilisk"] - sig["bench"]) ** 2)))
    return {
        "effect": name,
        "params": params,
        "stream": stream,
        "signature_rms": rms_b,
        "basilisk_signature_rms": float(np.sqrt(np.mean(sig["basilisk"] ** 2))),
        "difference_rms": rms_d,
        "share": rms_d / rms_b if rms_b > 0 else float("inf"),
    }


def impulse_check(pulse_s: float = 0.04, thrust_n: float = 0.02, mass_kg: float = 3.0, step_s: float = 1e-3) -> dict:
    """One thruster (at 5 cm from the centre of mass, turning the body) fired
    once for ``pulse_s``: the spacecraft's delta-v and the IMU's summed
    delta-v and delta-angle against the commanded impulse, with the pulse
    ended by the effector's on-time countdown and by an explicit off command."""
    from Basilisk.architecture import messaging
    from Basilisk.simulation import imuSensor, spacecraft, thrusterDynamicEffector
    from Basilisk.utilities import SimulationBaseClass, simIncludeGravBody

    from bench.sim.basilisk_sim import imu_dv_error

    arm, inertia = 0.05, 0.02
    out = {"pulse_s": pulse_s, "step_s": step_s, "dv_commanded_mps": thrust_n * pulse_s / mass_kg}
    for mode in ("countdown", "explicit_off"):
        sim = SimulationBaseClass.SimBaseClass()
        proc = sim.CreateNewProcess("p")
        ns = int(round(step_s * 1e9))
        proc.addTask(sim.CreateNewTask("t", ns))
        grav = simIncludeGravBody.gravBodyFactory()
        earth = grav.createEarth()
        earth.isCentralBody = True
        sc = spacecraft.Spacecraft()
        sc.hub.mHub = mass_kg
        sc.hub.IHubPntBc_B = (inertia * np.eye(3)).tolist()
        grav.addBodiesTo(sc)
        a = 6378137.0 + 500e3
        sc.hub.r_CN_NInit = [[a], [0.0], [0.0]]
        sc.hub.v_CN_NInit = [[0.0], [np.sqrt(earth.mu / a)], [0.0]]
        thr = thrusterDynamicEffector.ThrusterDynamicEffector()
        c = thrusterDynamicEffector.THRSimConfig()
        c.thrLoc_B, c.thrDir_B, c.MaxThrust, c.MinOnTime, c.steadyIsp = (
            [0.0, arm, 0.0],
            [1.0, 0.0, 0.0],
            thrust_n,
            0.0,
            0.0,
        )
        thr.addThruster(c)
        cmd = messaging.THRArrayOnTimeCmdMsg()
        thr.cmdsInMsg.subscribeTo(cmd)
        sc.addDynamicEffector(thr)
        imu = imuSensor.ImuSensor()
        imu.scStateInMsg.subscribeTo(sc.scStateOutMsg)
        sim.AddModelToTask("t", thr, 100)
        sim.AddModelToTask("t", sc, 90)
        sim.AddModelToTask("t", imu, 50)
        ri, rs = imu.sensorOutMsg.recorder(), sc.scStateOutMsg.recorder()
        sim.AddModelToTask("t", ri, 10)
        sim.AddModelToTask("t", rs, 10)
        sim.InitializeSimulation()
        t_on = 1.0
        p = messaging.THRArrayOnTimeCmdMsgPayload()
        sim.ConfigureStopTime(int(round(t_on / step_s)) * ns)
        sim.ExecuteSimulation()
        p.OnTimeRequest = [pulse_s if mode == "countdown" else pulse_s + step_s]
        cmd.write(p, int(round(t_on / step_s)) * ns)
        if mode == "explicit_off":
            t_off = int(round((t_on + pulse_s) / step_s)) * ns
            sim.ConfigureStopTime(t_off)
            sim.ExecuteSimulation()
            p.OnTimeRequest = [0.0]
            cmd.write(p, t_off)
        sim.ConfigureStopTime(int(round((t_on + pulse_s + 5.0) / step_s)) * ns)
        sim.ExecuteSimulation()
        dv_raw = np.asarray(ri.DVFramePlatform)
        dv_fixed = dv_raw - imu_dv_error(np.asarray(rs.TotalAccumDV_BN_B), np.asarray(rs.sigma_BN))
        dr = np.asarray(ri.DRFramePlatform)
        w_end = np.asarray(rs.omega_BN_B)[-1]
        # Torque impulse F arm / J about z (the thruster at +y pushing +x turns the body about -z).
        out["dtheta_rate_commanded_rps"] = -thrust_n * arm * pulse_s / inertia
        out[mode] = {
            "spacecraft_dv_mps": float(np.linalg.norm(np.asarray(rs.TotalAccumDV_CN_N)[-1])),
            "rate_change_rps": float(w_end[2]),
            "imu_dv_sum_mps": np.sum(dv_raw, axis=0).tolist(),
            "imu_dv_sum_corrected_mps": np.sum(dv_fixed, axis=0).tolist(),
            "imu_dtheta_sum_rad": float(np.sum(dr[:, 2])),
        }
        out[mode]["impulse_ratio"] = out[mode]["spacecraft_dv_mps"] / out["dv_commanded_mps"]
    return out


def main(argv=None):
    import argparse
    import json

    from bench.sim.basilisk_sim import basilisk_version
    from bench.sim.vehicles import VEHICLES

    ap = argparse.ArgumentParser(description="The bench's plant against Basilisk: null, effect signatures, impulses")
    ap.add_argument("--vehicle", default="12kg", choices=sorted(VEHICLES))
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    t0 = time.time()
    desc = VEHICLES[a.vehicle]()
    plan = short_plan(desc, a.seconds)
    res = {
        "vehicle": a.vehicle,
        "seconds": a.seconds,
        "basilisk_version": basilisk_version(),
        "impulse": impulse_check(),
        "null": null_agreement(desc, plan),
        "effects": [],
    }
    d = quiet(desc)
    nulls = {e: _fly(e, d, plan, {}) for e in ("bench", "basilisk")}
    nulls["bench"]["pose_r"] = _noise_free_bench_pose(d, plan, {})
    print(json.dumps(res["impulse"], indent=1))
    print(json.dumps(res["null"], indent=1))
    for name in CROSSCHECK_EFFECTS:
        r = signature_agreement(desc, plan, name, nulls)
        res["effects"].append(r)
        if name == "com_offset":  # it moves the pose reference point too
            res["effects"].append(signature_agreement(desc, plan, name, nulls, stream="pose_r"))
            q = res["effects"][-1]
            print(
                f"{name:22s} {q['stream']:15s} signature rms {q['signature_rms']:.3e}  difference {q['difference_rms']:.3e}"
                f"  share {q['share']:.2e}",
                flush=True,
            )
        print(
            f"{name:22s} {r['stream']:15s} signature rms {r['signature_rms']:.3e}  basilisk {r['basilisk_signature_rms']:.3e}"
            f"  difference {r['difference_rms']:.3e}  share {r['share']:.2e}",
            flush=True,
        )
    res["elapsed_s"] = time.time() - t0
    print(f"{res['elapsed_s']:.0f} s")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
