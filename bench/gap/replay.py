"""Stage 2 of the diagnosis (bench/gap/diagnose.py): re-run the flight
navigation filter (fsw_bindings.NavUkf, in-process) over a loaded log's IMU
and pose streams (bench/gap/load.py LogData), with a candidate model's corrections
applied to the inputs, and return the per-update innovations, their
covariances, NIS and log-likelihood.

Conventions (docs/FLIGHT_LOG.md): the IMU sample stamped t_k is the mean over
(t_k - dt, t_k] and drives ``predict(t_k, ...)``; a pose captured at t_c is
fused once the replay clock reaches max(t_delivered, t_c), with
R = diag(r_sigma^2 I3, att_sigma^2 I3). The filter starts at the first pose
(position and attitude from it, its own R; velocity 0 with
``V0_SIGMA_MPS``), as the bench's docking scenario does. Gating is off by
default: a gap must show in the innovations, not vanish behind the gate.

The filter navigates the IMU's own point: its accelerometer measures that
point's specific force exactly, whatever the vehicle's mass properties or
valves do, so no lever-arm term (which needs the angular acceleration, and
so the vehicle model) enters the navigation channel; each pose is moved
from its reference point to the IMU along the measured attitude (a
body-fixed offset the description states).

Corrections (all optional, zero means "the nominal model"), the IMU's own
errors in the IMU's axes (C_bi the described mounting):
  IMU   accel = C_bi Exp(misalign) ((accel_raw - b_a) / (1 + s_a)) + C_bh a_extra_hill
        omega = C_bi Exp(misalign) ((omega_raw - b_g) / (1 + s_g))
  pose  r = r_meas - C_hb(q_meas) lever_b + latency * v_ref(t_c)
        q = q_meas (+) latency * omega_bh_ref(t_c)
  clock every time tag of the log (IMU ticks, pose capture and fusion
        times) divided by 1 + clock_eps: the flight clock runs fast by
        clock_eps, so its tags are (1 + clock_eps) t of true time t, and
        the filter must integrate the rates and accelerations over true
        intervals
where the reference trajectory (v_ref, q_ref, r_ref at every IMU tick) comes
from one nominal replay (``reference``): the latency and Hill-frame terms
are small corrections linearised about it, so they cost no Python work per
step. Everything is precomputed with numpy; the loop only calls the filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from bench.gap.load import V0_SIGMA_MPS, LogData
from bench.so3 import qexp_many, qmul_many, rotmats, rotvec_matrix

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
    # The flight clock's rate error: its tags are (1 + clock_eps) t.
    clock_eps: float = 0.0

    def add(self, other: "Corrections") -> "Corrections":
        h = (
            self.hill_accel
            if other.hill_accel is None
            else (other.hill_accel if self.hill_accel is None else self.hill_accel + other.hill_accel)
        )
        x = (
            self.accel_extra_b
            if other.accel_extra_b is None
            else (other.accel_extra_b if self.accel_extra_b is None else self.accel_extra_b + other.accel_extra_b)
        )
        return Corrections(
            self.accel_bias + other.accel_bias,
            self.accel_scale + other.accel_scale,
            self.gyro_bias + other.gyro_bias,
            self.gyro_scale + other.gyro_scale,
            self.imu_misalign + other.imu_misalign,
            self.latency_s + other.latency_s,
            self.lever_arm_b + other.lever_arm_b,
            h,
            x,
            self.clock_eps + other.clock_eps,
        )


def corrected_inputs(d: LogData, c: Corrections | None):
    """(accel (N,3), gyro (N,3), pose_r (M,3), pose_q (M,4)) with ``c`` applied."""
    if c is None:
        r, q = _shift_poses(d, d.gyro, d.pose_r, d.pose_q, 0.0, 0.0, d.accel)
        return d.accel, d.gyro, r, q
    acc, gyr = _imu_corrected(d, c)
    if c.accel_extra_b is not None:
        acc = acc + c.accel_extra_b
    if c.hill_accel is not None:
        if d.ref_q is None:
            raise ValueError("Hill-frame corrections need the reference trajectory (replay.reference)")
        acc = acc + np.einsum("nji,nj->ni", rotmats(d.ref_q), c.hill_accel)
    r, q = d.pose_r, d.pose_q
    if np.any(c.lever_arm_b != 0.0):
        r = r - rotmats(q) @ c.lever_arm_b
    r, q = _shift_poses(d, gyr, r, q, c.latency_s, c.clock_eps, acc)
    return acc, gyr, r, q


def retimed(d: LogData, c: Corrections | None) -> tuple:
    """(d, c) as the replay runs them. Every pose is fused at its capture
    tick: the flight filter's delayed update equals the on-time delivery
    (nav_ukf.hpp), and fusing at capture needs no history, which at 50 Hz
    holds only 0.3 s of delay. A latency correction is moved into the
    ticks: each pose (but a run's first, which starts the filter) at the
    tick nearest its true capture time in its own run, after the run's
    start, so the filter's own IMU propagation carries it over whole
    intervals and only the rest (under half an interval) is shifted along
    the reference (``_shift_poses``), whose velocity is an estimate:
    shifted whole, a 0.1 s latency left 0.5 % of its effect in the
    innovations of a noise-free log (the reference's velocity error times
    the latency), retimed 0.03 %."""
    if d.pose_tc.size == 0:
        return d, c
    if c is None or c.latency_s == 0.0 or d.pose_align_s is None:
        return replace(d, pose_tf=d.pose_tc), c
    n = d.imu_t.size
    k_old = d.pose_tick
    tt = d.pose_tc - d.pose_align_s - c.latency_s * (1.0 + c.clock_eps)  # true capture, flight clock
    seg = d.imu_seg if d.imu_seg is not None else np.zeros(n, int)
    ks = np.clip(k_old, 0, n - 1)
    first = np.searchsorted(seg, seg, side="left")[ks]
    last = np.searchsorted(seg, seg, side="right")[ks] - 1
    # After the tick where the run's filter started (its first pose).
    run_start = np.maximum.accumulate(np.where(d.pose_start, np.arange(k_old.size), 0))
    lo = np.maximum(first, k_old[run_start] + 1)
    j = np.clip(np.searchsorted(d.imu_t, tt), 1, n - 1)
    j = np.where(np.abs(d.imu_t[j - 1] - tt) <= np.abs(d.imu_t[j] - tt), j - 1, j)
    k_new = np.where(d.pose_start, k_old, np.clip(j, lo, np.maximum(last, lo)))
    tick = np.where(k_new >= 0, d.imu_t[np.clip(k_new, 0, n - 1)], d.imu_t[0] - d.dt_s)
    d2 = replace(d, pose_tick=k_new, pose_tc=tick, pose_tf=tick, pose_align_s=tick - tt)
    return d2, replace(c, latency_s=0.0)


def _imu_corrected(d: LogData, c: Corrections) -> tuple:
    """The IMU's own errors undone in its own axes, then turned into body
    axes: the IMU reads (1 + s) C(e)^T C_ib v + b."""
    if d.imu_accel_raw is None:  # a LogData built by hand: its IMU axes are the body axes
        raw_a, raw_g, c_bi = d.accel, d.gyro, np.eye(3)
    else:
        raw_a, raw_g, c_bi = d.imu_accel_raw, d.imu_gyro_raw, d.c_bi
    M = c_bi @ rotvec_matrix(c.imu_misalign) if np.any(c.imu_misalign != 0.0) else c_bi
    acc = ((raw_a - c.accel_bias) / (1.0 + c.accel_scale)) @ M.T
    gyr = ((raw_g - c.gyro_bias) / (1.0 + c.gyro_scale)) @ M.T
    return acc, gyr


def _shift_poses(
    d: LogData, gyr: np.ndarray, r: np.ndarray, q: np.ndarray, latency_s: float, clock_eps: float = 0.0, acc=None
):
    """Each pose moved from its true capture time to its IMU tick: over
    ``latency_s`` plus its own shift to the tick (LogData.pose_align_s, on
    the flight clock: in true time over 1 + clock_eps). The position along
    the reference's velocity and the measured acceleration, the attitude
    by the measured rates over the shift (``gyr``, corrected, each sample's
    rate over its own interval) and the Hill frame's turn. ``retimed``
    keeps the shift under about half an IMU interval, so the reference's
    velocity error matters little. Needs the reference (replay.reference)
    unless every shift is zero."""
    align = d.pose_align_s / (1.0 + clock_eps) if d.pose_align_s is not None else 0.0
    tau = latency_s + align
    if not np.any(tau != 0.0):
        return r, q
    if d.ref_v is None:
        if latency_s != 0.0:
            raise ValueError("latency corrections need the reference trajectory (replay.reference)")
        return r, q  # the first nominal pass: shifts follow once the reference exists
    tau = np.array(np.broadcast_to(tau, (r.shape[0],)), float)
    n = d.imu_t.size
    t = d.imu_t / (1.0 + clock_eps)
    k = np.clip(d.pose_tick, 0, n - 1)
    seg = d.imu_seg if d.imu_seg is not None else np.zeros(n, int)
    first = np.searchsorted(seg, seg, side="left")[k]  # each pose's run: its first and last sample
    last = np.searchsorted(seg, seg, side="right")[k] - 1
    t_tick = np.where(d.pose_tick >= 0, t[k], t[0] - d.dt_s / (1.0 + clock_eps))  # -1: the first interval's start
    tt = t_tick - tau  # the true capture time
    # r(t_k) = r(tt) + tau v(t_k) - a tau^2 / 2, v and a at the tick (the
    # reference velocity, the measured specific force turned into Hill axes).
    a_hill = np.einsum("nij,nj->ni", rotmats(d.ref_q[k]), acc[k]) if acc is not None else 0.0
    r = r + tau[:, None] * d.ref_v[k] - 0.5 * tau[:, None] ** 2 * a_hill
    q = qmul_many(qexp_many(np.outer(-d.n_radps * tau, [0.0, 0.0, 1.0])), q)
    return r, qmul_many(q, _body_turn(gyr, t, tt, t_tick, k, first, last))


def _body_turn(gyr: np.ndarray, t: np.ndarray, tt: np.ndarray, t_tick: np.ndarray, k, first, last) -> np.ndarray:
    """(M, 4) the body's turn from each capture time ``tt`` to its tick
    ``t_tick`` (sample k's time, or the first interval's start), from the
    rates of the samples between (each sample's rate held over
    (t_{i-1}, t_i], as the filter integrates it), within the pose's run."""
    out = np.tile([1.0, 0.0, 0.0, 0.0], (tt.size, 1))
    # Captured after its tick (a pose shifted back): the next sample's rate, inside the run.
    after = tt > t_tick
    if np.any(after):
        nxt = np.where(t_tick < t[k], k, np.minimum(k + 1, last))
        out[after] = qexp_many(gyr[nxt[after]] * (t_tick - tt)[after, None])
    # Captured before: each sample from the tick back to the one whose interval holds tt.
    i = k.copy()
    todo = ~after & (tt < t_tick)
    while np.any(todo):
        lo = np.where(i > first, t[np.maximum(i - 1, 0)], -np.inf)  # the run's first sample reaches back
        span = np.where(todo, np.minimum(t[i], t_tick) - np.maximum(lo, tt), 0.0)
        out = np.where(todo[:, None], qmul_many(qexp_many(gyr[i] * span[:, None]), out), out)
        todo = todo & (lo > tt)
        i = np.where(todo, i - 1, i)
    return out


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

    from bench.sim.sensors import NoiseProfile

    nc = fb.NavConfig()
    nc.n_radps = d.n_radps
    nc.dt_imu_s = d.dt_s
    if d.desc is not None:
        nc.accel_sigma_mps2, nc.gyro_sigma_rps = d.desc.accel_sigma_mps2, d.desc.gyro_sigma_rps
    else:
        prof = NoiseProfile.paper()
        nc.accel_sigma_mps2, nc.gyro_sigma_rps = prof.accel_sigma_mps2, prof.gyro_sigma_rps
    # Jittered time stamps: a step may be longer than the nominal interval.
    steps = np.diff(d.imu_t)
    if steps.size:
        nc.max_dt_s = max(float(nc.max_dt_s), float(np.max(steps)) * 1.01)
    nc.gate_chi2 = gate_chi2
    # Poses are fused at their capture ticks (retimed): a delay of a tick or two at most.
    nc.max_delay_s = float(np.max(d.pose_tf - d.pose_tc, initial=0.0)) + 2 * d.dt_s
    return nc


@dataclass
class ReplayInputs:
    """What the navigation filter is given for one replay: the configuration
    and the streams with the corrections applied, every time on the true
    clock (fsw_bindings.nav_replay's arguments)."""

    cfg: object  # fsw_bindings.NavConfig
    imu_t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    pose_tc: np.ndarray
    pose_tf: np.ndarray
    pose_r: np.ndarray
    pose_q: np.ndarray
    pose_R: np.ndarray
    pose_start: np.ndarray
    pose_v0_sigma: np.ndarray
    t_init: float


def replay_inputs(d: LogData, c: Corrections | None = None, gate_chi2: float = 0.0) -> tuple:
    """(the log as replayed, ReplayInputs) for ``replay(d, c, gate_chi2=...)``."""
    d, c = retimed(d, c)
    acc, gyr, pr, pq = corrected_inputs(d, c)
    v0sig = d.pose_v0_sigma if d.pose_v0_sigma is not None else np.full(d.pose_tc.size, V0_SIGMA_MPS)
    # A flight clock fast by clock_eps: true time is its tag over 1 + clock_eps.
    to_true = 1.0 / (1.0 + c.clock_eps) if c is not None and c.clock_eps != 0.0 else 1.0
    return d, ReplayInputs(
        cfg=nav_config(d, gate_chi2),
        imu_t=d.imu_t * to_true,
        accel=acc,
        gyro=gyr,
        pose_tc=d.pose_tc * to_true,
        pose_tf=d.pose_tf * to_true,
        pose_r=pr,
        pose_q=pq,
        pose_R=d.pose_R,
        pose_start=d.pose_start,
        pose_v0_sigma=v0sig,
        t_init=d.t_init * to_true,
    )


def replay(
    d: LogData, c: Corrections | None = None, record_states: bool = False, gate_chi2: float = 0.0
) -> ReplayResult:
    """The flight filter over the log in one call (fsw_bindings.nav_replay,
    fsw/include/fsw/app/nav_replay.hpp): initialised from the first pose at
    t_init, reset at each run's first pose, a predict per IMU sample, each
    other pose fused once the replay clock reaches its fusion time."""
    import fsw_bindings as fb

    d, x = replay_inputs(d, c, gate_chi2)
    out = fb.nav_replay(
        x.cfg,
        x.imu_t,
        x.accel,
        x.gyro,
        x.pose_tc,
        x.pose_tf,
        x.pose_r,
        x.pose_q,
        x.pose_R,
        x.pose_start,
        x.pose_v0_sigma,
        x.t_init,
        record_states,
    )
    ok = out["fused"]
    sel = np.flatnonzero(ok)
    return ReplayResult(
        t=d.pose_tc[sel],
        index=sel,
        innovation=out["innovation"][sel],
        S=out["innovation_cov"][sel],
        nis=out["nis"][sel],
        loglik=out["log_likelihood"][sel],
        ok=ok[sel],
        states=out["states"],
    )


def reference(d: LogData) -> ReplayResult:
    """Nominal replay that also stores the estimate at every tick as the
    reference trajectory (needed by the latency and Hill-frame corrections)."""
    res = replay(d, None, record_states=True)
    d.ref_r, d.ref_v, d.ref_q = res.states[:, 0:3], res.states[:, 3:6], res.states[:, 6:10]
    if d.pose_align_s is not None and np.any(d.pose_align_s != 0.0):
        # Poses moved to their IMU ticks along the first pass's motion.
        res = replay(d, None, record_states=True)
        d.ref_r, d.ref_v, d.ref_q = res.states[:, 0:3], res.states[:, 3:6], res.states[:, 6:10]
    return res
