"""Rotations for the bench: unit quaternions [w, x, y, z] (Hamilton, scalar
first, docs/CONVENTIONS.md), rotation vectors and matrices, one at a time
and vectorised over rows. ``rotmat(q)`` takes vectors in the frame q
belongs to (the body) into the frame it points to; ``boxplus`` and
``boxminus`` are the body-frame perturbations the flight filter uses
(the flight code's so3.hpp). tests/py/test_bench_so3.py checks them against
scipy's Rotation."""

from __future__ import annotations

import numpy as np


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


def quat_from_rotmat(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion [w, x, y, z], w >= 0 (Shepperd)."""
    R = np.asarray(R, float)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    return qnormalize(np.array(q))


def rotmats(q: np.ndarray) -> np.ndarray:
    """(N, 4) wxyz -> (N, 3, 3) body-to-frame matrices."""
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


def rotvec_matrix(phi) -> np.ndarray:
    """Exp(phi) as a 3x3 matrix (Rodrigues)."""
    phi = np.asarray(phi, float)
    a = np.linalg.norm(phi)
    k = np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    if a < 1e-9:
        return np.eye(3) + k
    return np.eye(3) + np.sin(a) / a * k + (1 - np.cos(a)) / a**2 * (k @ k)


def qmul_many(p: np.ndarray, q: np.ndarray) -> np.ndarray:
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


def qexp_many(phi: np.ndarray) -> np.ndarray:
    a = np.linalg.norm(phi, axis=1)
    half = 0.5 * a
    s = np.where(a < 1e-9, 0.5 - a * a / 48.0, np.sin(half) / np.where(a < 1e-9, 1.0, a))
    q = np.concatenate([np.cos(half)[:, None], s[:, None] * phi], axis=1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)
