"""The bench's rotations (bench/so3.py): the flight code's convention kept
in numpy against scipy's Rotation, and the forms that are scipy's against
the one-at-a-time ones."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench import so3

RNG = np.random.default_rng(20261126)


def _scipy(q):
    """scipy takes [x, y, z, w]."""
    return Rotation.from_quat(np.roll(np.asarray(q, float), -1))


def _random_quats(n=200):
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _random_rotvecs(n=200):
    v = RNG.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # angles from 1e-12 rad to just under pi, so every branch is taken
    return v * np.concatenate([[1e-12, 1e-9, 1e-6], RNG.uniform(1e-3, np.pi - 1e-6, n - 3)])[:, None]


def test_rotmat_and_product_match_scipy():
    for p, q in zip(_random_quats(), _random_quats()):
        np.testing.assert_allclose(so3.rotmat(p), _scipy(p).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(so3.rotmat(so3.qmul(p, q)), (_scipy(p) * _scipy(q)).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(so3.rotmat(so3.qconj(p)), _scipy(p).inv().as_matrix(), atol=1e-12)


def test_exp_and_log_match_scipy():
    for v in _random_rotvecs():
        np.testing.assert_allclose(so3.rotmat(so3.qexp(v)), Rotation.from_rotvec(v).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(so3.qlog(so3.qexp(v)), v, atol=1e-12)
    for q in _random_quats():
        np.testing.assert_allclose(so3.qlog(q), _scipy(q).as_rotvec(), atol=1e-10)


def test_boxplus_and_boxminus_are_inverse_in_the_body_frame():
    for q, v in zip(_random_quats(), _random_rotvecs()):
        q1 = so3.boxplus(q, v)
        np.testing.assert_allclose(so3.boxminus(q1, q), v, atol=1e-10)
        # body frame: q1 = q Exp(v), i.e. the perturbation rotates after q
        np.testing.assert_allclose(
            so3.rotmat(q1), _scipy(q).as_matrix() @ Rotation.from_rotvec(v).as_matrix(), atol=1e-12
        )


@pytest.mark.parametrize("axis", range(3))
def test_matrix_to_quaternion_near_pi_and_at_random(axis):
    # near-pi rotations about each axis: the trace is near -1
    v = np.zeros(3)
    v[axis] = np.pi - 1e-3
    for R in [Rotation.from_rotvec(v).as_matrix()] + [
        Rotation.from_quat(np.roll(q, -1)).as_matrix() for q in _random_quats(50)
    ]:
        q = so3.quat_from_rotmat(R)
        assert q[0] >= 0.0 and np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(so3.rotmat(q), R, atol=1e-12)


def test_vectorised_forms_equal_the_scalar_ones():
    p, q, v = _random_quats(), _random_quats(), _random_rotvecs()
    np.testing.assert_allclose(so3.qmul_many(p, q), np.array([so3.qmul(a, b) for a, b in zip(p, q)]), atol=1e-15)
    np.testing.assert_allclose(so3.rotmats(p), np.array([so3.rotmat(a) for a in p]), atol=1e-15)
    e = so3.qexp_many(v)
    np.testing.assert_allclose(e, np.array([so3.qexp(a) for a in v]), atol=1e-15)
    for a in v[:50]:
        np.testing.assert_allclose(so3.rotvec_matrix(a), so3.rotmat(so3.qexp(a)), atol=1e-12)


def test_matrix_to_quaternion_over_rows_keeps_the_hemisphere():
    q = _random_quats()
    out = so3.quat_from_rotmat(so3.rotmats(q))
    assert out.shape == q.shape and np.all(out[:, 0] >= 0.0)
    np.testing.assert_allclose(out, q * np.sign(q[:, :1]), atol=1e-12)
    v = _random_rotvecs(20)
    np.testing.assert_allclose(so3.rotvec_matrix(v), np.array([so3.rotvec_matrix(a) for a in v]), atol=1e-15)
