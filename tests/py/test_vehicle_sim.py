"""Logs of any described vehicle: pulse-width-modulated valves integrated
exactly, IMU samples as interval means on jittered clocks, the replay's
valve integration agreeing with the simulator's."""

import numpy as np

from bench.gap.load import open_fractions
from bench.sim.plans import characterisation_plan
from bench.sim.vehicle_sim import Clocks, PlanSegment, simulate
from bench.sim.vehicles import inspector_12kg


def test_open_fractions_against_brute_force():
    rng = np.random.default_rng(5)
    k = 3
    vt = np.cumsum(rng.uniform(0.02, 0.15, 60))
    on = rng.uniform(0.0, 1.0, (60, k)) * np.r_[np.diff(vt), 0.05][:, None]
    on[rng.uniform(size=on.shape) < 0.4] = 0.0
    t = np.arange(0.1, vt[-1], 0.05) + rng.normal(0, 0.004, np.arange(0.1, vt[-1], 0.05).size)
    dt = 0.05
    got = open_fractions({"t_s": vt, "on_time_s": on}, t, dt, k)
    fine = np.linspace(0.0, vt[-1] + 1.0, 400001)
    h = fine[1] - fine[0]
    for i in range(k):
        j = np.searchsorted(vt, fine, side="right") - 1
        is_on = (j >= 0) & (fine < vt[np.clip(j, 0, None)] + on[np.clip(j, 0, None), i])
        c = np.concatenate([[0.0], np.cumsum(is_on) * h])
        ref = (np.interp(t, fine, c[1:]) - np.interp(t - dt, fine, c[1:])) / dt
        np.testing.assert_allclose(got[:, i], ref, atol=2e-3)


def test_mask_form_equals_on_time_form():
    vt = np.arange(0.0, 2.0, 0.1)
    mask = np.array([0b101, 0, 0b010] * 6 + [0, 0])
    t = np.arange(0.1, 2.0, 0.1)
    a = open_fractions({"t_s": vt, "interval_s": np.full(vt.size, 0.1), "mask": mask}, t, 0.1, 3)
    on = ((mask[:, None] >> np.arange(3)) & 1) * 0.1
    b = open_fractions({"t_s": vt, "on_time_s": on}, t, 0.1, 3)
    np.testing.assert_allclose(a, b)


def test_pwm_pulse_gives_its_duty_in_the_accelerometer():
    # One thruster at 30 % duty of each 0.1 s cycle, a 20 Hz IMU: the mean
    # specific force per sample (noise-free) is the open fraction times F / m.
    desc = inspector_12kg()
    desc["imu"] = dict(
        desc["imu"],
        accel_noise_density_mps2_rthz=1e-12,
        gyro_noise_density_rps_rthz=1e-12,
        q_body_imu=[1.0, 0.0, 0.0, 0.0],
    )
    desc["imu"]["position_b_m"] = desc["vehicle"]["com_b_m"]
    cmd_t = np.arange(1.0, 3.0, 0.1)
    on = np.zeros((cmd_t.size, 12))
    on[:, 4] = 0.03
    plan = [PlanSegment("other", 4.0, np.array([0.0, -1.5, 0.0]), np.array([1.0, 0, 0, 0]), cmd_t, on)]
    log, _ = simulate(desc, plan, {}, seed=1, clocks=Clocks(imu_jitter_s=0.003))
    t = log["imu"]["t_s"]
    frac = open_fractions(log["valves"], t, 0.05, 12)[:, 4]
    assert 0.2 < frac.max() <= 0.6 + 1e-9 and frac.min() == 0.0
    from bench.sim.log_description import resolve

    v = resolve(desc).vehicle()
    pred = frac[:, None] * v.thruster_forces_b_n()[4] / v.mass_kg
    acc = log["imu"]["accel_b_mps2"]
    # rotation of the body over a sample moves the specific force by < 1e-3 of itself
    np.testing.assert_allclose(acc, pred, atol=2e-3 * np.abs(pred).max() + 1e-9)


def test_jittered_stamps_and_pose_between_ticks():
    desc = inspector_12kg()
    plan = characterisation_plan(desc, seed=2, per_run=12, fire_s=0.5, coast_s=1.0, passes=1)
    log, _ = simulate(
        desc, plan, {}, seed=2, clocks=Clocks(imu_jitter_s=0.0025, imu_drop_frac=0.02, pose_phase_s=0.537)
    )
    t = log["imu"]["t_s"]
    d = np.diff(t)
    assert d.std() > 0.001 and d.max() > 0.09  # jitter, and dropped samples
    tc = log["pose"]["t_capture_s"] + desc["pose_sensor"]["time_offset_s"] - desc["pose_sensor"]["latency_s"]
    off = np.min(np.abs(tc[:, None] - t[None, :]), axis=1)
    assert np.median(off) > 0.005  # captures between IMU samples


def test_gyro_differences_are_exact_under_jitter_drops_and_pwm():
    # Noise-free: the dynamics channel's prediction of each change of the
    # mean rate equals the simulator's to 1e-6 of the rate changes, with
    # jittered and dropped samples and pulses shorter than an interval (a
    # per-sample torque average leaked a drift of 2e-3 rad/s here).
    from bench.gap import dyn
    from bench.gap.load import prepare
    from bench.gap.replay import reference

    desc = inspector_12kg()
    desc["imu"] = dict(desc["imu"], accel_noise_density_mps2_rthz=1e-12, gyro_noise_density_rps_rthz=1e-12)
    log, _ = simulate(
        desc,
        characterisation_plan(desc, seed=8),
        {},
        seed=1,
        clocks=Clocks(imu_jitter_s=0.0025, imu_drop_frac=0.02),
        with_truth=False,
    )
    d = prepare(log)
    reference(d)
    ch = dyn.build(d)
    resid = ch.unwhiten_gyro(ch.e0[ch.kind == 1]) * ch.sig_g
    raw = d.gyro[ch.gyro_rows] - d.gyro[ch.gyro_rows - 1]
    assert np.sqrt(np.mean(resid**2)) < 1e-3 * np.sqrt(np.mean(raw**2))
    assert np.all(np.abs(resid.sum(axis=0)) < 1e-5)


def test_a_run_flown_again_on_given_times_reuses_its_flight():
    """A null calibration flies one log's runs again and again on its time
    stamps with fresh sensor noise: the plant's flight is made once per
    process and reused, giving the logs a fresh flight gives."""
    from bench.sim import vehicle_sim
    from bench.sim.log_description import resolve

    desc = inspector_12kg()
    plan = characterisation_plan(desc, seed=2)[:1]
    T = 1.0 / (resolve(desc).imu_rate_hz or 10.0)
    imu_t = np.delete(5.0 + T * np.arange(1, int(plan[0].duration_s / T) + 1), [7, 30])
    pose_t = 5.43 + np.arange(0.0, plan[0].duration_s - 1.0, 1.0)
    times = [{"imu_t": imu_t, "pose_t": pose_t, "pose_delay": np.full(pose_t.size, 0.2)}]
    vehicle_sim._FLIGHTS.clear()
    first, _ = simulate(desc, plan, {}, seed=3, times=times)
    assert len(vehicle_sim._FLIGHTS) == 1
    again, _ = simulate(desc, plan, {}, seed=3, times=times)  # the kept flight
    other, _ = simulate(desc, plan, {}, seed=4, times=times)
    vehicle_sim._FLIGHTS.clear()
    fresh, _ = simulate(desc, plan, {}, seed=3, times=times)  # flown again
    for log in (again, fresh):
        for name, stream in first.streams.items():
            for field, value in stream.items():
                np.testing.assert_array_equal(log[name][field], value, err_msg=f"{name}/{field}")
    np.testing.assert_array_equal(other["truth"]["r_hill_m"], first["truth"]["r_hill_m"])
    assert not np.array_equal(other["imu"]["accel_b_mps2"], first["imu"]["accel_b_mps2"])
