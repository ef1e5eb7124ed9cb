"""The dynamics channel: the IMU against what the nominal vehicle model says
the commanded valves should do. The navigation filter cannot see an effect
that changes the thrust (the accelerometer and gyro measure what really
happened), but this channel can:

  accel    e_a,k = (a_k - a_pred,k) / sigma_a                      (body axes, at the IMU, per sample)
           a_pred = F(valves) / m + alpha x rho + w x (w x rho),
           alpha = J^-1 (tau(valves) - w x J w),  rho the IMU from the centre of mass
  gyro     d_k = w_k - w_{k-1} - turn_k,
           turn_k = J^-1 (torque's open seconds over the two intervals) + the gyroscopic term's mean
           whitened with its noise's exact covariance: the difference of two
           samples' noise and that noise passed through the gyroscopic term,
           (I - h/2 G_k) n_k - (I + h/2 G_k-1) n_k-1 with G its derivative at the
           measured rate (banded Cholesky per segment, axes coupled).

Under the nominal model both are N(0, 1) per row.

Every candidate that touches this channel enters it exactly, in the axes it
acts in (``DynChannel.residual``): the IMU's own errors (bias, scale factor,
misalignment) are undone on the raw samples in the IMU's axes before they
are turned into body axes, so they reach every place the measured rate is
used, the gyroscopic term ``w x J w`` and the accelerometer's lever arm
included; a thrust loss, a nozzle tilt (a rotation of the valve's
direction), a centre-of-mass offset (torque arms and the accelerometer's
lever arm), propellant use (the mass at each sample), the inspector's own
drag and a drifting clock (every interval over 1 + eps) change the
prediction. A candidate's Jacobian is the forward difference of that exact
residual (``jacobian``), so the screen, the fits and the corrections all
use one model; candidates with no signature here return None.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cholesky_banded, solve_banded

from bench.gap.load import LogData
from bench.so3 import rotmats, rotvec_matrix

# Candidates with a signature in this channel, and the parameters each takes.
DYN_CANDIDATES = (
    "accel_bias",
    "gyro_bias",
    "gyro_scale",
    "imu_misalignment",
    "clock_drift",
    "thrust_loss",
    "thruster_misalignment",
    "com_offset",
    "mass_depletion",
    "differential_drag",
)
# Candidates whose Jacobian in this channel does not read the IMU's
# measurements (valve forces and torques, the mass, a constant bias, the
# drag): the same for every noise draw of one flight, so a calibration's
# null runs can share their log's. The others (a gyro scale or misalignment
# scales or turns the measured rate, a clock stretches it, a centre-of-mass
# offset moves the lever arm the measured rate acts through) carry each
# draw's noise, and that correlation is part of their null statistic.
READINGS_FREE = ("accel_bias", "thrust_loss", "thruster_misalignment", "mass_depletion", "differential_drag")


def _gyroscopic_jacobian(w: np.ndarray, J: np.ndarray, Jinv: np.ndarray) -> np.ndarray:
    """(N, 3, 3) d/dw of the gyroscopic acceleration -J^-1 (w x J w):
    -J^-1 ([w]x J - [J w]x)."""
    return -Jinv[None] @ (_skew_rows(w) @ J[None] - _skew_rows(w @ J.T))


def _skew_rows(v: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) cross-product matrices [v]x."""
    z = np.zeros(v.shape[0])
    return np.stack(
        [np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1), np.stack([-v[:, 1], v[:, 0], z], 1)],
        1,
    )


@dataclass
class DynChannel:
    t: np.ndarray  # time of each row (accel rows, one per IMU sample, then gyro rows; each row has 3 axes)
    e0: np.ndarray  # (R, 3) whitened residual rows under the nominal model
    kind: np.ndarray  # (R,) 0 accel, 1 gyro
    sig_a: float
    sig_g: float
    gyro_rows: np.ndarray  # IMU indices k of the gyro rows (difference k-1 -> k)
    seg_bounds: list  # [(start, stop)] row ranges of each gyro segment (whitening)
    chol: list | None  # banded Cholesky factor per segment (gyro_whiteners)
    open_: np.ndarray  # (N, K) open fraction of each IMU interval per valve
    W: np.ndarray  # (rows, K) each valve's effective open seconds in each gyro difference
    h: np.ndarray  # (rows, 1) spacing of the two samples of each gyro difference [s]
    vs: np.ndarray  # (N, K) the run's valve-seconds used, averaged over each valve's open time in each interval
    dt: float
    veh: object  # the described vehicle about the described centre of mass
    rho: np.ndarray  # the IMU from the described centre of mass (body axes)
    c_bi: np.ndarray  # IMU axes -> body axes
    accel_raw: np.ndarray  # (N, 3) IMU axes
    gyro_raw: np.ndarray  # (N, 3) IMU axes
    c_hb: np.ndarray | None  # (N, 3, 3) body -> Hill along the reference trajectory, or None
    accel_whiten: np.ndarray | None = None  # (N, 3, 3) L^-1 of each accelerometer row's covariance
    _jac: dict = field(default_factory=dict)

    @property
    def rows(self) -> int:
        return self.e0.shape[0]

    @property
    def mass(self) -> float:
        return float(self.veh.mass_kg)

    def whiten_gyro(self, x: np.ndarray) -> np.ndarray:
        """Whiten (n_gyro_rows, 3, ...) differenced-gyro quantities already
        divided by sigma_g, in body axes (the axes couple: see gyro_whiteners)."""
        out = np.empty_like(x)
        for (a, b), L in zip(self.seg_bounds, self.chol):
            y = x[a:b].reshape((3 * (b - a),) + x.shape[2:])
            out[a:b] = solve_banded((L.shape[0] - 1, 0), L, y).reshape(x[a:b].shape)
        return out

    def unwhiten_gyro(self, w: np.ndarray) -> np.ndarray:
        """The raw differences (over sigma_g) behind whitened gyro rows: L w."""
        out = np.empty_like(w)
        for (a, b), L in zip(self.seg_bounds, self.chol):
            y = w[a:b].reshape((3 * (b - a),) + w.shape[2:])
            x = L[0].reshape((-1,) + (1,) * (y.ndim - 1)) * y
            for i in range(1, L.shape[0]):
                x[i:] += L[i, :-i].reshape((-1,) + (1,) * (y.ndim - 1)) * y[:-i]
            out[a:b] = x.reshape(w[a:b].shape)
        return out

    def adjacent_gyro_rows(self) -> np.ndarray:
        """(n_gyro_rows,) True where row i and row i + 1 share a segment (their differences correlate, -1/2)."""
        adj = np.zeros(self.gyro_rows.size, bool)
        for a, b in self.seg_bounds:
            adj[a : b - 1] = True
        return adj

    def mounting(self, p: dict) -> np.ndarray:
        """IMU axes -> body axes with the candidates' misalignment: the IMU
        reads C(e)^T C_ib v."""
        return self.c_bi @ rotvec_matrix(p["imu_misalignment"]) if "imu_misalignment" in p else self.c_bi

    def imu_body(self, p: dict) -> tuple:
        """(specific force, rate) (N, 3) in body axes at the IMU, with the
        candidates' sensor errors undone in the IMU's own axes: the IMU
        reads (1 + s) C(e)^T C_ib v + b, so v = C_bi C(e) (x - b) / (1 + s).
        The model's estimate of the motion (for the gyroscopic term and the
        lever arm), not the rows' measurement side."""
        M = self.mounting(p)
        a = self.accel_raw - p["accel_bias"] if "accel_bias" in p else self.accel_raw
        w = self.gyro_raw - p["gyro_bias"] if "gyro_bias" in p else self.gyro_raw
        if "gyro_scale" in p:
            w = w / (1.0 + np.asarray(p["gyro_scale"], float))
        return a @ M.T, w @ M.T

    def thrusters(self, p: dict) -> tuple:
        """(K, 3) forces and (K, 3) torques about the true centre of mass of
        each valve at full thrust, with the candidates' thrust changes."""
        veh = self.veh
        k = veh.n_thrusters
        dirs = np.asarray(veh.directions_b, float)
        if "thruster_misalignment" in p:
            phi = np.asarray(p["thruster_misalignment"], float).reshape(k, 3)
            dirs = np.einsum("kij,kj->ki", rotvec_matrix(phi), dirs)
        thrust = np.asarray(veh.thrust_n, float) * np.asarray(veh.thrust_scale, float) * np.ones(k)
        if "thrust_loss" in p:
            thrust = thrust * (1.0 - np.asarray(p["thrust_loss"], float))
        F = thrust[:, None] * dirs
        pos = np.asarray(veh.positions_b_m, float)
        if "com_offset" in p:
            pos = pos - np.asarray(p["com_offset"], float)
        return F, np.cross(pos, F)

    def residual(self, params: dict | None = None) -> np.ndarray:
        """(R, 3) whitened rows with the candidates ``params`` ({name: theta})
        applied exactly; ``residual()`` is the nominal model's ``e0``."""
        p = {k: np.asarray(v, float) for k, v in (params or {}).items()}
        _, w = self.imu_body(p)
        Fi, Ti = self.thrusters(p)
        J = np.asarray(self.veh.inertia_kgm2, float)
        Jinv = np.linalg.inv(J)
        to_true = 1.0 / (1.0 + float(p["clock_drift"][0])) if "clock_drift" in p else 1.0
        gyroscopic = -np.cross(w, w @ J.T) @ Jinv.T
        alpha = (self.open_ @ Ti) @ Jinv.T + gyroscopic
        rho = self.rho - p["com_offset"] if "com_offset" in p else self.rho
        if "mass_depletion" in p:
            # Each valve's thrust over the mass while it was open (propellant
            # used by every valve so far in the run).
            m = self.mass - float(p["mass_depletion"][0]) * self.vs * to_true
            force = (self.open_ / m) @ Fi
        else:
            force = (self.open_ @ Fi) / self.mass
        a_pred = force + np.cross(alpha, rho) + np.cross(w, np.cross(w, rho))
        if "differential_drag" in p and self.c_hb is not None:
            a_pred = a_pred + self.c_hb[:, 1, :] * float(p["differential_drag"][0])
        k = self.gyro_rows
        turn = ((self.W @ Ti) @ Jinv.T + 0.5 * (gyroscopic[k - 1] + gyroscopic[k]) * self.h) * to_true
        # The rows compare the IMU's own readings with what the model predicts
        # it reads ((1 + s) C(e)^T C_ib v + b), in the IMU's axes, turned into
        # body axes by the described mounting (a rotation keeps them white).
        # Predicting the reading, not correcting it, keeps the measurement
        # noise out of the parameters' derivatives: a scale factor fitted to
        # corrected readings would shrink their noise and look like a gain.
        M = self.mounting(p)
        a_hat = a_pred @ M + (p["accel_bias"] if "accel_bias" in p else 0.0)
        d_hat = turn @ M
        if "gyro_scale" in p:
            d_hat = d_hat * (1.0 + np.asarray(p["gyro_scale"], float))
        r_a = (self.accel_raw - a_hat) @ self.c_bi.T
        e_a = r_a / self.sig_a if self.accel_whiten is None else np.einsum("nij,nj->ni", self.accel_whiten, r_a)
        d_meas = self.gyro_raw[k] - self.gyro_raw[k - 1]
        e_g = self.whiten_gyro(((d_meas - d_hat) / self.sig_g) @ self.c_bi.T)
        return np.vstack([e_a, e_g])

    def jacobian(self, name: str) -> np.ndarray | None:
        """d(e)/d(theta) (R, 3, k) at the nominal model: differences of the
        exact residual (None: no signature in this channel)."""
        if name not in DYN_CANDIDATES or (name == "differential_drag" and self.c_hb is None):
            return None
        if name not in self._jac:
            self._jac[name] = _central_jacobian(self, name)
        return self._jac[name]


def _n_params(ch: DynChannel, name: str) -> int:
    k = ch.veh.n_thrusters
    return {"thrust_loss": k, "thruster_misalignment": 3 * k, "mass_depletion": 1, "clock_drift": 1}.get(
        name, 2 if name == "differential_drag" else 3
    )


# Steps of the differences: small against each parameter's typical
# size, so the second-order terms are far below the first (the residual is
# smooth in every parameter).
_STEP = {
    "accel_bias": 1e-6,
    "gyro_bias": 1e-6,
    "gyro_scale": 1e-5,
    "imu_misalignment": 1e-6,
    "clock_drift": 1e-6,
    "thrust_loss": 1e-5,
    "thruster_misalignment": 1e-6,
    "com_offset": 1e-6,
    "mass_depletion": 1e-8,
    "differential_drag": 1e-7,
}


def _central_jacobian(ch: DynChannel, name: str) -> np.ndarray:
    """Forward differences from the nominal rows: one residual per
    parameter (the steps are small enough that the second-order term is
    1e-6 of the first; central differences cost twice as much for nothing
    the screen can see)."""
    n = _n_params(ch, name)
    h = _STEP[name]
    out = np.zeros((ch.rows, 3, n))
    for i in range(n):
        th = np.zeros(n)
        th[i] = h
        out[:, :, i] = (ch.residual({name: th}) - ch.e0) / h
    return out


def _open_seconds_before(n_open: np.ndarray, seg_id: np.ndarray) -> np.ndarray:
    """Valve-open seconds summed over all valves before each sample, restarted
    at each segment (the propellant used so far, for the mass)."""
    vs = np.zeros_like(n_open)
    for s in np.unique(seg_id):
        m = seg_id == s
        c = np.cumsum(n_open[m])
        vs[m] = c - n_open[m]
    return vs


def gyro_whiteners(ch: "DynChannel") -> list:
    """Per segment (``ch.seg_bounds``), the banded Cholesky factor of the
    covariance (over sigma_g^2) of the gyro rows' noise, body axes
    interleaved (row r, axis i at 3 r + i). A row differences two samples
    and subtracts the gyroscopic term's trapezoid, whose rate is those
    same noisy samples: row k reads (I - h/2 G_k) n_k - (I + h/2 G_k-1) n_k-1,
    G = d(-J^-1 (w x J w))/dw at the measured rate. Whitened as plain
    differences (tridiagonal 2, -1 per axis) that part was missing, and on
    a fast-turning vehicle its integral along a run read as a gyro bias,
    scale or misalignment on effect-free logs (tests/py/test_gap_dyn.py):
    the null runs then set thresholds from each log's own stamps and rates.
    Taken at the nominal model, so it is the same for every candidate."""
    _, w = ch.imu_body({})
    J = np.asarray(ch.veh.inertia_kgm2, float)
    G = _gyroscopic_jacobian(w, J, np.linalg.inv(J))
    k = ch.gyro_rows
    half_h = 0.5 * ch.h[:, :, None]
    eye = np.eye(3)[None]
    P = eye - half_h * G[k]  # row r's coefficient of its own sample's noise
    Q = -(eye + half_h * G[k - 1])  # and of the sample before
    chols = []
    for a, b in ch.seg_bounds:
        n = b - a
        cov = np.einsum("rij,rkj->rik", P[a:b], P[a:b]) + np.einsum("rij,rkj->rik", Q[a:b], Q[a:b])
        off = np.einsum("rij,rkj->rik", Q[a + 1 : b], P[a : b - 1])  # rows r + 1, r share sample k
        ab = np.zeros((6, 3 * n))
        for i in range(3):
            for j in range(i + 1):  # the diagonal blocks' lower triangles
                ab[i - j, 3 * np.arange(n) + j] = cov[:, i, j]
            for j in range(3):  # the blocks below them
                ab[3 + i - j, 3 * np.arange(n - 1) + j] = off[:, i, j]
        chols.append(cholesky_banded(ab, lower=True))
    return chols


def _segment_bounds(seg_of_row: np.ndarray) -> list:
    """[(start, stop)] the row range of each segment (rows in segment order)."""
    bounds, start = [], 0
    for s in np.unique(seg_of_row):
        n = int(np.sum(seg_of_row == s))
        bounds.append((start, start + n))
        start += n
    return bounds


def build(d: LogData) -> DynChannel | None:
    """The channel for a log with a valve stream (None without one), for the
    vehicle the log describes (bench/sim/log_description.py)."""
    if d.valves is None:
        return None
    from bench.sim.log_description import resolve

    desc = d.desc if d.desc is not None else resolve(None, d.config)
    veh = desc.vehicle()
    open_ = np.asarray(d.valves, float)  # (N, K) open fraction of each interval
    # Segments (runs) reset the gyro differences and the mass.
    seg_id = d.imu_seg if d.imu_seg is not None else np.concatenate([[0], np.cumsum(np.diff(d.imu_t) > 1.5 * d.dt_s)])
    brk = np.concatenate([[True], np.diff(seg_id) != 0])
    if d.valve_stream is not None:
        vs = open_weighted_run_seconds(d.valve_stream, d.imu_t, d.dt_s, open_.shape[1], seg_id)
    else:
        used = open_.sum(axis=1) * d.dt_s
        vs = np.repeat((_open_seconds_before(used, seg_id) + 0.5 * used)[:, None], open_.shape[1], axis=1)
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
    c_bi = d.c_bi if d.c_bi is not None else np.eye(3)
    ch = DynChannel(
        t=np.concatenate([d.imu_t, d.imu_t[k]]),
        e0=None,
        kind=np.concatenate([np.zeros(d.imu_t.size, int), np.ones(k.size, int)]),
        sig_a=desc.accel_sigma_mps2,
        sig_g=desc.gyro_sigma_rps,
        gyro_rows=k,
        seg_bounds=_segment_bounds(seg_id[k]),
        chol=None,
        open_=open_,
        W=W,
        h=h,
        vs=vs,
        dt=d.dt_s,
        veh=veh,
        rho=np.asarray(desc.imu_position_b_m - desc.com_b_m, float),
        c_bi=c_bi,
        accel_raw=d.imu_accel_raw if d.imu_accel_raw is not None else d.accel @ c_bi,
        gyro_raw=d.imu_gyro_raw if d.imu_gyro_raw is not None else d.gyro @ c_bi,
        c_hb=rotmats(d.ref_q) if d.ref_q is not None else None,
    )
    ch.accel_whiten = accel_whitener(ch)
    ch.chol = gyro_whiteners(ch)
    ch.e0 = ch.residual()
    return ch


def accel_whitener(ch: DynChannel) -> np.ndarray | None:
    """(N, 3, 3) L^-1 with L L^T each accelerometer row's covariance: its
    own noise and the gyro's, which the predicted lever-arm terms
    alpha x rho + w x (w x rho) carry (the measured rate enters them). A
    small vehicle slewing at 0.5 rad/s with its IMU 0.2 m from the centre
    of mass reads the gyro's noise there above the accelerometer's; whitened
    by the accelerometer's alone, a null log's variance showed at z = 24.
    Taken at the nominal model, so it is the same for every candidate."""
    if not np.any(ch.rho != 0.0):
        return None
    _, w = ch.imu_body({})
    J = np.asarray(ch.veh.inertia_kgm2, float)
    Jinv = np.linalg.inv(J)
    rho = ch.rho
    dalpha = _gyroscopic_jacobian(w, J, Jinv)  # d(alpha x rho)/dw = -[rho]x d(alpha)/dw
    S_rho = _skew_rows(np.broadcast_to(rho, w.shape))
    wr = w @ rho
    G = (
        -S_rho @ dalpha
        + wr[:, None, None] * np.eye(3)
        + w[:, :, None] * rho[None, None, :]
        - 2.0 * rho[None, :, None] * w[:, None, :]
    )
    cov = ch.sig_a**2 * np.eye(3) + ch.sig_g**2 * G @ np.transpose(G, (0, 2, 1))
    return np.linalg.inv(np.linalg.cholesky(cov))


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


def _pulses(valves: dict, n_thrusters: int) -> tuple:
    """(command times (C,), on-times (C, K)) of a valves stream in either
    form, each pulse ended at the next command (bench/sim/flight_log.py)."""
    from bench.sim.flight_log import valve_on_times

    vt, on, _ = valve_on_times(valves, n_thrusters)
    return vt, on


_RUN_SECONDS: dict = {}  # the last valve stream's answer: a calibration's null runs share their flight's


def _digest(*parts) -> str:
    import hashlib

    h = hashlib.sha1()
    for p in parts:
        if isinstance(p, dict):
            for k in sorted(p):
                h.update(str(k).encode())
                h.update(np.ascontiguousarray(np.asarray(p[k])).tobytes())
        else:
            h.update(np.ascontiguousarray(np.asarray(p)).tobytes())
    return h.hexdigest()


def open_weighted_run_seconds(valves: dict, t: np.ndarray, dt: float, n_thrusters: int, seg: np.ndarray):
    """As _open_weighted_run_seconds, the last answer kept: the same valve
    commands and time stamps (every null run of one flight) give the same."""
    key = _digest(valves, t, np.float64(dt), np.int64(n_thrusters), seg)
    if key not in _RUN_SECONDS:
        _RUN_SECONDS.clear()
        _RUN_SECONDS[key] = _open_weighted_run_seconds(valves, t, dt, n_thrusters, seg)
    return _RUN_SECONDS[key].copy()


def _open_weighted_run_seconds(valves: dict, t: np.ndarray, dt: float, n_thrusters: int, seg: np.ndarray):
    """(N, K): the valve-seconds every valve has used since its run began
    (the propellant gone), averaged over valve i's open time within each
    IMU interval (t_k - dt, t_k]: the mass each valve's thrust acted on,
    exactly for pulses of any length and jittered or dropped samples."""
    from bench.gap.load import open_time

    vt, on = _pulses(valves, n_thrusters)
    pulses = [(vt[on[:, i] > 0.0], on[on[:, i] > 0.0, i]) for i in range(n_thrusters)]

    def used(x):  # all valves' open seconds up to x
        return sum(open_time(s, du, x) for s, du in pulses if s.size)

    def used_integral(x):  # its integral over time up to x
        return sum(_open_time_integral(s, du, x) for s, du in pulses if s.size)

    brk = np.flatnonzero(np.diff(seg) != 0) + 1
    starts = np.r_[0, brk]
    v0 = used(t[starts] - dt)[np.searchsorted(starts, np.arange(t.size), side="right") - 1]
    out = np.zeros((t.size, n_thrusters))
    for i, (s, du) in enumerate(pulses):
        if not s.size:
            continue
        e = s + du
        full = np.concatenate([[0.0], np.cumsum(used_integral(e) - used_integral(s))])
        pulse = (s, e, full, used_integral)
        open_s = open_time(s, du, t) - open_time(s, du, t - dt)
        weighted = _open_times_used(t, *pulse) - _open_times_used(t - dt, *pulse) - v0 * open_s
        out[:, i] = np.where(open_s > 0.0, weighted / np.where(open_s > 0.0, open_s, 1.0), 0.0)
    return out


def _open_times_used(x, s, e, full, used_integral):
    """The integral up to x of one valve's open indicator (pulses [s, e))
    times the valve-seconds used so far: ``full`` holds it over each whole
    pulse, cumulated; a pulse still open at x counts up to x."""
    j = np.searchsorted(s, x, side="left")
    last = np.clip(j - 1, 0, None)
    part = (j > 0) & (x < e[last])
    return full[j] - np.where(part, used_integral(e[last]) - used_integral(x), 0.0)


def turn_weights(valves: dict, t: np.ndarray, rows: np.ndarray, dt: float, n_thrusters: int) -> np.ndarray:
    """(len(rows), K): for each difference of consecutive interval means
    (sample k - 1 to k, k in ``rows``), the effective open seconds of each
    valve: mean over (t_k - dt, t_k] minus mean over (t_{k-1} - dt, t_{k-1}]
    of the cumulative open time."""
    vt, on = _pulses(valves, n_thrusters)
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
