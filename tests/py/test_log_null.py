"""The null calibration made for a log: its tail fit, checked on the
committed 1000-run calibrations; the fingerprint that keys its cache."""

import json
from pathlib import Path

import numpy as np

from bench.gap.log_null import FA_EACH, frechet_threshold

DATA = Path(__file__).resolve().parents[2] / "bench" / "gap" / "data"


def test_frechet_tail_from_40_runs_holds_the_false_alarm_rate():
    # 300 random 40-run calibrations drawn from each committed 1000-run one;
    # each pair of thresholds judged on all 1000 null runs.
    rng = np.random.default_rng(2026)
    for name in ("null_calibration.json", "null_calibration_characterisation.json"):
        cal = json.loads((DATA / name).read_text())
        z, b = np.array(cal["null_map_max_abs_z"]), np.array(cal["null_screen_logp"])
        fa = []
        for _ in range(300):
            tz = frechet_threshold(rng.choice(z, 40, replace=False))
            tb = frechet_threshold(rng.choice(b, 40, replace=False))
            fa.append(np.mean((z > tz) | (b > tb)))
        assert np.median(fa) <= 2 * FA_EACH, (name, np.median(fa))
        assert np.percentile(fa, 95) <= 0.02, (name, np.percentile(fa, 95))


def test_raw_gumbel_would_not_hold_it():
    # The reason for the fit on the logarithm: a Gumbel on the raw maxima
    # puts the 99.5 % point of the docking map statistic below the measured one.
    cal = json.loads((DATA / "null_calibration.json").read_text())
    z = np.array(cal["null_map_max_abs_z"])
    beta = z.std(ddof=1) * np.sqrt(6) / np.pi
    gumbel = z.mean() - 0.5772156649 * beta - beta * np.log(-np.log(1 - FA_EACH))
    measured = np.quantile(z, 1 - FA_EACH)
    assert gumbel < measured <= frechet_threshold(z)


def test_stated_bias_stability_puts_biases_into_the_null():
    """A bias within the IMU's stated stability is part of the null: each
    bootstrap flight carries a constant bias drawn at that size."""
    import copy

    from bench.gap.log_null import _bench_like, null_log_like, stated_biases
    from bench.gap.plans import characterisation_plan
    from bench.sim.log_description import resolve
    from bench.sim.vehicle_sim import simulate
    from bench.sim.vehicles import inspector_12kg

    base = inspector_12kg()
    assert stated_biases(base, 1) == {}
    stated = copy.deepcopy(base)
    stated["imu"]["gyro_bias_stability_rps"] = 2e-3
    stated["imu"]["accel_bias_stability_mps2"] = 1e-3
    g = np.array([stated_biases(stated, s)["gyro_bias"] for s in range(600)])
    a = np.array([stated_biases(stated, s)["accel_bias"] for s in range(600)])
    assert np.allclose(g.std(axis=0), 2e-3, rtol=0.12) and np.allclose(a.std(axis=0), 1e-3, rtol=0.12)
    assert np.all(np.abs(g.mean(axis=0)) < 4 * 2e-3 / np.sqrt(600))
    assert _bench_like(resolve(stated), resolve(base)) == [
        "another accelerometer bias stability",
        "another gyro bias stability",
    ]

    plan = characterisation_plan(base, seed=3)[:1]
    log0, _ = simulate(base, plan, {}, seed=3, with_truth=False)
    log1 = copy.deepcopy(log0)
    log1.description = dict(log1.description, imu=stated["imu"])
    n0, n1 = null_log_like(log0, seed=11), null_log_like(log1, seed=11)
    dg = n1.streams["imu"]["omega_bi_b_rps"] - n0.streams["imu"]["omega_bi_b_rps"]
    np.testing.assert_allclose(dg, np.broadcast_to(stated_biases(stated, 11)["gyro_bias"], dg.shape), atol=1e-6)
