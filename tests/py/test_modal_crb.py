"""Cramer-Rao bounds of the modal filter's coarse estimates: the Fisher
information equals the one assembled from finite-difference derivatives,
the frequency bound of one sinusoid is the textbook formula, the
known-frequency shape bound is the least-squares covariance, and a plate run
and the CLI set the filter beside its bounds."""

import json

import numpy as np
import pytest

from bench.campaigns import modal_crb


def _model(theta, t, m):
    w, c, s = theta[:m], theta[m : 2 * m], theta[2 * m :]
    return np.cos(np.outer(t, w)) * c + np.sin(np.outer(t, w)) * s


def _random_covs(rng, k, m):
    b = 0.05 * rng.standard_normal((k, m, m))
    return b @ np.swapaxes(b, 1, 2) + 0.02**2 * np.eye(m)


def test_fisher_equals_finite_difference_assembly_with_coupled_covariances():
    rng = np.random.default_rng(3)
    m, k = 3, 40
    t = np.arange(k) * 60.0
    w = np.array([0.003, 0.0061, 0.011])
    c, s = rng.uniform(-1, 1, m), rng.uniform(-1, 1, m)
    cov = _random_covs(rng, k, m)
    sw = 0.1 * w
    theta = np.concatenate([w, c, s])
    d = np.zeros((k, m, 3 * m))
    for j in range(3 * m):
        h = 1e-6 * max(abs(theta[j]), 1e-3)
        e = np.zeros(3 * m)
        e[j] = h
        d[:, :, j] = (_model(theta + e, t, m) - _model(theta - e, t, m)) / (2 * h)
    ref = np.einsum("kia,kij,kjb->ab", d, np.linalg.inv(cov), d) + np.diag(np.r_[1 / sw**2, np.zeros(2 * m)])
    got = modal_crb.fisher(t, w, c, s, cov, sw)
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
    with pytest.raises(ValueError, match="expected \\(40, 3, 3\\)"):
        modal_crb.fisher(t, w, c, s, cov[:, :2, :2])


def test_single_sinusoid_frequency_bound_is_the_textbook_formula():
    # Kay, Fundamentals of Statistical Signal Processing I, eq. 3.41 (large n):
    # var(w) = 12 / (eta n (n^2 - 1) dt^2), eta = A^2 / (2 sigma^2).
    n, dt, w, amp, sigma = 400, 60.0, 0.0061, 0.7, 0.1
    t = np.arange(n) * dt
    ratios = []
    for ph in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        b = modal_crb.bound(
            t, [w], [amp * np.sin(ph)], [amp * np.cos(ph)], np.full((n, 1, 1), sigma**2), None, np.ones((1, 1))
        )
        ratios.append(b["sd_omega_radps"][0] / np.sqrt(12 / (amp**2 / (2 * sigma**2) * n * (n**2 - 1) * dt**2)))
    # the formula is the large-n asymptote; at n = 400 the exact bound still
    # moves with the phase by about 1 % (0.990 to 1.010 here)
    np.testing.assert_allclose(ratios, 1.0, atol=0.02)
    assert np.ptp(ratios) > 0  # the phase does enter
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.002)  # and averages out
    # a prior can only tighten the bound
    b_prior = modal_crb.bound(t, [w], [0.3], [0.5], np.full((n, 1, 1), sigma**2), [1e-6], np.ones((1, 1)))
    b_flat = modal_crb.bound(t, [w], [0.3], [0.5], np.full((n, 1, 1), sigma**2), None, np.ones((1, 1)))
    assert b_prior["sd_omega_radps"][0] < 1e-6 < b_flat["sd_omega_radps"][0]


def test_known_frequency_shape_bound_is_the_weighted_least_squares_covariance():
    rng = np.random.default_rng(4)
    m, k = 3, 30
    t = np.arange(k) * 60.0
    w = np.array([0.003, 0.0061, 0.011])
    cov = _random_covs(rng, k, m)
    phi = rng.standard_normal((50, m))
    b = modal_crb.bound(t, w, rng.uniform(-1, 1, m), rng.uniform(-1, 1, m), cov, 0.1 * w, phi)
    # weighted least squares for (c, s) with the frequencies known, stacked over images
    basis = np.concatenate(
        [np.cos(np.outer(t, w))[:, :, None] * np.eye(m)[None], np.sin(np.outer(t, w))[:, :, None] * np.eye(m)[None]],
        axis=2,
    )  # (k, m, 2m)
    info = np.einsum("kia,kij,kjb->ab", basis, np.linalg.inv(cov), basis)
    g = np.concatenate([np.diag(np.cos(w * t[-1])), np.diag(np.sin(w * t[-1]))], axis=1)
    p = g @ np.linalg.solve(info, g.T)
    ref = np.sqrt(np.mean(np.einsum("gi,ij,gj->g", phi, p, phi)))
    assert b["shape_rms_bound_known_omega_m"] == pytest.approx(ref, rel=1e-9)
    # not knowing the frequencies costs something
    assert b["shape_rms_bound_m"] > ref


def test_chance_within_the_band_agrees_with_the_sampled_joint_chance_for_one_mode():
    n, dt = 60, 60.0
    t = np.arange(n) * dt
    b = modal_crb.bound(t, [0.0061], [0.2], [0.1], np.full((n, 1, 1), 0.3**2), [0.0006], np.ones((1, 1)), samples=40000)
    assert 0.2 < b["p_within_band"][0] < 0.9  # a case where the band matters
    # 40,000 draws: sampling spread about 0.0025
    assert b["p_all_scored_within_band"] == pytest.approx(b["p_within_band"][0], abs=0.01)
    assert b["expected_within_band_scored"] == pytest.approx(b["p_within_band"][0])


def test_plate_run_sets_the_filter_beside_its_bounds():
    from bench.campaigns import modal_campaign as mc

    tr = mc.plate_trial(0, n_modes=10, kind="joint", n_images=81, crb_periods=(2.0,))
    (row,) = tr["crb"]
    assert row["images"] == 81 and row["periods"] == pytest.approx(2.0)
    assert row["n_excited"] == int(np.sum(tr["amp_true"] >= 0.2))
    # the known-frequency filter and its bound describe the same error (one run: a loose check of scale)
    assert 0.5 < row["shape_rms_known_omega_m"] / row["crb_shape_rms_known_omega_m"] < 2.0
    assert row["crb_shape_rms_m"] > row["crb_shape_rms_known_omega_m"]
    assert len(row["crb_sd_omega_rel"]) == 10 and np.all(np.asarray(row["crb_sd_omega_rel"]) > 0)
    with pytest.raises(ValueError, match="Cramer-Rao bound at 3.0 lowest-mode periods needs 121 images"):
        mc.plate_trial(0, n_modes=10, kind="joint", n_images=81, crb_periods=(3.0,))


def test_cli_structure_with_crb(tmp_path, capsys):
    from bench import cli

    out = tmp_path / "s.json"
    assert (
        cli.main(
            [
                "modal",
                "--scenario",
                "structure",
                "--modes",
                "10",
                "--trials",
                "2",
                "--images",
                "41",
                "--filter",
                "joint",
                "--crb-at",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    (row,) = json.loads(out.read_text())["crb_summary"]
    assert row["trials"] == 2 and row["images"] == 41
    assert 0 <= row["filter_excited_within_1pct"] <= row["excited_modes"]
    assert 0 <= row["crb_expected_excited_within_1pct"] <= row["excited_modes"]
    assert row["filter_over_crb_rms"] > 0
    trials = json.loads(out.read_text())["trials"]
    filt = [t["crb"][0]["shape_rms_filter_m"] <= 2 * t["crb"][0]["shape_rms_known_omega_m"] for t in trials]
    assert row["filter_within_2x_known_same_image"] == sum(filt)
    assert 0 <= row["crb_within_2x_known_same_image"] <= 2
    assert "within 2x the known-frequency filter at that image" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["flight", "batch-ml"])
def test_acquisition_is_scored_beside_the_filter(tmp_path, capsys, method):
    from bench import cli
    from bench.campaigns import modal_campaign as mc

    tr = mc.plate_trial(
        1, n_modes=10, kind="joint", n_images=81, crb_periods=(0.5, 2.0), acquire_periods=1.0, acquire_with=method
    )
    acq = tr["acquisition"]
    assert acq["method"] == method and acq["images"] == 41 and acq["periods"] == pytest.approx(1.0)
    (row,) = acq["at"]  # nothing is scored before the acquisition (0.5 periods)
    assert row["images"] == 81
    n_exc = int(np.sum(tr["amp_true"] >= 0.2))
    assert 0 <= row["excited_within_1pct"] <= n_exc and 0 <= acq["search_excited_within_1pct"] <= n_exc
    # the replayed filter has every image's information: its shape error is of the one-pass filter's size
    assert row["shape_rms_m"] < 3 * tr["crb"][1]["shape_rms_filter_m"]
    if method == "flight":
        assert acq["replay_fused"] == 41 and acq["search_s"] > 0
    with pytest.raises(ValueError, match="acquisition at 3.0 lowest-mode periods needs 121 images"):
        mc.plate_trial(1, n_modes=10, kind="joint", n_images=81, crb_periods=(2.0,), acquire_periods=3.0)
    with pytest.raises(ValueError, match="scored at the Cramer-Rao times"):
        mc.plate_trial(1, n_modes=10, kind="joint", n_images=81, acquire_periods=1.0)
    out = tmp_path / "a.json"
    assert (
        cli.main(
            [
                "modal",
                "--scenario",
                "structure",
                "--modes",
                "10",
                "--trials",
                "1",
                "--seed",
                "1",
                "--images",
                "81",
                "--filter",
                "joint",
                "--crb-at",
                "0.5",
                "2",
                "--acquire-at",
                "1",
                "--acquire-with",
                method,
                "--json",
                str(out),
            ]
        )
        == 0
    )
    (s,) = json.loads(out.read_text())["acquisition_summary"]
    assert s["trials"] == 1 and s["images"] == 81 and s["method"] == method
    assert s["excited_within_1pct"] == row["excited_within_1pct"]  # same seed, same run
    # against the known-frequency filter at the same image
    assert row["shape_rms_known_omega_m"] == pytest.approx(tr["shape_rms_oracle_m"][80])
    assert s["runs_shape_within_2x_known_same_image"] == int(row["shape_rms_m"] <= 2 * row["shape_rms_known_omega_m"])
    assert f"acquisition ({method})" in capsys.readouterr().out


def test_unscented_spread_reaches_the_filters():
    from bench.campaigns import modal_campaign as mc

    a = mc.plate_trial(2, n_modes=10, kind="joint", n_images=21, oracle=False)
    b = mc.plate_trial(2, n_modes=10, kind="joint", n_images=21, oracle=False, ut_alpha=0.5)
    assert np.max(np.abs(np.asarray(a["omega_final_radps"]) - np.asarray(b["omega_final_radps"]))) > 1e-9
    with pytest.raises(ValueError, match="ut_alpha"):
        mc.plate_trial(2, n_modes=10, kind="joint", n_images=21, oracle=False, ut_alpha=0.0)
