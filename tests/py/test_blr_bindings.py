"""fsw_bindings.ThrusterBlr against an independent batch ridge least-squares
solve of the same window (numpy lstsq) and against bench/perf/blr_numpy.py."""

import numpy as np
import pytest

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "ThrusterBlr"):
    pytest.skip("fsw_bindings built without the thruster learner", allow_module_level=True)

from bench.perf.blr_numpy import NumpyBlr  # noqa: E402

LAMBDA = 1e-3


def features(mask):
    return np.r_[[(mask >> i) & 1 for i in range(8)], 1.0].astype(float)


def samples(n, seed):
    rng = np.random.default_rng(seed)
    theta = rng.standard_normal((9, 6))
    mask, out = 0, []
    for _ in range(n):
        mask ^= 1 << int(rng.integers(8))
        x = features(mask)
        out.append((mask, x, theta.T @ x + 0.1 * rng.standard_normal(6)))
    return out


def batch_theta(xs, ys):
    X = np.vstack([np.array(xs), np.sqrt(LAMBDA) * np.eye(9)])
    Y = np.vstack([np.array(ys), np.zeros((9, 6))])
    return np.linalg.lstsq(X, Y, rcond=None)[0]


def test_theta_matches_batch_solve_of_last_30_samples():
    b = fb.ThrusterBlr(prior_precision=LAMBDA)
    data = samples(500, 1)
    for mask, _x, y in data:
        b.add_mask(mask, y)
    ref = batch_theta([d[1] for d in data[-30:]], [d[2] for d in data[-30:]])
    assert b.count == 30
    assert np.linalg.norm(b.theta - ref) / np.linalg.norm(ref) < 1e-9


def test_prediction_matches_numpy_implementation():
    b = fb.ThrusterBlr(prior_precision=LAMBDA)
    n = NumpyBlr(prior_precision=LAMBDA)
    for _mask, x, y in samples(200, 2):
        b.add(x, y)
        n.add(x, y)
    xq = features(0b10110001)
    mean, var, status = b.predict(xq)
    mean_n, var_n = n.predict(xq)
    assert status == "ok"
    np.testing.assert_allclose(mean, mean_n, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(var, var_n, rtol=1e-8)


def test_add_reports_eviction_once_full():
    b = fb.ThrusterBlr()
    recs = [b.add_mask(m % 256, np.ones(6)) for m in range(31)]
    assert not recs[29]["evicted"] and recs[29]["count"] == 30
    assert recs[30]["evicted"] and recs[30]["count"] == 30


def test_nan_output_is_value_error_and_window_unchanged():
    b = fb.ThrusterBlr()
    b.add_mask(3, np.ones(6))
    y = np.ones(6)
    y[2] = np.nan
    with pytest.raises(ValueError, match="y"):
        b.add_mask(5, y)
    assert b.count == 1


def test_mask_out_of_range_is_value_error():
    with pytest.raises(ValueError, match="mask"):
        fb.ThrusterBlr().add_mask(256, np.ones(6))


def test_remove_from_empty_window_reports_bad_input():
    assert fb.ThrusterBlr().remove_oldest() == "bad_input"


def test_pairs_features_have_37_inputs():
    x = fb.ThrusterBlrPairs.features(0b11)
    assert x.shape == (37,) and x[8] == 1.0 and x[9] == 1.0 and x[10:].sum() == 0.0


def test_variance_of_the_mean_excludes_measurement_noise_and_shrinks_with_data():
    import fsw_bindings as fb

    rng = np.random.default_rng(4)
    b = fb.ThrusterBlr()
    for _i in range(30):
        b.add_mask(int(rng.integers(1, 256)), 1e-3 * rng.standard_normal(6))
    mean, var_mean = b.mean_and_its_variance_mask(3)
    mean_p, var_pred, _ = b.predict_mask(3)
    assert np.array_equal(mean, mean_p)
    assert np.all(var_mean > 0) and np.all(var_mean < var_pred)
    for _ in range(29):  # the window fills with configuration 3
        b.add_mask(3, 1e-3 * rng.standard_normal(6))
    assert np.all(b.mean_and_its_variance_mask(3)[1] < var_mean)
