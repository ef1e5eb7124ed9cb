"""Nonlinear relative orbital motion about a circular host orbit (truth for
checking the Clohessy-Wiltshire model).

The host flies a circular orbit of radius ``a`` in the inertial x-y plane.
The relative position rho (inertial axes) obeys
    rho'' = -mu (R + rho) / |R + rho|^3 + mu R / |R|^3,
integrated directly so that nothing cancels at metre separations. Results are
expressed in the Hill frame (x radial, y along-track, z orbit normal).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

MU_EARTH = 3.986004418e14  # [m^3/s^2]
EARTH_RADIUS = 6378137.0  # [m]


def orbit_rate(radius_m: float, mu: float = MU_EARTH) -> float:
    """Circular-orbit rate n = sqrt(mu / a^3) [rad/s]; a is the radius [m]."""
    return float(np.sqrt(mu / radius_m**3))


def _host(t: float, radius_m: float, n: float):
    c, s = np.cos(n * t), np.sin(n * t)
    r = radius_m * np.array([c, s, 0.0])
    v = radius_m * n * np.array([-s, c, 0.0])
    c_ih = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # Hill -> inertial
    return r, v, c_ih


def hill_to_inertial_relative(t, state_hill, radius_m, n):
    """Hill-frame relative state [r, v] -> inertial relative state [rho, rho_dot]."""
    _, _, c_ih = _host(t, radius_m, n)
    r_h, v_h = np.asarray(state_hill[:3]), np.asarray(state_hill[3:])
    omega = np.array([0.0, 0.0, n])
    rho = c_ih @ r_h
    rho_dot = c_ih @ (v_h + np.cross(omega, r_h))
    return np.concatenate([rho, rho_dot])


def inertial_to_hill_relative(t, state_inertial, radius_m, n):
    """Inverse of :func:`hill_to_inertial_relative`."""
    _, _, c_ih = _host(t, radius_m, n)
    r_h = c_ih.T @ state_inertial[:3]
    omega = np.array([0.0, 0.0, n])
    v_h = c_ih.T @ state_inertial[3:] - np.cross(omega, r_h)
    return np.concatenate([r_h, v_h])


def propagate_two_body(state0_hill, radius_m, t_eval, mu=MU_EARTH, accel_hill=None, rtol=1e-12, atol=1e-12):
    """Relative state in the Hill frame at times ``t_eval`` [s] from exact
    two-body motion of host and inspector.

    ``accel_hill(t, state_hill) -> (3,)`` adds a Hill-frame acceleration
    [m/s^2] to the inspector (thrust, disturbances); None for a free drift.
    Returns an array of shape (len(t_eval), 6).
    """
    n = orbit_rate(radius_m, mu)
    t_eval = np.asarray(t_eval, dtype=float)
    y0 = hill_to_inertial_relative(float(t_eval[0]), state0_hill, radius_m, n)

    def rhs(t, y):
        r_host, _, c_ih = _host(t, radius_m, n)
        rho = y[:3]
        r_insp = r_host + rho
        acc = -mu * r_insp / np.linalg.norm(r_insp) ** 3 + mu * r_host / radius_m**3
        if accel_hill is not None:
            acc = acc + c_ih @ np.asarray(accel_hill(t, inertial_to_hill_relative(t, y, radius_m, n)))
        return np.concatenate([y[3:], acc])

    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), y0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"two-body integration failed: {sol.message}")
    return np.array([inertial_to_hill_relative(t, y, radius_m, n) for t, y in zip(sol.t, sol.y.T)])


def second_order_accel_bound(rho_max_m: float, radius_m: float, mu: float = MU_EARTH) -> float:
    """Upper bound [m/s^2] on the gravity terms CW neglects at separation rho.

    The second-order Taylor term of -mu r/|r|^3 about the host is
    (3 mu / r^4) [ (r_hat . rho) rho + |rho|^2 r_hat / 2 - 5/2 (r_hat . rho)^2 r_hat ],
    whose norm is at most (3 mu / r^4)(1 + 1/2 + 5/2) |rho|^2 = 12 mu |rho|^2 / r^4.
    Third-order terms are smaller by another factor rho / r (1e-6 at 10 m).
    """
    return 12.0 * mu * rho_max_m**2 / radius_m**4
