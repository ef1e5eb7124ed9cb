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

from bench.so3 import qexp_many, qmul_many, rotmats, rotvec_matrix

V0_SIGMA_MPS = 0.003
ORBIT_RADIUS_DEFAULT_M = 6378137.0 + 500e3
MU_EARTH = 3.986004418e14


# --- the log in replay form --------------------------------------------------


@dataclass
class LogData:
    imu_t: np.ndarray
    accel: np.ndarray  # specific force at the IMU, body axes
    gyro: np.ndarray  # body axes
    pose_tc: np.ndarray  # capture time on the IMU clock, moved to the nearest IMU tick
    pose_tf: np.ndarray  # replay time at which the pose is fused
    pose_r: np.ndarray  # the IMU's position in the Hill frame
    pose_q: np.ndarray
    pose_R: np.ndarray  # (M, 6, 6)
    pose_tick: np.ndarray  # IMU index at the capture time (-1: before the first sample)
    pose_start: np.ndarray  # bool: this pose starts a new segment (the flight filter was reset)
    valves: np.ndarray | None  # (N, K) fraction of each IMU interval each valve was open, or None
    dt_s: float  # IMU sample interval (each sample is the mean over it)
    n_radps: float
    t_init: float
    # Reference trajectory at the IMU ticks, from the nominal replay.
    ref_r: np.ndarray | None = None
    ref_v: np.ndarray | None = None
    ref_q: np.ndarray | None = None
    truth: dict | None = None
    config: dict = field(default_factory=dict)
    desc: object = None  # bench.sim.log_description.Resolved
    imu_seg: np.ndarray | None = None  # (N,) run (segment) of each IMU sample
    pose_align_s: np.ndarray | None = None  # (M,) IMU tick minus the pose's capture time
    pose_v0_sigma: np.ndarray | None = None  # (M,) initial velocity sigma where a pose starts a run
    valve_stream: dict | None = None  # the log's valves stream (open times over any span: open_fractions)
    dropped: dict = field(default_factory=dict)  # samples the replay could not use, and why
    # The raw IMU samples in the IMU's own axes and its mounting (IMU -> body
    # axes): sensor candidates are undone there (corrected_inputs, dyn.py).
    imu_accel_raw: np.ndarray | None = None
    imu_gyro_raw: np.ndarray | None = None
    c_bi: np.ndarray | None = None
    imu_from_com_b: np.ndarray | None = None  # the IMU from the described centre of mass (body axes)

    @property
    def duration_s(self) -> float:
        return float(self.imu_t[-1] - self.t_init)

    @property
    def firing(self) -> np.ndarray:
        """(N,) a valve was open during the IMU interval."""
        if self.valves is None:
            return np.zeros(self.imu_t.size, bool)
        return self.valves.sum(axis=1) > 0.0

    @property
    def n_segments(self) -> int:
        return int(self.imu_seg.max()) + 1 if self.imu_seg is not None and self.imu_seg.size else 1


POSE_V0_SIGMA_MOVING_MPS = 0.05  # a run that does not start at rest


def prepare(log) -> LogData:
    """Arrays of a FlightLog, ready to replay (the first pose of each run
    initialises it). Everything the log's description states (format
    version 2) is applied here: IMU mounting, pose reference point (moved to
    the IMU) and clock, orbit, vehicle, segments; pose capture times are moved
    to the nearest IMU tick (the flight filter fuses a pose at a stored tick),
    the motion over that shift corrected like a known latency."""
    from bench.sim.flight_log import FlightLogError
    from bench.sim.log_description import resolve

    desc = resolve(getattr(log, "description", None), log.config)
    imu = log["imu"]
    t = np.asarray(imu["t_s"], np.float64)
    dt = 1.0 / desc.imu_rate_hz if desc.imu_rate_hz else (float(np.median(np.diff(t))) if t.size > 1 else 0.1)
    dropped = {}
    c_bi = rotmats(desc.imu_q_body_imu[None])[0]  # IMU axes -> body axes
    accel_raw = np.asarray(imu["accel_b_mps2"], float)
    gyro_raw = np.asarray(imu["omega_bi_b_rps"], float)
    inside, imu_seg, seg_desc = _runs(t, dt, desc)
    if not np.any(inside):
        raise FlightLogError("/description_json: segments: no IMU sample inside any segment")
    if not np.all(inside):
        dropped["imu samples outside every segment"] = int(np.sum(~inside))
        t, accel_raw, gyro_raw = t[inside], accel_raw[inside], gyro_raw[inside]
    accel, gyro = accel_raw @ c_bi.T, gyro_raw @ c_bi.T
    vstream = _valve_stream(log, desc.n_thrusters, dropped)
    valves = open_fractions(vstream, t, dt, desc.n_thrusters) if vstream is not None else None
    p = _poses_on_ticks(log["pose"], t, dt, imu_seg, seg_desc, desc, dropped)
    if p["tc"].size == 0:
        raise FlightLogError("pose/t_capture_s: no pose within one IMU interval of an IMU sample of its run")
    truth = {k: np.asarray(v) for k, v in log["truth"].items()} if log.has("truth") else None
    return LogData(
        imu_t=t,
        accel=accel,
        gyro=gyro,
        pose_tc=p["tc"],
        pose_tf=p["tf"],
        pose_r=p["r"],
        pose_q=p["q"],
        pose_R=p["R"],
        pose_tick=p["tick"],
        pose_start=p["start"],
        valves=valves,
        dt_s=dt,
        n_radps=desc.mean_motion_radps,
        t_init=float(max(t[0] - dt, p["tc"][0])),
        truth=truth,
        config=dict(log.config or {}),
        desc=desc,
        imu_seg=imu_seg,
        pose_align_s=p["align"],
        pose_v0_sigma=p["v0"],
        dropped=dropped,
        valve_stream=vstream,
        imu_accel_raw=accel_raw,
        imu_gyro_raw=gyro_raw,
        c_bi=c_bi,
        imu_from_com_b=np.asarray(desc.imu_position_b_m - desc.com_b_m, float),
    )


def _valve_stream(log, n_thrusters: int, dropped: dict) -> dict | None:
    """The log's valves as on-times per thruster, every pulse ended at the
    next command (those that ran past it counted in ``dropped``), or None."""
    from bench.sim.flight_log import valve_on_times

    if not log.has("valves"):
        return None
    vt, von, clipped = valve_on_times(log["valves"], n_thrusters)
    _drop(dropped, "valve pulses clipped at the next command", np.ones(clipped, bool))
    return {"t_s": vt, "on_time_s": von}


def _runs(t: np.ndarray, dt: float, desc):
    """(samples inside a run, each kept sample's run 0.., the runs' segment
    descriptions or None): the stated segments, or a skipped IMU tick
    (version 1's rule)."""
    if not desc.segments:
        seg = np.concatenate([[0], np.cumsum(np.diff(t) > 1.5 * dt)]) if t.size else np.zeros(0, int)
        return np.ones(t.size, bool), seg, None
    starts = np.array([sg.t_start_s for sg in desc.segments])
    ends = np.array([sg.t_end_s for sg in desc.segments])
    seg = np.searchsorted(starts, t, side="right") - 1
    inside = (seg >= 0) & (t <= ends[np.clip(seg, 0, None)] + 1e-9)
    held = np.unique(seg[inside])
    _, imu_seg = np.unique(seg[inside], return_inverse=True)  # renumbered over the runs that hold samples
    return inside, imu_seg, [desc.segments[i] for i in held]


def _poses_on_ticks(pose: dict, t, dt, imu_seg, seg_desc, desc, dropped: dict) -> dict:
    """The pose stream on the IMU clock, moved to the IMU's point, each pose
    at its nearest IMU tick of its own run (the shift kept as ``align`` for
    the latency-like correction), with its covariance, run starts and the
    initial velocity sigma of each run."""
    tc = np.asarray(pose["t_capture_s"], np.float64) + desc.pose_time_offset_s - desc.pose_latency_s
    td = np.asarray(pose["t_delivered_s"], np.float64) + desc.pose_time_offset_s
    pr = np.asarray(pose["r_hill_m"], float)
    pq = np.asarray(pose["q_hb"], float)
    rs = np.asarray(pose["r_sigma_m"], float)
    asg = np.asarray(pose["att_sigma_rad"], float)
    pref = desc.pose_reference_b_m - desc.imu_position_b_m
    if np.any(pref != 0.0):
        pr = pr - rotmats(pq) @ pref
    # Nearest tick: the IMU samples and the start of the first interval.
    grid = np.concatenate([[t[0] - dt], t])
    gseg = np.concatenate([[imu_seg[0]], imu_seg])
    j = np.clip(np.searchsorted(grid, tc), 1, grid.size - 1)
    j = np.where(np.abs(grid[j - 1] - tc) <= np.abs(grid[j] - tc), j - 1, j)
    align = grid[j] - tc
    # Jitter and a dropped sample leave a pose up to one interval from its
    # nearest tick; the shift is a linearised correction, so no farther.
    near = np.abs(align) <= dt + 1e-9
    keep = near.copy()
    if desc.segments:
        starts = np.array([sg.t_start_s for sg in desc.segments])
        ends = np.array([sg.t_end_s for sg in desc.segments])
        pseg = np.searchsorted(starts, tc, side="right") - 1
        pin = (pseg >= 0) & (tc <= ends[np.clip(pseg, 0, None)] + 1e-9)
        _drop(dropped, "poses outside every segment", ~pin)
        # the tick must belong to the pose's own run
        own = np.searchsorted(starts, grid[j], side="right") - 1 == pseg
        _drop(dropped, "poses whose nearest IMU tick is in another run", pin & near & ~own)
        keep &= pin & own
        near |= ~pin  # counted once, as outside every segment
    _drop(dropped, "poses more than one IMU interval from every IMU tick", ~near)
    kept = np.flatnonzero(keep)
    dup = np.zeros(tc.size, bool)
    dup[kept[1:]] = j[kept[1:]] == j[kept[:-1]]
    _drop(dropped, "poses on an IMU tick already taken by an earlier pose", dup)
    keep &= ~dup
    j, align, td, pr, pq, rs, asg = (x[keep] for x in (j, align, td, pr, pq, rs, asg))
    tc_tick = grid[j]
    R = np.zeros((j.size, 6, 6))
    R[:, [0, 1, 2], [0, 1, 2]] = (rs**2)[:, None]
    R[:, [3, 4, 5], [3, 4, 5]] = (asg**2)[:, None]
    v0 = np.full(j.size, V0_SIGMA_MPS)
    if seg_desc is not None:
        ps = gseg[j]
        start = np.concatenate([[True], ps[1:] != ps[:-1]]) if ps.size else np.zeros(0, bool)
        for i in np.flatnonzero(start):
            if not seg_desc[ps[i]].starts_at_rest:
                v0[i] = POSE_V0_SIGMA_MOVING_MPS
    else:
        start = segment_starts(tc_tick, pr, rs, t)
    return {
        "tc": tc_tick,
        "tf": np.maximum(td, tc_tick),
        "r": pr,
        "q": pq,
        "R": R,
        "tick": j - 1,
        "start": start,
        "align": align,
        "v0": v0,
    }


def _drop(dropped: dict, why: str, mask) -> None:
    k = int(np.sum(mask))
    if k:
        dropped[why] = dropped.get(why, 0) + k


def open_fractions(valves: dict, t: np.ndarray, dt: float, n_thrusters: int) -> np.ndarray:
    """(N, K): the fraction of each IMU interval (t_k - dt, t_k] that each
    valve was open. Valve i opens at t_s for on_time_s[i] (or, in the mask
    form, every valve of the mask for interval_s); pulses of any length, also
    shorter than an IMU interval or across its ends, are integrated exactly."""
    from bench.sim.flight_log import STAMP_ROUNDING_S, valve_on_times

    vt, on, _ = valve_on_times(valves, n_thrusters)  # a pulse ends at the next command
    out = np.zeros((t.size, n_thrusters))
    if vt.size == 0:
        return out
    for i in range(n_thrusters):
        out[:, i] = (open_time(vt, on[:, i], t) - open_time(vt, on[:, i], t - dt)) / dt
    # Open or closed for all but the stamps' own rounding: exactly so.
    eps = STAMP_ROUNDING_S / dt
    return np.where(out < eps, 0.0, np.where(out > 1.0 - eps, 1.0, out))


def open_time(start: np.ndarray, dur: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Total open time up to each t of pulses [start_j, start_j + dur_j)
    (pulses do not overlap)."""
    cum = np.concatenate([[0.0], np.cumsum(dur)])
    j = np.searchsorted(start, t, side="right") - 1
    jj = np.clip(j, 0, None)
    part = np.clip(t - start[jj], 0.0, dur[jj])
    return np.where(j >= 0, cum[jj] + part, 0.0)


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
