"""A small seeded docking campaign through the flight filter (fsw_bindings.NavUkf):
errors within the required bounds and the filter consistent with the bench's
sensors. The 50-run campaign is the `proxops nav` command (docs/perf/nav_campaign.md,
"Result")."""

import numpy as np
import pytest
from scipy.stats import chi2

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "NavUkf"):
    pytest.skip("fsw_bindings has no NavUkf (bindings not built with bind_nav)", allow_module_level=True)

from bench.campaigns.nav_campaign import chi2_mean_band, run_campaign  # noqa: E402
from bench.sim.scenario_docking import ScenarioConfig, nav_config  # noqa: E402
from bench.sim.sensors import NoiseProfile  # noqa: E402


@pytest.fixture(scope="module")
def campaign():
    summary, _ = run_campaign(5, seed=1, cfg=ScenarioConfig())
    return summary


def test_filter_noise_settings_match_simulated_sensors():
    nc = nav_config(ScenarioConfig())
    p = NoiseProfile.paper()
    assert nc.accel_sigma_mps2 == p.accel_sigma_mps2 == pytest.approx(0.25 * 0.020 / 3.0, rel=1e-15)
    assert nc.gyro_sigma_rps == p.gyro_sigma_rps == 0.005
    assert nc.dt_imu_s == ScenarioConfig().dt_s
    assert nc.n_radps == pytest.approx(fb.orbit_rate(fb.EARTH_RADIUS + 500e3), rel=1e-15)


def test_every_run_docks(campaign):
    assert campaign["docked"] == 5


def test_each_runs_max_errors_within_paper_bounds(campaign):
    assert max(campaign["max_pos_err_m"]["per_run"]) <= 0.10
    assert max(campaign["max_vel_err_mps"]["per_run"]) <= 0.03
    assert campaign["max_pos_err_m"]["median"] <= 0.05
    assert campaign["max_vel_err_mps"]["median"] <= 0.015


def test_nis_mean_inside_its_chi_square_band(campaign):
    lo, hi = campaign["nis_band"]
    assert lo <= campaign["nis_mean"] <= hi
    # NIS samples are white: the band for independent samples holds too.
    lo, hi = campaign["nis_band_per_sample"]
    assert lo <= campaign["nis_mean"] <= hi


def test_nees_mean_inside_the_n_run_band(campaign):
    lo, hi = campaign["nees_band"]
    assert (lo, hi) == tuple(chi2_mean_band(9, campaign["runs"]))
    assert lo <= campaign["nees_mean"] <= hi


def test_nearly_independent_nees_mean_inside_its_chi_square_band(campaign):
    lo, hi = campaign["nees_thinned_band"]
    assert lo <= campaign["nees_thinned_mean"] <= hi


def test_no_more_than_two_updates_gated(campaign):
    assert campaign["gated_count"] <= 2


def test_bands_are_two_sided_95_percent_of_the_mean():
    lo, hi = chi2_mean_band(6, 100)
    assert lo == pytest.approx(chi2.ppf(0.025, 600) / 100) and hi == pytest.approx(chi2.ppf(0.975, 600) / 100)
    assert lo < 6.0 < hi


def test_summary_has_the_issue_fields(campaign):
    for k in (
        "runs",
        "max_pos_err_m",
        "max_vel_err_mps",
        "nees_mean",
        "nis_mean",
        "nees_band",
        "nis_band",
        "gated_count",
    ):
        assert k in campaign
    for k in ("per_run", "median", "p95"):
        assert k in campaign["max_pos_err_m"] and k in campaign["max_vel_err_mps"]
    assert campaign["runs"] == len(campaign["max_pos_err_m"]["per_run"]) == 5
    assert np.isfinite(campaign["nees_mean"]) and np.isfinite(campaign["nis_mean"])


def test_half_second_pose_latency_run_docks_within_bounds():
    from bench.campaigns.nav_campaign import run_metrics
    from bench.sim.scenario_docking import run_docking

    cfg = ScenarioConfig(profile=NoiseProfile.paper().with_(pose_latency_s=0.5))
    m = run_metrics(run_docking(1000, cfg))
    assert m.docked and m.statuses.get("bad_input", 0) == 0
    assert m.max_pos_err_m <= 0.10 and m.max_vel_err_mps <= 0.03
    assert len(m.nis) >= 0.95 * m.t_end_s  # nearly every pose fused despite the delay


def test_ensemble_consistency_counts_epochs_against_exact_bands():
    # Two runs with NEES exactly at the mean at every epoch are inside the
    # band everywhere; a run far above puts its epochs above it.
    from bench.campaigns.nav_campaign import ensemble_consistency

    keys = [np.arange(10), np.arange(10)]
    ok = ensemble_consistency([np.full(10, 9.0), np.full(10, 9.0)], keys, 9, min_runs=2)
    assert ok["epochs"] == 10 and ok["in_band_fraction"] == 1.0
    bad = ensemble_consistency([np.full(10, 9.0), np.full(10, 60.0)], keys, 9, min_runs=2)
    assert bad["above_band"] == 10 and bad["in_band_fraction"] == 0.0
    lo, hi = chi2.ppf([0.025, 0.975], 18) / 2
    assert np.allclose(ok["band_at_max_runs"], [lo, hi])


def test_blr_accel_source_learns_in_flight_and_stands_in_during_firings():
    from bench.sim.scenario_docking import run_docking

    run = run_docking(1000, ScenarioConfig(accel_source="blr", t_max_s=60.0))
    s = run.summary
    assert s.firing_steps > 30
    assert 0 < s.blr_steps <= s.firing_steps - 30  # only after the window has filled
    assert np.all(np.isfinite(run.est))
    with pytest.raises(ValueError, match="accel_source"):
        run_docking(1000, ScenarioConfig(accel_source="magic", t_max_s=1.0))
