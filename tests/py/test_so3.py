"""SO(3) through the bindings: properties and boundary validation."""

import fsw_bindings as fb
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

RNG = np.random.default_rng(20261122)


def random_vectors(count=200):
    dirs = RNG.normal(size=(count, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    mags = np.concatenate([np.zeros(1), 10.0 ** RNG.uniform(-9, np.log10(3.1), count - 1)])
    return dirs * mags[:, None]


def test_log_of_exp_is_identity():
    for v in random_vectors():
        np.testing.assert_allclose(fb.so3_log(fb.so3_exp(v)), v, atol=1e-12)


def test_boxminus_of_boxplus_is_identity():
    for v, d in zip(random_vectors(), random_vectors()):
        q = fb.so3_exp(v)
        np.testing.assert_allclose(fb.boxminus(fb.boxplus(q, d), q), d, atol=1e-11)


def test_exp_matches_scipy_rotation_scalar_first():
    # scipy's as_quat is scalar-last [x, y, z, w]; ours is scalar-first.
    for v in random_vectors(50):
        ref = Rotation.from_rotvec(v).as_quat()
        q = fb.so3_exp(v)
        np.testing.assert_allclose(q, np.roll(ref, 1) * np.sign(ref[3] or 1.0), atol=1e-12)
        np.testing.assert_allclose(fb.rotation_matrix(q), Rotation.from_rotvec(v).as_matrix(), atol=1e-12)


@pytest.mark.parametrize("bad", [np.zeros(2), np.zeros(4), np.zeros((3, 1))])
def test_wrong_shape_raises_value_error_naming_argument(bad):
    with pytest.raises(ValueError, match="phi: expected shape"):
        fb.so3_exp(bad)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_raises_value_error_naming_argument(value):
    with pytest.raises(ValueError, match="delta: element 1 is not finite"):
        fb.boxplus(np.array([1.0, 0, 0, 0]), np.array([0.0, value, 0.0]))


def test_non_unit_quaternion_raises_value_error_naming_argument():
    with pytest.raises(ValueError, match="q0: quaternion .* unit norm"):
        fb.boxminus(np.array([1.0, 0, 0, 0]), np.array([1.0, 0.1, 0, 0]))


def test_hill_rotation_turns_fixed_body_backwards():
    n = fb.orbit_rate(fb.EARTH_RADIUS + 500e3)
    q = np.array([1.0, 0, 0, 0])
    quarter = (np.pi / 2) / n
    for _ in range(100):
        q = fb.propagate_attitude(q, np.zeros(3), n, quarter / 100)
    np.testing.assert_allclose(fb.so3_log(q), [0, 0, -np.pi / 2], atol=1e-12)
