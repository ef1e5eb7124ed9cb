"""Modal estimator through the bindings: the decomposition against
numpy.linalg, off-nominal statuses, and small seeded pendulum and plate runs."""

import numpy as np
import pytest

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "ModalDecomposition3"):
    pytest.skip("fsw_bindings built without the modal estimator", allow_module_level=True)

from bench.campaigns import modal_campaign as mc  # noqa: E402
from bench.sim import structure as st  # noqa: E402


def _image(m, n, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(size=n)
    phi = np.sin(np.outer(x, np.arange(1, m + 1)) * np.pi)
    a = rng.standard_normal(m)
    var = 1e-4 * (1 + 3 * rng.uniform(size=n))
    z = phi @ a + np.sqrt(var) * rng.standard_normal(n)
    return phi, z, var


@pytest.mark.parametrize("m", [3, 10])
def test_decomposition_matches_numpy_lstsq_with_nan_points(m):
    phi, z, _ = _image(m, 200, 1)
    z[[5, 17, 99]] = np.nan
    dec = getattr(fb, f"ModalDecomposition{m}")(sigma_e_m=0.01)
    r = dec.decompose(phi, z)
    ok = np.isfinite(z)
    a_ref, *_ = np.linalg.lstsq(phi[ok], z[ok], rcond=None)
    cov_ref = 1e-4 * np.linalg.inv(phi[ok].T @ phi[ok])
    assert r.status == "ok"
    assert r.n_nonfinite == 3 and r.n_used == 197
    np.testing.assert_allclose(r.a_coarse, a_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r.cov_a, cov_ref, rtol=1e-9)
    assert r.condition_number == pytest.approx(np.linalg.cond(phi[ok].T @ phi[ok]), rel=1e-8)


def test_per_point_variance_covariance_matches_numpy_sandwich():
    phi, z, var = _image(3, 80, 2)
    r = fb.ModalDecomposition3().decompose(phi, z, var)
    mi = np.linalg.inv(phi.T @ phi)
    assert r.per_point_variance
    np.testing.assert_allclose(r.cov_a, mi @ phi.T @ np.diag(var) @ phi @ mi, rtol=1e-9)


def test_too_few_points_gives_status_and_no_update():
    phi, z, _ = _image(3, 3, 3)
    rec = fb.ModalDecomposition3(sigma_e_m=0.01).decompose(phi, z)
    assert rec.status == "too_few_points"
    good = fb.ModalDecomposition3(sigma_e_m=0.01).decompose(*_image(3, 100, 4)[:2])
    f = mc.make_filter("bank", 3, [1, 2, 3], [0, 0, 0], 1, 0.1, 0.01, 0, 0)
    twin = mc.make_filter("bank", 3, [1, 2, 3], [0, 0, 0], 1, 0.1, 0.01, 0, 0)
    assert f.step(0.1, good)["status"] == "ok" and twin.step(0.1, good)["status"] == "ok"
    r = f.step(0.1, rec)  # time advances (predict), nothing is fused
    assert r["status"] == "bad_input" and not r["fused"] and r["decomposition"] == "too_few_points"
    assert twin.predict(0.1) == "ok"
    np.testing.assert_array_equal(f.state, twin.state)


def test_ill_conditioned_cases_are_reported():
    cases = mc.plate_aliased_case(10)
    assert cases["too_few_points"]["status"] == "too_few_points"
    assert cases["aliased_diagonal"]["status"] == "ill_conditioned"


def test_shape_reconstruction_matches_numpy():
    rng = np.random.default_rng(5)
    a = rng.standard_normal(3)
    b = rng.standard_normal((3, 3))
    cov = b @ b.T
    phi = rng.standard_normal((7, 3))
    z, var = fb.reconstruct_shape3(a, cov, phi)
    np.testing.assert_allclose(z, phi @ a, rtol=1e-12)
    np.testing.assert_allclose(var, np.einsum("ki,ij,kj->k", phi, cov, phi), rtol=1e-12)


def test_bad_array_shape_is_value_error():
    with pytest.raises(ValueError, match="phi"):
        fb.ModalDecomposition3().decompose(np.zeros((10, 4)), np.zeros(10))
    with pytest.raises(ValueError, match="z_m"):
        fb.ModalDecomposition3().decompose(np.zeros((10, 3)), np.zeros(9))


@pytest.mark.parametrize("kind", ["bank", "joint"])
def test_pendulum_first_two_modes_converge_within_90_measurements(kind):
    tr = mc.pendulum_trial(0, kind=kind)
    assert tr["measurements_to_converge"] is not None and tr["measurements_to_converge"] <= 90
    np.testing.assert_allclose(tr["omega_final_radps"][:2], st.PENDULUM_OMEGA[:2], rtol=0.005)
    np.testing.assert_allclose(tr["alpha_final_ps"][:2], st.PENDULUM_ALPHA[:2], atol=0.02)
    assert tr["n_nonfinite_points"] > 0  # the dropouts were skipped, not fatal


def test_plate_10_modes_frequencies_and_shape_converge():
    # Joint filter, central-quarter view, 3 % range noise, 120 images = 3
    # periods of the lowest mode: every mode excited to >= 0.2 has its
    # frequency within 1 % by then, and the shape error over the whole plate
    # is within twice the known-frequency floor.
    tr = mc.plate_trial(0, n_modes=10, n_images=120, kind="joint")
    assert tr["n_not_ok"] == 0
    assert tr["time_to_converge_1pct_excited_periods"] is not None
    assert tr["time_to_converge_1pct_excited_periods"] <= 3.0
    assert tr["shape_converge_periods"] is not None and tr["shape_converge_periods"] <= 3.0


def test_footprint_mode_shapes_do_not_move_with_the_range_noise():
    plate = st.Plate(n_modes=10)
    sensor = st.plate_sensor(plate)
    a = np.linspace(0.5, -0.5, 10)
    r1, d = st.plate_range_image(plate, sensor, a, np.random.default_rng(1))
    r2, _ = st.plate_range_image(plate, sensor, a, np.random.default_rng(2))
    keep = np.isfinite(r1) & np.isfinite(r2)
    f1, z1, _ = st.plate_points(plate, sensor, r1[keep], d[keep], at="footprint")
    f2, z2, _ = st.plate_points(plate, sensor, r2[keep], d[keep], at="footprint")
    m1, _, _ = st.plate_points(plate, sensor, r1[keep], d[keep])
    m2, _, _ = st.plate_points(plate, sensor, r2[keep], d[keep])
    np.testing.assert_array_equal(f1, f2)
    assert np.max(np.abs(m1 - m2)) > 0.02 * np.max(np.abs(m1))  # at the measured point they do
    assert np.max(np.abs(z1 - z2)) > 1.0  # the deflection is measured either way
    with pytest.raises(ValueError, match="at: one of"):
        st.plate_points(plate, sensor, r1, d, at="centre")


def test_coarse_amplitudes_are_consistent_at_the_footprint_and_biased_at_the_measured_point(capsys):
    # Pooled over 3 runs of 60 images (10 modes): with the mode shapes at the
    # measured point the range noise enters the regressors too (errors in
    # variables) and eq. 4's covariance no longer describes the error; at the
    # ray's footprint it does. NEES standard error here: sqrt(20 / 180) = 0.33.
    from bench.campaigns.modal_study import coarse_check_summary

    rows = {}
    for at in ("measured", "footprint"):
        trials = [
            mc.plate_trial(s, n_modes=10, kind="joint", n_images=60, oracle=False, points_at=at, coarse_check=True)
            for s in range(3)
        ]
        assert all(t["points_at"] == at for t in trials)
        rows[at] = coarse_check_summary(trials, 10, at)
    assert rows["footprint"]["images"] == 180
    assert abs(rows["footprint"]["nees_mean"] - 10) < 4 * rows["footprint"]["nees_mean_se"]
    assert rows["footprint"]["modes_biased_4se"] == []
    assert rows["measured"]["nees_mean"] > 12.0
    assert 1 in rows["measured"]["modes_biased_4se"]  # the (1, 1) mode, symmetric about the view's centre
    assert rows["measured"]["bias_sigma"][0] < -0.5
    assert "NEES mean" in capsys.readouterr().out
