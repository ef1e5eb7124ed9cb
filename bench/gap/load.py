"""Stage 1 of the diagnosis (bench/gap/diagnose.py): a flight log read into
the form every later stage uses (``LogData``), its description resolved
(bench/sim/log_description.py: what the log states, the defaults for what
it does not), its time stamps from its own start, and a log the diagnosis
cannot look at refused.

The IMU stream on its ticks (each sample the mean over the interval before
its stamp), the poses moved to the nearest IMU tick of their run (the
capture time kept for the latency, the fusion time for the replay), the
runs (segments) the log chains, the valve stream as each valve's open
fraction of every IMU interval, and every sample the diagnosis could not
use named with why (``dropped``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.sim.flight_log import FlightLogError, relative_to_start
from bench.so3 import rotmats

V0_SIGMA_MPS = 0.003


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


MIN_IMU_S = 1.0  # the slewing regime averages the gyro over 1 s (localise.dyn_regimes)


def check_enough(d: LogData) -> None:
    """Refuse (FlightLogError, naming the field) a log the diagnosis cannot
    look at: less than MIN_IMU_S of IMU samples inside the segments, a
    stated segment whose run has no pose on its IMU ticks (a run starts at
    its first pose), or no pose update at all (a pose after a run's first)."""
    need = max(2, int(round(MIN_IMU_S / d.dt_s)))
    if d.imu_t.size < need:
        raise FlightLogError(
            f"imu/t_s: {d.imu_t.size} samples inside the segments, the diagnosis needs at least {need} "
            f"({MIN_IMU_S:g} s at {1.0 / d.dt_s:g} Hz)"
        )
    with_pose = np.unique(d.imu_seg[np.clip(d.pose_tick, 0, None)])
    bare = np.setdiff1d(np.unique(d.imu_seg), with_pose)
    if bare.size and d.desc.segments:
        t0 = float(d.imu_t[d.imu_seg == bare[0]][0])
        i = int(np.searchsorted([sg.t_start_s for sg in d.desc.segments], t0, side="right")) - 1
        raise FlightLogError(
            f"/description_json: segments[{i}]: no pose within one IMU interval of its IMU samples "
            "(a run starts at its first pose: check the pose clock, pose_sensor.time_offset_s)"
        )
    updates = int(d.pose_tc.size - d.pose_start.sum())
    if updates < 1:
        raise FlightLogError(
            f"pose/t_capture_s: {d.pose_tc.size} pose(s) on the IMU ticks, each the first of its run: the "
            "diagnosis needs at least one more (a run starts at its first pose, the next ones are compared)"
        )


def resolve(log) -> tuple:
    """(log, d): the log with every time stamp from its own origin
    (flight_log.relative_to_start; a log on a Unix epoch is diagnosed as the
    same log from zero), and its LogData; a log too short to diagnose is
    refused (FlightLogError, check_enough)."""
    log = relative_to_start(log)
    d = prepare(log)
    check_enough(d)
    return log, d
