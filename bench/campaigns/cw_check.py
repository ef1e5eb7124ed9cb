"""CW linearisation check: the flight CW propagator (through the bindings)
against exact two-body relative motion, with the error bound linearisation
predicts."""

from __future__ import annotations

import fsw_bindings as fb
import numpy as np

from bench.sim import orbit


# Initial relative states [m, m/s] at 10 m separation in a 500 km orbit.
def cases(n: float, sep_m: float = 10.0):
    return {
        "along-track station": np.array([0.0, sep_m, 0, 0, 0, 0]),
        "radial, closed ellipse": np.array([sep_m, 0, 0, 0, -2 * n * sep_m, 0]),
        "cross-track oscillation": np.array([0, 0, sep_m, 0, 0, 0]),
        "radial, released at rest": np.array([sep_m, 0, 0, 0, 0, 0]),
    }


def run_case(state0, radius_m, n_samples=401, orbits=1.0):
    n = orbit.orbit_rate(radius_m)
    t = np.linspace(0.0, orbits * 2 * np.pi / n, n_samples)
    truth = orbit.propagate_two_body(state0, radius_m, t)
    cw = np.array([fb.cw_stm(n, ti) @ state0 for ti in t])
    err = np.linalg.norm(cw[:, :3] - truth[:, :3], axis=1)
    rho_max = 1.05 * np.max(np.linalg.norm(truth[:, :3], axis=1))
    bound = linearisation_bound(n, t[-1], rho_max, radius_m)
    return {
        "t": t,
        "truth": truth,
        "cw": cw,
        "pos_err_m": err,
        "max_pos_err_m": float(err.max()),
        "bound_m": bound,
        "rho_max_m": float(rho_max),
    }


def linearisation_bound(n, t_end, rho_max_m, radius_m, n_quad=2001):
    """Position error bound [m] at t_end: the neglected acceleration bound
    (orbit.second_order_accel_bound) pushed through the CW response,
    int_0^T ||Phi_rv(T - tau)||_2 dtau * a_max."""
    a_max = orbit.second_order_accel_bound(rho_max_m, radius_m)
    taus = np.linspace(0.0, t_end, n_quad)
    gains = [np.linalg.norm(fb.cw_stm(n, t_end - tau)[:3, 3:], 2) for tau in taus]
    return float(np.trapezoid(gains, taus) * a_max)
