"""Small seeded checks of the thruster-learning bench (bench/campaigns/thrusters.py)."""

import json

import numpy as np
import pytest

from bench.campaigns import thrusters as th


def _need_blr():
    fb = pytest.importorskip("fsw_bindings")
    if not hasattr(fb, "ThrusterBlr"):
        pytest.skip("fsw_bindings built without the thruster learner")


def test_no_valves_give_no_linear_velocity_change():
    cfg = th.ProtocolConfig(n_samples=10)
    truth = th.ThrusterTruth(cfg, np.random.default_rng(0))
    y = truth.step(np.zeros(8), 0.0)
    np.testing.assert_array_equal(y[:3], 0.0)


def test_one_valve_gives_about_20mN_over_3kg():
    cfg = th.ProtocolConfig(magnitude_spread=0.0, misalign_rad=0.0)
    truth = th.ThrusterTruth(cfg, np.random.default_rng(0))
    v = np.zeros(8)
    v[0] = 1
    dv = truth.step(v, 0.0)[:3]
    assert np.linalg.norm(dv) == pytest.approx(0.020 / 3.0 * cfg.dt_s, rel=1e-12)


def test_propellant_use_lowers_mass_and_degradation_lowers_thrust():
    d = th.generate(3, th.ProtocolConfig(n_samples=400))
    assert d["mass_kg"][-1] < d["mass_kg"][0] - 1e-3
    truth = th.ThrusterTruth(th.ProtocolConfig(), np.random.default_rng(3))
    assert np.all(truth.thrust_n(500.0) <= truth.thrust_n(0.0))
    assert np.any(truth.thrust_n(500.0) < 0.97 * truth.thrust_n(0.0))


def test_measurement_noise_is_15_and_5_percent():
    d = th.generate(4, th.ProtocolConfig(n_samples=2000))
    nz = np.abs(d["y_true"]) > 1e-9
    rel = np.where(nz, d["y_meas"] / np.where(nz, d["y_true"], 1.0) - 1.0, np.nan)
    assert np.nanstd(rel[:, :3]) == pytest.approx(0.15, rel=0.05)
    assert np.nanstd(rel[:, 3:]) == pytest.approx(0.05, rel=0.05)


def test_autopilot_toggles_one_valve_per_interval():
    d = th.generate(5, th.ProtocolConfig(n_samples=200))
    flips = np.abs(np.diff(d["valves"], axis=0)).sum(axis=1)
    np.testing.assert_array_equal(flips, 1.0)


def test_pooled_correlation_uses_all_three_axes():
    pred = np.zeros((4, 6))
    ref = np.zeros((4, 6))
    ref[:, :3] = np.arange(12).reshape(4, 3)
    pred[:, :3] = 2 * ref[:, :3] + 1
    assert th.pooled_corr(pred, ref, "linear") == pytest.approx(1.0)


def test_blr_learns_thrusters_on_short_run():
    _need_blr()
    res, _, _ = th.evaluate(6, th.ProtocolConfig(n_samples=600), learners=("blr",))
    assert res["blr"]["corr_linear"] > 0.95
    assert res["blr"]["corr_angular"] > 0.95


def test_gpr_learns_thrusters_on_short_run():
    res, _, _ = th.evaluate(6, th.ProtocolConfig(n_samples=400), learners=("gpr",))
    assert res["gpr"]["corr_linear"] > 0.9
    assert res["gpr"]["corr_angular"] > 0.9


def test_marginal_likelihood_fit_beats_hand_values():
    d = th.generate(7, th.ProtocolConfig(n_samples=200))
    hyper, fitted = th.fit_gpr_hyper(d["valves"], d["y_meas"])
    for kind, sl in th.KINDS.items():
        Y = d["y_meas"][:, sl] / np.sqrt((d["y_meas"][:, sl] ** 2).mean(axis=0))
        length, ratio = th.GPR_HAND[kind]
        hand = th.neg_log_marginal(np.log([length, 1.0, np.sqrt(ratio)]), d["valves"], Y)
        assert fitted[kind]["neg_log_marginal"] < hand


def test_command_writes_the_required_keys(tmp_path):
    _need_blr()
    from bench.cli import main

    out = tmp_path / "t.json"
    assert main(["thrusters", "--seed", "1", "--samples", "150", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    for name in ("blr", "gpr", "gpr_tuned"):
        for key in ("corr_linear", "corr_angular", "step_us_median"):
            assert np.isfinite(r[name][key])
