"""The log replay in one binding call (fsw_bindings.nav_replay, used by
bench.gap.replay.replay) gives what stepping the filter from Python one
sample at a time gives (bench/perf/nav_replay_stepped.py), bit for bit: on
the bundled reality run, on logs of the 12 kg vehicle with jittered and
dropped IMU samples and chained runs (one not starting at rest), nominal
and with clock-rate, latency and IMU corrections, gated and ungated, with
and without the states."""

import numpy as np
import pytest

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "nav_replay"):
    pytest.skip("fsw_bindings has no nav_replay (rebuild the bindings)", allow_module_level=True)

from bench.gap import bundled  # noqa: E402
from bench.gap.load import V0_SIGMA_MPS, prepare  # noqa: E402
from bench.gap.replay import Corrections, ReplayResult, nav_config, reference, replay  # noqa: E402
from bench.perf.nav_replay_stepped import stepped  # noqa: E402
from bench.sim.flight_log import read_flight_log  # noqa: E402
from bench.sim.plans import characterisation_plan  # noqa: E402
from bench.sim.vehicle_sim import Clocks, simulate  # noqa: E402
from bench.sim.vehicles import VEHICLES  # noqa: E402


def assert_same(a: ReplayResult, b: ReplayResult):
    assert a.index.size > 0
    for name in ("t", "index", "innovation", "S", "nis", "loglik", "ok"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    if a.states is None:
        assert b.states is None
    else:
        np.testing.assert_array_equal(a.states, b.states, err_msg="states")


def corrections(d) -> list:
    """Nominal, then every kind of correction the candidates make (clock
    rate, latency, lever arm, IMU errors, extra specific force)."""
    n = d.imu_t.size
    rng = np.random.default_rng(3)
    return [
        None,
        Corrections(clock_eps=2e-4),
        Corrections(latency_s=0.04),
        Corrections(clock_eps=-1e-4, latency_s=-0.02, lever_arm_b=np.array([0.01, -0.02, 0.0])),
        Corrections(
            accel_bias=np.array([1e-4, -2e-4, 5e-5]),
            gyro_scale=np.array([1e-3, 0.0, -2e-3]),
            imu_misalign=np.array([1e-3, 2e-3, -1e-3]),
            accel_extra_b=1e-5 * rng.standard_normal((n, 3)),
        ),
    ]


def check(d):
    reference(d)  # the latency corrections move poses along the reference
    for c in corrections(d):
        assert_same(replay(d, c), stepped(d, c))
    assert_same(replay(d, None, record_states=True), stepped(d, None, record_states=True))
    gated = replay(d, None, gate_chi2=6.0)
    assert_same(gated, stepped(d, None, gate_chi2=6.0))
    assert gated.index.size < replay(d).index.size  # the gate rejected some


def vehicle12_log(seed: int, plans: int, moving_run: int | None = None):
    desc = VEHICLES["12kg"]()
    plan = [p for s in range(plans) for p in characterisation_plan(desc, seed=seed + s)]
    if moving_run is not None:
        plan[moving_run].v0_hill_mps = np.array([0.004, -0.002, 0.001])
    clocks = Clocks(imu_jitter_s=0.005, imu_drop_frac=0.03, pose_phase_s=0.37, pose_jitter_s=0.01, pose_delay_s=0.25)
    log, _ = simulate(desc, plan, {}, seed=seed, clocks=clocks, with_truth=False)
    return log


def test_bundled_reality_run():
    check(prepare(read_flight_log(bundled.LOG)))


def test_vehicle12_jittered_and_dropped():
    d = prepare(vehicle12_log(31, 1))
    assert np.any(np.diff(d.imu_t) > 1.5 * d.dt_s)  # IMU samples dropped
    check(d)


def test_vehicle12_chained_runs_one_moving():
    d = prepare(vehicle12_log(47, 2, moving_run=1))
    assert int(d.pose_start.sum()) >= 4
    assert np.any(d.pose_v0_sigma > V0_SIGMA_MPS)
    check(d)


def test_bad_arrays_raise_value_errors_naming_them():
    d = prepare(read_flight_log(bundled.LOG))
    nc = nav_config(d)
    ok = dict(
        imu_t_s=d.imu_t,
        accel_b_mps2=d.accel,
        omega_bi_b_rps=d.gyro,
        pose_t_capture_s=d.pose_tc,
        pose_t_fuse_s=d.pose_tf,
        pose_r_hill_m=d.pose_r,
        pose_q_hb_wxyz=d.pose_q,
        pose_R=d.pose_R,
        pose_run_start=d.pose_start,
        pose_v0_sigma_mps=d.pose_v0_sigma,
        t_init_s=d.t_init,
    )
    fb.nav_replay(nc, **ok)
    bad_q = d.pose_q.copy()
    bad_q[3] *= 1.1
    nan_acc = d.accel.copy()
    nan_acc[5, 1] = np.nan
    for name, value in (
        ("accel_b_mps2", d.accel[:-1]),
        ("accel_b_mps2", nan_acc),
        ("pose_q_hb_wxyz", bad_q),
        ("pose_R", d.pose_R[:, :5]),
        ("pose_run_start", d.pose_start[:-1]),
    ):
        with pytest.raises(ValueError, match=name):
            fb.nav_replay(nc, **dict(ok, **{name: value}))
    nc.max_delay_s = 10.0  # more than the history holds
    with pytest.raises(ValueError, match="max_delay_s"):
        fb.nav_replay(nc, **ok)
