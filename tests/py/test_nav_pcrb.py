"""The posterior Cramer-Rao bound of the docking navigation
(bench/campaigns/nav_pcrb.py): the recursion against an independent
covariance-form Riccati on one trajectory, latency only ever loosening it,
and the filters' errors against it on a few seeded runs."""

import fsw_bindings as fb
import numpy as np
import pytest

from bench.campaigns import nav_pcrb as P
from bench.sim.scenario_docking import ScenarioConfig, run_docking
from bench.so3 import qexp, rotmat

if not hasattr(fb, "NavUkfFloat"):
    pytest.skip("fsw_bindings without NavUkfFloat", allow_module_level=True)


@pytest.fixture(scope="module")
def runs():
    cfg = ScenarioConfig()
    return cfg, [run_docking(1000 + i, cfg) for i in range(3)]


def _riccati(run, cfg):
    """Covariance-form Kalman recursion at the truth, written out here."""
    m = P.Model(cfg)
    forces, _ = cfg.truth_vehicle.config_table()
    r0 = run.r_true[0]
    s0 = m.pos_frac * np.linalg.norm(r0)
    Pk = np.linalg.inv(m.pose_information(r0) + np.diag([0.0] * 3 + [1 / m.v0_sigma**2] * 3 + [0.0] * 3))
    assert s0 > 0
    out = [np.diag(Pk)]
    for k, c in enumerate(run.config):
        a = forces[c] / cfg.truth_vehicle.mass_kg
        w = 0.5 * (run.w_true[k] + run.w_true[k + 1])
        F = np.zeros((9, 9))
        F[0:6, 0:6] = m.phi
        F[0:6, 6:9] = m.gamma @ (-m.rz @ rotmat(run.q_true[k]) @ P.skew(a + 0.05 * np.cross(w, a)))
        F[6:9, 6:9] = rotmat(qexp(w * 0.1)).T
        Pk = F @ Pk @ F.T + m.Q
        if (k + 1) % 10 == 0:
            Pk = np.linalg.inv(np.linalg.inv(Pk) + m.pose_information(run.r_true[k + 1]))
        out.append(np.diag(Pk))
    return np.array(out)


def test_bound_of_one_trajectory_is_the_kalman_covariance_at_the_truth(runs):
    cfg, rs = runs
    b = P.pcrb(rs[:1], cfg)
    ref = _riccati(rs[0], cfg)
    np.testing.assert_allclose(b["bound_diag"], ref, rtol=1e-6)
    np.testing.assert_allclose(b["conditional_diag"], ref, rtol=1e-6)
    # Position: below the pose noise per axis once several poses are in.
    assert np.sqrt(b["bound_diag"][200, 0]) < 0.05 * np.linalg.norm(rs[0].r_true[200])


def test_ensemble_bound_is_below_the_mean_of_the_per_trajectory_bounds(runs):
    cfg, rs = runs
    b = P.pcrb(rs, cfg)
    n = min(len(r.t) for r in rs)
    assert np.all(b["bound_diag"][:n] <= b["conditional_diag"][:n] * (1 + 1e-9))
    assert b["spread_term_rel_max"] < 1e-2  # the model barely changes over the runs


def test_latency_loosens_the_bound(runs):
    cfg, rs = runs
    late = ScenarioConfig(profile=cfg.profile.with_(pose_latency_s=0.5))
    b0, b1 = P.pcrb(rs, cfg), P.pcrb(rs, late)
    assert np.all(b1["bound_diag"] >= b0["bound_diag"] * (1 - 1e-9))
    assert np.mean(b1["bound_diag"][100:, 0] / b0["bound_diag"][100:, 0]) > 1.05


def test_filters_sit_near_the_bound_and_agree(runs):
    cfg, rs = runs
    out, series = P.compare(rs, cfg, filters=("ukf", "ukf_float", "ekf"))
    for f in ("ukf", "ukf_float", "ekf"):
        r = out["filters"][f]
        for blk in P.BLOCKS:
            assert 0.8 < r[blk] < 1.25, (f, blk, r[blk])
            assert 0.97 < r["sqrt_P_over_bound"][blk] < 1.05, (f, blk)
    # The float build and the EKF estimate what the double UKF does, to a fraction of the bound.
    for f in ("ukf_float", "ekf"):
        for blk in P.BLOCKS:
            assert abs(out["filters"][f][blk] - out["filters"]["ukf"][blk]) < 0.01
    assert series["rmse"]["ukf"].shape == (len(series["t"]), 3)


def test_filterpy_comparison_refuses_late_poses(runs):
    cfg, rs = runs
    late = ScenarioConfig(profile=cfg.profile.with_(pose_latency_s=0.5))
    with pytest.raises(ValueError, match="latency"):
        P.compare(rs, late, filters=("ekf",))
