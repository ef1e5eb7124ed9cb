"""The flight frequency acquisition (fsw/include/fsw/modal_acquisition.hpp)
through the bindings: on a simulated plate it picks the same grid
frequencies as the numpy RELAX of bench/modal_batch_ml.py, and its inputs are
checked."""
import numpy as np
import pytest

from bench import modal_batch_ml
from bench import modal_campaign as mc
from bench import structure as st


def _plate_records(seed, n_modes, n_images, dt_s):
    fb = mc._fb()
    rng = np.random.default_rng(seed)
    plate = st.Plate(n_modes=n_modes)
    sensor = st.plate_sensor(plate)
    amp, phase = st.plate_truth(plate, rng)
    w_prior = plate.omega_radps * (1 + rng.uniform(-0.1, 0.1, n_modes))
    dec = getattr(fb, f"ModalDecomposition{n_modes}")()
    recs, t = [], []
    for k in range(n_images):
        a = st.plate_coeffs(plate, amp, phase, k * dt_s)
        r_meas, d = st.plate_range_image(plate, sensor, a, rng, noise_frac=0.03)
        rec = dec.decompose(*st.plate_points(plate, sensor, r_meas, d, noise_frac=0.03))
        if rec.ok:
            recs.append(rec)
            t.append(k * dt_s)
    return recs, np.array(t), w_prior


def _numpy_relax(coarse, cov, t, w_prior, sigma_w):
    m = coarse.shape[1]
    wh = modal_batch_ml._whiteners(cov)

    def amplitudes(w):
        basis = np.concatenate([np.cos(np.outer(t, w))[:, None, :] * np.eye(m)[None],
                                np.sin(np.outer(t, w))[:, None, :] * np.eye(m)[None]], axis=2)
        a = np.einsum("kij,kjl->kil", wh, basis).reshape(-1, 2 * m)
        y = np.einsum("kij,kj->ki", wh, coarse).ravel()
        return np.linalg.lstsq(a, y, rcond=None)[0]

    var = np.diagonal(cov, axis1=1, axis2=2)
    w0 = modal_batch_ml._grid_start(coarse, var, t, w_prior, sigma_w, 201)
    return modal_batch_ml._relax_start(coarse, np.linalg.inv(cov), t, w_prior, sigma_w, w0, 201, amplitudes=amplitudes)


@pytest.mark.parametrize("seed", [0, 3])
def test_flight_search_picks_the_numpy_relax_frequencies(seed):
    recs, t, w_prior = _plate_records(seed, 10, 80, 60.0)
    sigma_w = 0.1 * w_prior
    acq = mc._fb().ModalAcquisition10(w_prior, sigma_w)
    assert all(acq.add(tk, r) == "ok" for tk, r in zip(t, recs))
    assert acq.images == len(recs) and not acq.done
    assert acq.search() == "ok" and acq.done
    coarse = np.array([r.a_coarse for r in recs])
    cov = np.array([r.cov_a for r in recs])
    w_np = _numpy_relax(coarse, cov, t, w_prior, sigma_w)
    # same grid point for every mode (one grid step is 0.3 % of the prior)
    np.testing.assert_allclose(acq.omega, w_np, rtol=1e-12)
    assert np.any(np.abs(w_np / w_prior - 1) > 0.01)  # the search moved off the prior
    # a stored image comes back as it went in
    back = acq.coarse(5)
    np.testing.assert_allclose(back.a_coarse, recs[5].a_coarse, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.cov_a, recs[5].cov_a, rtol=1e-9, atol=0)


def test_inputs_are_checked():
    fb = mc._fb()
    w = np.linspace(1.0, 2.0, 10)
    with pytest.raises(ValueError, match="sigma_omega_radps"):
        fb.ModalAcquisition10(w, np.zeros(10))
    with pytest.raises(ValueError, match="omega_prior_radps"):
        fb.ModalAcquisition10(w[:3], 0.1 * w[:3])
    with pytest.raises(ValueError, match="cycles"):
        fb.ModalAcquisition10(w, 0.1 * w, cycles=0)
    with pytest.raises(ValueError, match="min_images"):
        fb.ModalAcquisition10(w, 0.1 * w, min_images=2)
    acq = fb.ModalAcquisition10(w, 0.1 * w)
    assert acq.search() == "too_few_images"
    with pytest.raises(IndexError, match="image index"):
        acq.coarse(0)
    bad = fb.ModalDecomposition10().decompose(np.ones((3, 10)), np.zeros(3))  # too few points
    assert acq.add(0.0, bad) == "not_usable" and acq.images == 0
