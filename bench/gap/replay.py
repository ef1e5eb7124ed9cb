"""Re-run the flight navigation filter (fsw_bindings.NavUkf, in-process) over a
flight log's IMU and pose streams, with a candidate model's corrections
applied to the inputs, and return the per-update innovations, their
covariances, NIS and log-likelihood.

Conventions (docs/FLIGHT_LOG.md): the IMU sample stamped t_k is the mean over
(t_k - dt, t_k] and drives ``predict(t_k, ...)``; a pose captured at t_c is
fused once the replay clock reaches max(t_delivered, t_c), with
R = diag(r_sigma^2 I3, att_sigma^2 I3). The filter starts at the first pose
(position and attitude from it, its own R; velocity 0 with
``V0_SIGMA_MPS``), as the bench's docking scenario does. Gating is off by
default: a gap must show in the innovations, not vanish behind the gate.

Corrections (all optional, zero means "the nominal model"):
  IMU   accel = Exp(misalign) ((accel_raw - b_a) / (1 + s_a)) + C_bh a_extra_hill
        omega = Exp(misalign) ((omega_raw - b_g) / (1 + s_g))
  pose  r = r_meas - C_hb(q_meas) lever_b + latency * v_ref(t_c)
        q = q_meas (+) latency * omega_bh_ref(t_c)
where the reference trajectory (v_ref, q_ref, r_ref at every IMU tick) comes
from one nominal replay (``reference``): the latency and Hill-frame terms
are small corrections linearised about it, so they cost no Python work per
step. Everything is precomputed with numpy; the loop only calls the filter.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

V0_SIGMA_MPS = 0.003
ORBIT_RADIUS_DEFAULT_M = 6378137.0 + 500e3
MU_EARTH = 3.986004418e14


# --- vectorised rotation helpers (Hamilton, scalar first) -------------------

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
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=1)


def qexp_many(phi: np.ndarray) -> np.ndarray:
    a = np.linalg.norm(phi, axis=1)
    half = 0.5 * a
    s = np.where(a < 1e-9, 0.5 - a * a / 48.0, np.sin(half) / np.where(a < 1e-9, 1.0, a))
    q = np.concatenate([np.cos(half)[:, None], s[:, None] * phi], axis=1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# --- the log in replay form --------------------------------------------------

@dataclass
class LogData:
    imu_t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    pose_tc: np.ndarray
    pose_tf: np.ndarray  # replay time at which the pose is fused
    pose_r: np.ndarray
    pose_q: np.ndarray
    pose_R: np.ndarray  # (M, 6, 6)
    pose_tick: np.ndarray  # IMU index at the capture time (-1: before the first sample)
    pose_start: np.ndarray  # bool: this pose starts a new segment (the flight filter was reset)
    valves: np.ndarray | None  # (N,) valve mask over each IMU interval, or None
    dt_s: float
    n_radps: float
    t_init: float
    # Reference trajectory at the IMU ticks, from the nominal replay.
    ref_r: np.ndarray | None = None
    ref_v: np.ndarray | None = None
    ref_q: np.ndarray | None = None
    truth: dict | None = None
    config: dict = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(self.imu_t[-1] - self.t_init)


def prepare(log) -> LogData:
    """Arrays of a FlightLog, ready to replay (the first pose initialises)."""
    imu, pose = log["imu"], log["pose"]
    t = np.asarray(imu["t_s"], float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.1
    cfg = dict(log.config or {})
    radius = float(cfg.get("orbit_radius_m", ORBIT_RADIUS_DEFAULT_M))
    n = float(np.sqrt(MU_EARTH / radius**3))
    tc = np.asarray(pose["t_capture_s"], float)
    td = np.asarray(pose["t_delivered_s"], float)
    rs = np.asarray(pose["r_sigma_m"], float)
    asg = np.asarray(pose["att_sigma_rad"], float)
    R = np.zeros((tc.size, 6, 6))
    R[:, [0, 1, 2], [0, 1, 2]] = (rs**2)[:, None]
    R[:, [3, 4, 5], [3, 4, 5]] = (asg**2)[:, None]
    tick = np.searchsorted(t, tc - 1e-6)
    tick = np.where(np.abs(t[np.minimum(tick, t.size - 1)] - tc) < 1e-6, tick, -1)
    start = segment_starts(tc, np.asarray(pose["r_hill_m"], float), rs, t)
    valves = None
    if log.has("valves"):
        vt = np.asarray(log["valves"]["t_s"], float)
        vm = np.asarray(log["valves"]["mask"]).astype(np.int64)
        # IMU interval (t_k - dt, t_k] is covered by the valve record that
        # starts at or before t_k - dt.
        idx = np.searchsorted(vt, t - dt + 1e-6, side="right") - 1
        valves = np.where(idx >= 0, vm[np.clip(idx, 0, None)], 0)
    truth = None
    if log.has("truth"):
        truth = {k: np.asarray(v) for k, v in log["truth"].items()}
    return LogData(imu_t=t, accel=np.asarray(imu["accel_b_mps2"], float), gyro=np.asarray(imu["omega_bi_b_rps"], float),
                   pose_tc=tc, pose_tf=np.maximum(td, tc), pose_r=np.asarray(pose["r_hill_m"], float),
                   pose_q=np.asarray(pose["q_hb"], float), pose_R=R, pose_tick=tick, pose_start=start, valves=valves, dt_s=dt,
                   n_radps=n, t_init=float(max(t[0] - dt, tc[0])), truth=truth, config=cfg)


def segment_starts(tc: np.ndarray, r: np.ndarray, r_sigma: np.ndarray, imu_t: np.ndarray | None = None) -> np.ndarray:
    """Where a log chains separate approaches (a new run, the flight filter
    reset): the IMU stream skips a sample between two poses, the pose period
    breaks (a gap 5 % off the usual period), or the position jumps by more
    than 0.2 m plus 5 sigma in one period."""
    start = np.zeros(tc.size, bool)
    if tc.size:
        start[0] = True
    if tc.size < 3:
        return start
    dt = np.diff(tc)
    period = float(np.median(dt))
    jump = np.linalg.norm(np.diff(r, axis=0), axis=1)
    sig = np.sqrt(r_sigma[1:] ** 2 + r_sigma[:-1] ** 2)
    brk = (np.abs(dt - period) > 0.05 * period) | (jump > 0.2 + 5.0 * sig)
    if imu_t is not None and imu_t.size > 2:
        d_imu = np.diff(imu_t)
        gaps = imu_t[1:][d_imu > 1.5 * float(np.median(d_imu))]
        if gaps.size:
            c = np.searchsorted(gaps, tc, side="right")  # gaps up to each capture
            brk |= c[1:] > c[:-1]
    start[1:] = brk
    return start


# --- corrections --------------------------------------------------------------

@dataclass
class Corrections:
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_scale: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_scale: np.ndarray = field(default_factory=lambda: np.zeros(3))
    imu_misalign: np.ndarray = field(default_factory=lambda: np.zeros(3))
    latency_s: float = 0.0
    lever_arm_b: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # Extra Hill-frame acceleration per IMU tick (N, 3) (orbital terms), or None.
    hill_accel: np.ndarray | None = None
    # Extra body-frame specific force added to the corrected accelerometer (N, 3), or None.
    accel_extra_b: np.ndarray | None = None

    def add(self, other: "Corrections") -> "Corrections":
        h = self.hill_accel if other.hill_accel is None else (
            other.hill_accel if self.hill_accel is None else self.hill_accel + other.hill_accel)
        x = self.accel_extra_b if other.accel_extra_b is None else (
            other.accel_extra_b if self.accel_extra_b is None else self.accel_extra_b + other.accel_extra_b)
        return Corrections(self.accel_bias + other.accel_bias, self.accel_scale + other.accel_scale,
                           self.gyro_bias + other.gyro_bias, self.gyro_scale + other.gyro_scale,
                           self.imu_misalign + other.imu_misalign, self.latency_s + other.latency_s,
                           self.lever_arm_b + other.lever_arm_b, h, x)


def corrected_inputs(d: LogData, c: Corrections | None):
    """(accel (N,3), gyro (N,3), pose_r (M,3), pose_q (M,4)) with ``c`` applied."""
    if c is None:
        return d.accel, d.gyro, d.pose_r, d.pose_q
    acc = (d.accel - c.accel_bias) / (1.0 + c.accel_scale)
    gyr = (d.gyro - c.gyro_bias) / (1.0 + c.gyro_scale)
    if np.any(c.imu_misalign != 0.0):
        M = rotvec_matrix(c.imu_misalign)
        acc = acc @ M.T
        gyr = gyr @ M.T
    if c.accel_extra_b is not None:
        acc = acc + c.accel_extra_b
    if c.hill_accel is not None:
        if d.ref_q is None:
            raise ValueError("Hill-frame corrections need the reference trajectory (replay.reference)")
        acc = acc + np.einsum("nji,nj->ni", rotmats(d.ref_q), c.hill_accel)
    r, q = d.pose_r, d.pose_q
    if np.any(c.lever_arm_b != 0.0):
        r = r - rotmats(q) @ c.lever_arm_b
    if c.latency_s != 0.0:
        if d.ref_v is None:
            raise ValueError("latency corrections need the reference trajectory (replay.reference)")
        k = np.clip(d.pose_tick, 0, d.imu_t.size - 1)
        r = r + c.latency_s * d.ref_v[k]
        # The body rate over the latency: the IMU interval that ends at the
        # pose's tick (sample k), never the next one, which at a run's last
        # pose belongs to the next run.
        w_bh = gyr[k] - np.einsum(
            "nji,j->ni", rotmats(d.ref_q[k]), np.array([0.0, 0.0, d.n_radps]))
        q = qmul_many(q, qexp_many(c.latency_s * w_bh))
    return acc, gyr, r, q


# --- the replay ----------------------------------------------------------------

@dataclass
class ReplayResult:
    t: np.ndarray  # capture time of each fused pose (M',)
    index: np.ndarray  # pose index of each record
    innovation: np.ndarray  # (M', 6)
    S: np.ndarray  # (M', 6, 6)
    nis: np.ndarray
    loglik: np.ndarray
    ok: np.ndarray  # bool: the filter accepted the update
    states: np.ndarray | None = None  # (N, 10) after each predict, when recorded

    def whitened(self) -> np.ndarray:
        """L^-1 innovation with S = L L^T (M', 6): N(0, I) for a consistent model."""
        L = np.linalg.cholesky(self.S)
        return np.linalg.solve(L, self.innovation[..., None])[..., 0]


def nav_config(d: LogData, gate_chi2: float = 0.0):
    import fsw_bindings as fb

    from bench.sensors import NoiseProfile

    prof = NoiseProfile.paper()
    noise = d.config.get("noise") if isinstance(d.config.get("noise"), dict) else {}
    nc = fb.NavConfig()
    nc.n_radps = d.n_radps
    nc.dt_imu_s = d.dt_s
    nc.accel_sigma_mps2 = float(noise.get("accel_sigma_mps2", d.config.get("accel_sigma_mps2", prof.accel_sigma_mps2)))
    nc.gyro_sigma_rps = float(noise.get("gyro_sigma_rps", d.config.get("gyro_sigma_rps", prof.gyro_sigma_rps)))
    nc.gate_chi2 = gate_chi2
    nc.max_delay_s = max(0.5, float(np.max(d.pose_tf - d.pose_tc, initial=0.0)) + 2 * d.dt_s)
    return nc


def replay(d: LogData, c: Corrections | None = None, record_states: bool = False,
           gate_chi2: float = 0.0) -> ReplayResult:
    import fsw_bindings as fb

    acc, gyr, pr, pq = corrected_inputs(d, c)
    ukf = fb.NavUkf(nav_config(d, gate_chi2))
    t = d.imu_t
    # Initialise from the first pose at (or before) the first IMU interval.
    P0 = np.zeros((9, 9))
    P0[0:3, 0:3], P0[6:9, 6:9] = d.pose_R[0, 0:3, 0:3], d.pose_R[0, 3:6, 3:6]
    P0[3:6, 3:6] = V0_SIGMA_MPS**2 * np.eye(3)
    ukf.init(d.t_init, pr[0], np.zeros(3), pq[0], P0)
    m = d.pose_tc.size
    start = d.pose_start
    innov = np.zeros((m, 6))
    S = np.zeros((m, 6, 6))
    nis = np.zeros(m)
    ll = np.zeros(m)
    ok = np.zeros(m, bool)
    states = np.zeros((t.size, 10)) if record_states else None
    tf, tc, R = d.pose_tf, d.pose_tc, d.pose_R
    eps = 1e-9
    j = 1
    while j < m and tc[j] <= d.t_init + 1e-9:
        j += 1
    predict, update = ukf.predict, ukf.update_pose
    k0 = int(np.searchsorted(t, d.t_init + eps, side="right"))
    for k in range(k0, t.size):
        tk = t[k]
        if j < m and start[j] and tc[j] <= tk + eps:
            # A new approach (the flight filter was reset): start again from its first pose.
            P0[0:3, 0:3], P0[6:9, 6:9] = R[j, 0:3, 0:3], R[j, 3:6, 3:6]
            ukf = fb.NavUkf(nav_config(d, gate_chi2))
            ukf.init(tc[j], pr[j], np.zeros(3), pq[j], P0)
            predict, update = ukf.predict, ukf.update_pose
            j += 1
            if tk > tc[j - 1] + eps:
                predict(tk, acc[k], gyr[k])
        else:
            predict(tk, acc[k], gyr[k])
        if record_states:
            states[k] = ukf.state()
        while j < m and tf[j] <= tk + eps and not start[j]:
            rec = update(tc[j], pr[j], pq[j], R[j])
            if rec.status == "ok":
                ok[j] = True
                innov[j] = rec.innovation
                S[j] = rec.innovation_cov
                nis[j] = rec.nis
                ll[j] = rec.log_likelihood
            j += 1
    sel = np.flatnonzero(ok)
    return ReplayResult(t=tc[sel], index=sel, innovation=innov[sel], S=S[sel], nis=nis[sel], loglik=ll[sel],
                        ok=ok[sel], states=states)


def reference(d: LogData) -> ReplayResult:
    """Nominal replay that also stores the estimate at every tick as the
    reference trajectory (needed by the latency and Hill-frame corrections)."""
    res = replay(d, None, record_states=True)
    d.ref_r, d.ref_v, d.ref_q = res.states[:, 0:3], res.states[:, 3:6], res.states[:, 6:10]
    return res
