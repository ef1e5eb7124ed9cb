"""The flight frequency acquisition (fsw/include/fsw/modal/modal_acquisition.hpp)
through the bindings: on a simulated plate it picks the same grid
frequencies as the numpy RELAX of bench/campaigns/modal_batch_ml.py, and its inputs are
checked."""

import numpy as np
import pytest

from bench.campaigns import modal_campaign as mc
from bench.perf import perf_modal_acquisition as perf


@pytest.mark.parametrize("seed", [0, 3])
def test_flight_search_picks_the_numpy_relax_frequencies(seed):
    recs, t, w_prior = perf.plate_history(10, 80, 60.0, seed=seed)
    sigma_w = 0.1 * w_prior
    acq = mc._fb().ModalAcquisition10(w_prior, sigma_w)
    assert all(acq.add(tk, r) == "ok" for tk, r in zip(t, recs))
    assert acq.images == len(recs) and not acq.done
    assert acq.search() == "ok" and acq.done
    coarse = np.array([r.a_coarse for r in recs])
    cov = np.array([r.cov_a for r in recs])
    w_np = perf.numpy_relax(coarse, cov, t, w_prior, sigma_w)
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


def test_timing_command_compares_like_with_like(tmp_path, monkeypatch):
    import json

    out = tmp_path / "t.json"
    monkeypatch.setattr(perf, "CASES", ((10, 30, 60.0),))
    assert perf.main(["--repeats", "1", "--numpy-repeats", "1", "--json", str(out)]) == 0
    (case,) = json.loads(out.read_text())["cases"]
    assert case["modes"] == 10 and case["images"] == 30 and case["replay_fused"] == 30
    assert case["same_grid_frequencies"] is True
    assert case["flight_search_s"] > 0 and case["numpy_search_s"] > 0


def test_grid_span_reaches_the_flight_search():
    def searched(k):
        tr = mc.plate_trial(
            1,
            n_modes=10,
            kind="joint",
            n_images=81,
            crb_periods=(2.0,),
            acquire_periods=1.0,
            acquire_grid_sigmas=k,
            oracle=False,
        )
        assert tr["acquisition"]["grid_sigmas"] == k
        return np.abs(np.asarray(tr["acquisition"]["omega_radps"]) / np.asarray(tr["omega_prior_radps"]) - 1)

    assert np.max(searched(0.2)) <= 0.02 * (1 + 1e-12)  # +-0.2 sigma of 10 %
    assert np.max(searched(3.0)) > 0.02  # a priori errors up to 10 %: the full span moves off the prior
    with pytest.raises(ValueError, match="flight search only"):
        mc.plate_trial(
            1,
            n_modes=10,
            kind="joint",
            n_images=81,
            crb_periods=(2.0,),
            acquire_periods=1.0,
            acquire_with="batch-ml",
            acquire_grid_sigmas=2.0,
            oracle=False,
        )
