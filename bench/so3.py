"""Rotations for the bench: unit quaternions [w, x, y, z], rotation vectors
and matrices.

Two kinds of function live here:

- The flight code's own convention, one function for each of
  fsw/include/fsw/math/so3.hpp's (docs/CONVENTIONS.md): Hamilton product,
  scalar first, ``q`` rotating body vectors into the frame it points to,
  the w >= 0 hemisphere, and the body-frame perturbations the flight filter
  uses, ``boxplus(q, d) = q (x) Exp(d)`` and ``boxminus(q1, q0) =
  Log(q0^-1 (x) q1)``. They are kept as plain numpy because they state that
  convention where the bench's models meet the flight code, and because the
  simulators call them once a step on one quaternion, where numpy's few
  microseconds beat the ten or more of building a scipy ``Rotation``:
  ``qmul``, ``qconj``, ``qnormalize``, ``qexp``, ``qlog``, ``boxplus``,
  ``boxminus``, ``rotmat``, and over rows ``qmul_many`` (scipy's composition
  costs twenty times as much there) and ``rotmats`` (Eigen's formula, which
  takes the unset all-zero state of a filter, as scipy does not).
- Everything else is scipy's ``Rotation`` behind the scalar-first order:
  ``quat_from_rotmat`` (in place of the Shepperd conversion), ``rotvec_matrix``
  and ``qexp_many``.

tests/py/test_bench_so3.py checks the first kind against scipy's Rotation."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def qmul(p, q):
    """Hamilton product p (x) q."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def qconj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def qnormalize(q):
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


def qexp(phi):
    """Rotation vector [rad] -> unit quaternion."""
    phi = np.asarray(phi, dtype=float)
    a = np.linalg.norm(phi)
    if a < 1e-8:
        return qnormalize(np.concatenate([[1.0 - a * a / 8.0], 0.5 * phi]))
    return np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * phi / a])


def qlog(q):
    """Unit quaternion -> rotation vector [rad], angle in [0, pi]."""
    q = qnormalize(q)
    v = q[1:]
    s = np.linalg.norm(v)
    if s < 1e-8:
        return 2.0 * v / q[0]
    return 2.0 * np.arctan2(s, q[0]) * v / s


def boxplus(q, dtheta):
    """q (x) Exp(dtheta), dtheta in the body frame of q."""
    return qmul(q, qexp(dtheta))


def boxminus(q1, q0):
    """Log(q0^-1 (x) q1): the body-frame rotation from q0 to q1."""
    return qlog(qmul(qconj(q0), q1))


def rotmat(q):
    """3x3 matrix taking body vectors into the frame q points to."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def qmul_many(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product row by row, (N, 4) x (N, 4) -> (N, 4)."""
    pw, px, py, pz = p.T
    qw, qx, qy, qz = q.T
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=1,
    )


def rotmats(q: np.ndarray) -> np.ndarray:
    """(N, 4) wxyz -> (N, 3, 3) body-to-frame matrices: rotmat row by row,
    as Eigen's toRotationMatrix, so a row of zeros (a filter state not yet
    set) gives the identity where scipy refuses it."""
    q = np.atleast_2d(q)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3, 3))
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - w * z)
    out[:, 0, 2] = 2 * (x * z + w * y)
    out[:, 1, 0] = 2 * (x * y + w * z)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - w * x)
    out[:, 2, 0] = 2 * (x * z - w * y)
    out[:, 2, 1] = 2 * (y * z + w * x)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


# --------------------------------------------------------------------- scipy


def _wxyz(r: Rotation) -> np.ndarray:
    """scipy's quaternions [x, y, z, w] in the scalar-first order."""
    return r.as_quat()[..., [3, 0, 1, 2]]


def quat_from_rotmat(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) or matrices (N, 3, 3) -> unit quaternion(s)
    [w, x, y, z], w >= 0."""
    q = _wxyz(Rotation.from_matrix(np.asarray(R, float)))
    return np.where(q[..., :1] < 0.0, -q, q)


def rotvec_matrix(phi) -> np.ndarray:
    """Exp(phi) as a 3x3 matrix; (N, 3) rotation vectors give (N, 3, 3)."""
    return Rotation.from_rotvec(np.asarray(phi, float)).as_matrix()


def qexp_many(phi: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors [rad] -> (N, 4) unit quaternions."""
    return _wxyz(Rotation.from_rotvec(np.asarray(phi, float)))
