"""The dynamics channel: the IMU against what the nominal vehicle model says
the commanded valves should do. The navigation filter cannot see an effect
that changes the thrust (the accelerometer and gyro measure what really
happened), but this replay can:

  accel    e_a,k = (a_meas,k - F_nom(valves_k) / m) / sigma_a          (body, per IMU sample)
  gyro     d_k = w_k - w_{k-1} - (alpha_{k-1} + alpha_k) dt / 2,
           alpha = J^-1 (tau_nom(valves) - w x J w),
           whitened with the exact MA(1) covariance sigma_g^2 tridiag(-1, 2, -1)
           of differenced white noise (banded Cholesky per segment).

Under the nominal model both are N(0, 1) per row. Each candidate's effect
on these rows is linear in its parameters (to first order), so its
Jacobian is computed in closed form here (``jacobian``); candidates with no
signature on this channel return None.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cholesky_banded, solve_banded

from bench.gap.replay import LogData
from bench.so3 import rotmats


def _skew_rows(v: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) cross-product matrices [v]x."""
    z = np.zeros(v.shape[0])
    return np.stack(
        [np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1), np.stack([-v[:, 1], v[:, 0], z], 1)],
        1,
    )


@dataclass
class DynChannel:
    t: np.ndarray  # time of each row (2 N rows: accel block then gyro block; each row has 3 axes)
    e0: np.ndarray  # (R, 3) whitened residual rows
    kind: np.ndarray  # (R,) 0 accel, 1 gyro
    # for Jacobians
    sig_a: float
    gyro_rows: np.ndarray  # IMU indices k of the gyro rows (difference k-1 -> k)
    seg_bounds: list  # [(start, stop)] row ranges of each gyro segment (whitening)
    chol: list  # banded Cholesky factor per segment
    F: np.ndarray  # (N, 3) nominal force per IMU sample [N]
    open_: np.ndarray  # (N, 8) valve open flags
    alpha: np.ndarray  # (N, 3) nominal angular acceleration
    w: np.ndarray  # (N, 3) gyro
    vs: np.ndarray  # (N,) valve-seconds since the segment start (before the sample)
    mass: float
    dt: float
    veh: object

    @property
    def rows(self) -> int:
        return self.e0.shape[0]

    def whiten_gyro(self, x: np.ndarray) -> np.ndarray:
        """Whiten (n_gyro_rows, ...) differenced-gyro quantities already divided by sigma_g."""
        out = np.empty_like(x)
        for (a, b), L in zip(self.seg_bounds, self.chol):
            out[a:b] = solve_banded((1, 0), L, x[a:b])
        return out

    def unwhiten_gyro(self, w: np.ndarray) -> np.ndarray:
        """The raw differences (over sigma_g) behind whitened gyro rows: L w."""
        out = np.empty_like(w)
        for (a, b), L in zip(self.seg_bounds, self.chol):
            x = L[0][:, None] * w[a:b]
            x[1:] += L[1][:-1, None] * w[a : b - 1]
            out[a:b] = x
        return out

    def adjacent_gyro_rows(self) -> np.ndarray:
        """(n_gyro_rows,) True where row i and row i + 1 share a segment (their differences correlate, -1/2)."""
        adj = np.zeros(self.gyro_rows.size, bool)
        for a, b in self.seg_bounds:
            adj[a : b - 1] = True
        return adj

    def jacobian(self, name: str) -> np.ndarray | None:
        """d(e)/d(theta) (R, 3, k): the change of the whitened rows per unit parameter."""
        f = _JAC.get(name)
        return None if f is None else f(self)


def _open_seconds_before(n_open: np.ndarray, seg_id: np.ndarray) -> np.ndarray:
    """Valve-open seconds summed over all valves before each sample, restarted
    at each segment (the propellant used so far, for the mass)."""
    vs = np.zeros_like(n_open)
    for s in np.unique(seg_id):
        m = seg_id == s
        c = np.cumsum(n_open[m])
        vs[m] = c - n_open[m]
    return vs


def _difference_whiteners(seg_of_row: np.ndarray) -> tuple:
    """Per segment, the row range and the banded Cholesky factor of the
    covariance of first differences of white noise (tridiagonal 2, -1)."""
    bounds, chols = [], []
    start = 0
    for s in np.unique(seg_of_row):
        n = int(np.sum(seg_of_row == s))
        ab = np.zeros((2, n))
        ab[0] = 2.0
        ab[1, :-1] = -1.0
        chols.append(cholesky_banded(ab, lower=True))
        bounds.append((start, start + n))
        start += n
    return bounds, chols


def build(d: LogData) -> DynChannel | None:
    """The channel for a log with a valve stream (None without one), for the
    vehicle the log describes (bench/sim/log_description.py)."""
    if d.valves is None:
        return None
    from bench.sim.log_description import resolve

    desc = d.desc if d.desc is not None else resolve(None, d.config)
    veh = desc.vehicle()
    sig_a, sig_g = desc.accel_sigma_mps2, desc.gyro_sigma_rps
    open_ = np.asarray(d.valves, float)  # (N, K) open fraction of each interval
    Fi = veh.thruster_forces_b_n()  # (K, 3)
    Ti = veh.thruster_torques_b_nm()
    F = open_ @ Fi
    tau = open_ @ Ti
    J = np.asarray(veh.inertia_kgm2, float)
    Jinv = np.linalg.inv(J)
    w = d.gyro
    alpha = (tau - np.cross(w, w @ J.T)) @ Jinv.T
    e_a = (d.accel - F / veh.mass_kg) / sig_a
    # Segments (runs) reset the gyro differences and the mass.
    seg_id = d.imu_seg if d.imu_seg is not None else np.concatenate([[0], np.cumsum(np.diff(d.imu_t) > 1.5 * d.dt_s)])
    brk = np.concatenate([[True], np.diff(seg_id) != 0])
    vs = _open_seconds_before(open_.sum(axis=1) * d.dt_s, seg_id)
    k = np.flatnonzero(~brk)  # difference k-1 -> k within a segment
    # Consecutive interval means are their centres' spacing apart (the time
    # stamps' difference: jitter and dropped samples included).
    h = (d.imu_t[k] - d.imu_t[k - 1])[:, None]
    # The change of the mean rate between consecutive samples, from the
    # valves' torque exactly: each sample averages the rate over its own
    # interval, so with jittered or dropped samples the intervals overlap or
    # leave gaps, and a per-sample average of the torque would leak a drift.
    # W[r, i]: thruster i's effective open seconds in difference row r.
    W = (
        turn_weights(d.valve_stream, d.imu_t, k, d.dt_s, open_.shape[1])
        if d.valve_stream is not None
        else 0.5 * (open_[k - 1] + open_[k]) * h
    )
    gyroscopic = -np.cross(w, w @ J.T) @ Jinv.T
    turn = (W @ Ti) @ Jinv.T + 0.5 * (gyroscopic[k - 1] + gyroscopic[k]) * h
    dg = (w[k] - w[k - 1] - turn) / sig_g
    bounds, chols = _difference_whiteners(seg_id[k])
    ch = DynChannel(
        t=None,
        e0=None,
        kind=None,
        sig_a=sig_a,
        gyro_rows=k,
        seg_bounds=bounds,
        chol=chols,
        F=F,
        open_=open_,
        alpha=alpha,
        w=w,
        vs=vs,
        mass=veh.mass_kg,
        dt=d.dt_s,
        veh=veh,
    )
    ch.sig_g = sig_g
    ch.h = h
    ch.turn = turn
    ch.W = W
    ch.c_bh = rotmats(d.ref_q) if d.ref_q is not None else None
    e_g = ch.whiten_gyro(dg)
    ch.e0 = np.vstack([e_a, e_g])
    ch.t = np.concatenate([d.imu_t, d.imu_t[k]])
    ch.kind = np.concatenate([np.zeros(d.imu_t.size, int), np.ones(k.size, int)])
    return ch


# --- Jacobians: rows = -(change of the predicted measurement) / sigma ----------


def _stack(
    ch: DynChannel, da: np.ndarray | None, dalpha: np.ndarray | None, dturn: np.ndarray | None = None
) -> np.ndarray:
    """da: (N, 3, k) change of the predicted accelerometer; dalpha: (N, 3, k)
    change of the predicted angular acceleration (gyro differences follow);
    or dturn: (rows, 3, k) the change of each gyro difference directly."""
    k = next(x for x in (da, dalpha, dturn) if x is not None).shape[2]
    n = ch.F.shape[0]
    out = np.zeros((ch.rows, 3, k))
    if da is not None:
        out[:n] = -da / ch.sig_a
    if dalpha is not None or dturn is not None:
        g = ch.gyro_rows
        dd = (dturn if dturn is not None else 0.5 * (dalpha[g - 1] + dalpha[g]) * ch.h[:, :, None]) / ch.sig_g
        out[n:] = -ch.whiten_gyro(dd.reshape(g.size, -1)).reshape(g.size, 3, k)
    return out


def _open_time_integral(start: np.ndarray, dur: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The integral over time, up to each t, of the cumulative open time of
    pulses [start_j, start_j + dur_j) (sorted, not overlapping)."""
    cd = np.concatenate([[0.0], np.cumsum(dur)])
    ce = np.concatenate([[0.0], np.cumsum(dur * start + 0.5 * dur * dur)])
    j = np.searchsorted(start, t, side="left")  # pulses that started before t: 0 .. j-1
    full = t * cd[j] - ce[j]  # every started pulse taken as complete
    last = np.clip(j - 1, 0, None)
    part = (j > 0) & (t < start[last] + dur[last])
    # the last started pulse, still open at t: (t - s)^2 / 2 instead of its complete form
    s, dd = start[last], dur[last]
    full = full - np.where(part, dd * t - (dd * s + 0.5 * dd * dd) - 0.5 * (t - s) ** 2, 0.0)
    return full


def turn_weights(valves: dict, t: np.ndarray, rows: np.ndarray, dt: float, n_thrusters: int) -> np.ndarray:
    """(len(rows), K): for each difference of consecutive interval means
    (sample k - 1 to k, k in ``rows``), the effective open seconds of each
    valve: mean over (t_k - dt, t_k] minus mean over (t_{k-1} - dt, t_{k-1}]
    of the cumulative open time."""
    vt = np.asarray(valves["t_s"], np.float64)
    if "on_time_s" in valves:
        on = np.asarray(valves["on_time_s"], float).reshape(vt.size, -1)
    else:
        mask = np.asarray(valves["mask"]).astype(np.int64)
        on = ((mask[:, None] >> np.arange(n_thrusters)[None, :]) & 1) * np.asarray(valves["interval_s"], float)[:, None]
    a, b = t[rows], t[rows - 1]
    out = np.zeros((rows.size, n_thrusters))
    for i in range(n_thrusters):
        m = on[:, i] > 0.0
        if not np.any(m):
            continue
        s, du = vt[m], on[m, i]
        out[:, i] = (
            _open_time_integral(s, du, a)
            - _open_time_integral(s, du, a - dt)
            - _open_time_integral(s, du, b)
            + _open_time_integral(s, du, b - dt)
        ) / dt
    return out


def _jac_accel_bias(ch):
    n = ch.F.shape[0]
    return _stack(ch, np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), None)


def _jac_thrust_loss(ch):
    # a = sum_i (1 - loss_i) F_i open_i / m
    Fi = ch.veh.thruster_forces_b_n()
    Ti = ch.veh.thruster_torques_b_nm()
    Jinv = np.linalg.inv(np.asarray(ch.veh.inertia_kgm2, float))
    da = -(ch.open_[:, None, :] * Fi.T[None, :, :]) / ch.mass
    dturn = -(ch.W[:, None, :] * (Ti @ Jinv.T).T[None, :, :])
    return _stack(ch, da, None, dturn)


def _jac_misalign(ch):
    # d_i -> d_i + phi_i x d_i: force change -T [d_i]x phi_i, torque r_i x that.
    veh = ch.veh
    T = np.linalg.norm(veh.thruster_forces_b_n(), axis=1)
    Jinv = np.linalg.inv(np.asarray(veh.inertia_kgm2, float))
    n, nt = ch.F.shape[0], veh.n_thrusters
    da = np.zeros((n, 3, 3 * nt))
    dturn = np.zeros((ch.gyro_rows.size, 3, 3 * nt))
    for i in range(nt):
        d = veh.directions_b[i]
        r = veh.positions_b_m[i]
        Sd = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
        Sr = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        dF = -T[i] * Sd  # d(force)/d(phi_i)
        da[:, :, 3 * i : 3 * i + 3] = ch.open_[:, i, None, None] * dF[None] / ch.mass
        dturn[:, :, 3 * i : 3 * i + 3] = ch.W[:, i, None, None] * (Jinv @ Sr @ dF)[None]
    return _stack(ch, da, None, dturn)


def _jac_com(ch):
    # Torques about the true centre of mass c: tau - c x F = tau + [F]x c;
    # accelerometer at the body origin: a_cm - alpha x c - w x (w x c).
    Jinv = np.linalg.inv(np.asarray(ch.veh.inertia_kgm2, float))
    dturn = Jinv[None] @ _skew_rows(ch.W @ ch.veh.thruster_forces_b_n())
    Sw = _skew_rows(ch.w)
    da = -_skew_rows(ch.alpha) - Sw @ Sw
    return _stack(ch, da, None, dturn)


def _jac_mass(ch):
    # a = F / (m - mdot V): d a / d mdot = F V / m^2 (V valve-seconds used so far)
    da = (ch.F * ch.vs[:, None] / ch.mass**2)[:, :, None]
    return _stack(ch, da, None)


def _jac_gyro_scale(ch):
    n = ch.F.shape[0]
    dal = np.zeros((n, 3, 3))
    dal[:, [0, 1, 2], [0, 1, 2]] = ch.alpha
    return _stack(ch, None, dal)


def _jac_imu_misalign(ch):
    # The IMU reads C(phi)^T v ~ v + [v]x phi.
    a_nom = ch.F / ch.mass
    return _stack(ch, _skew_rows(a_nom), _skew_rows(ch.alpha))


def _jac_drag(ch):
    # The accelerometer senses the inspector's own drag, along Hill y:
    # C_bh e_y = row 1 of C_hb. The host's drag has no signature here.
    n = ch.F.shape[0]
    da = np.zeros((n, 3, 2))
    if ch.c_bh is not None:
        da[:, :, 0] = ch.c_bh[:, 1, :]
    return _stack(ch, da, None)


def _jac_clock(ch):
    # Every time of the log on a clock fast by eps: true intervals are the
    # tagged ones over 1 + eps, so each predicted change of the rate (valve
    # open seconds and the gyroscopic term, both integrals over time) shrinks
    # by 1 + eps: d(turn)/d(eps) = -turn. The accelerometer rows compare
    # means over the same interval (the valves' open fraction of it does
    # not change with the clock): no signature there.
    return _stack(ch, None, None, -ch.turn[:, :, None])


_JAC = {
    "clock_drift": _jac_clock,
    "differential_drag": _jac_drag,
    "accel_bias": _jac_accel_bias,
    "thrust_loss": _jac_thrust_loss,
    "thruster_misalignment": _jac_misalign,
    "com_offset": _jac_com,
    "mass_depletion": _jac_mass,
    "gyro_scale": _jac_gyro_scale,
    "imu_misalignment": _jac_imu_misalign,
}
