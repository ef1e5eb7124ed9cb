"""A null calibration made for one flight log (a parametric bootstrap).

The committed null calibrations (bench/gap/null.py) hold for the bench's
3 kg inspector flying the bench's manoeuvres. Any other log (another
vehicle, other sensors, other time stamps or valve commands) gets its own:
the log's own flight is flown again by the truth plant with nothing
unmodelled (bench/sim/vehicle_sim.py): the vehicle, IMU and pose sensor its
description states, every run from its first pose at rest, the log's own
valve commands, IMU time stamps, pose capture times, delivery delays and
stated pose sigmas (each pose's noise drawn at its own r_sigma_m and
att_sigma_rad), fresh sensor noise per run. Each such null log is diagnosed
without thresholds, and each detection statistic gets the threshold that
leaves FA_EACH of a fitted tail above it.

The tail (``tail_threshold``): the statistic's excesses over an order
statistic (the top TAIL_FRACTION of the runs) are exponential, the tail of
a Gumbel-domain maximum, with their scale unknown: the threshold is the
(1 - FA_EACH) point of the predictive distribution (a Lomax: the
exponential averaged over the scale's posterior), which holds a 40-run
calibration's expected false-alarm rate at the target where the fitted
scale alone would not. Only the values above the order statistic enter, so
runs far below the tail do not move it (the earlier Gumbel fitted by moments
to log(values), ``frechet_threshold``, was pulled up by them). Evidence on
the committed 1000-run calibrations: ``python -m bench.campaigns.gap.log_null_far tails``
and tests/py/test_log_null.py.

Made on demand and cached (``cache_dir``, default ~/.cache/proxops) under
the SHA-256 of what the thresholds depend on (``key_contents``); an entry
is checked when read and made again when it does not hold. The answer
carries its size, wall time and whether it came from the cache.
``python -m bench.campaigns.gap.log_null_far far`` measures the false-alarm rate of the
calibration on random vehicles (bench/sim/random_vehicle.py).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

FA_EACH = 0.005
DEFAULT_RUNS = 40
# 2: the tail fitted to the top of the values; the pose noise at the log's
# own sigmas; the key without absolute times or the first pose. 3: the
# statistics of the exact candidates. 4: shared Jacobians. 5: the gyro
# rows whitened with the gyroscopic term's share of their noise.
VERSION = 5  # bump when the bootstrap, the tail or the diagnosis statistics change
STATISTICS = ("map_max_abs_z", "screen_logp")
TAIL_FRACTION = 0.6  # the share of the runs, from the top, whose excesses are fitted
TIME_QUANTUM_S = 1e-6  # time stamps in the key, relative to their run's start
SIGMA_DIGITS = 3  # significant digits of the pose sigmas in the key
# Another flight of the same vehicle and plan shares a calibration when its
# timing has the same shape (``shape_differs``): commands within
# COMMAND_TOLERANCE_S of each other, the same IMU and pose rates, jitter of
# the same size, as many samples dropped.
COMMAND_TOLERANCE_S = 0.005
EULER_GAMMA = 0.5772156649015329


def tail_threshold(values, fa: float = FA_EACH) -> tuple:
    """(threshold, tail): the (1 - fa) point of the predictive tail of
    ``values`` (one statistic's null values), and what it was fitted to.

    The k = TAIL_FRACTION * n largest values exceed the next one, u, by
    excesses taken as exponential with an unknown scale (prior 1/scale);
    the chance that a new value exceeds u is (k + 1) / (n + 1). Averaged over
    the scale's posterior, P(x > u + e) = (k + 1) / (n + 1) (1 + e / S)^-k
    with S the sum of the excesses, so the threshold is
    u + S (((k + 1) / ((n + 1) fa))^(1 / k) - 1). Values below u do not
    enter."""
    v = np.sort(np.asarray(values, float).ravel())[::-1]
    if v.size < 2 or not np.all(np.isfinite(v)):
        raise ValueError(f"a tail needs at least 2 finite null values (got {v.size}, or some not finite)")
    n = v.size
    k = int(min(max(round(TAIL_FRACTION * n), 1), n - 1))
    u = float(v[k])
    s = float(np.sum(v[:k] - u))
    above = (k + 1) / (n + 1)
    thr = u + s * ((above / fa) ** (1.0 / k) - 1.0)
    tail = {
        "model": "exponential excesses over the (k + 1)-th largest value, scale unknown (predictive Lomax)",
        "n": n,
        "k": k,
        "u": u,
        "mean_excess": s / k,
        "p_above_u": above,
        "fa": fa,
        "threshold": thr,
    }
    return thr, tail


def frechet_threshold(values, fa: float = FA_EACH) -> float:
    """The (1 - fa) quantile of a Gumbel fitted by moments to log(values):
    the tail model before ``tail_threshold`` (kept for the committed 12 kg
    calibration, bench/campaigns/gap/validate_vehicle.py, and for comparison). Small
    values pull it up: it is fitted to all of them on a log scale."""
    v = np.log(np.maximum(np.asarray(values, float), 1e-12))
    beta = float(np.std(v, ddof=1)) * np.sqrt(6.0) / np.pi
    mu = float(np.mean(v)) - EULER_GAMMA * beta
    return float(np.exp(mu - beta * np.log(-np.log(1.0 - fa))))


def thresholds_of(rows: list) -> tuple:
    """({statistic: threshold}, {statistic: tail}, {statistic: null values})
    of null runs' statistics."""
    thr, tails, vals = {}, {}, {}
    for k in STATISTICS:
        vals[k] = np.array([r[k] for r in rows], float)
        thr[k], tails[k] = tail_threshold(vals[k])
    return thr, tails, vals


def plan_of(log):
    """(description, [PlanSegment], per-run times, prepared log) of the
    flight in ``log``: each run from its first pose, at rest, with the log's
    valve commands, IMU time stamps, pose capture times and delivery delays,
    and each pose's stated sigmas (r_sigma_m, att_sigma_rad)."""
    from bench.gap.load import prepare
    from bench.sim.vehicle_sim import PlanSegment
    from bench.so3 import rotmats

    d = prepare(log)
    desc = d.desc
    description = dict(log.description or {})
    description.pop("segments", None)
    vs = d.valve_stream  # each pulse ended at the next command at the latest, as the replay reads it
    vt, von = (np.asarray(vs["t_s"], float), np.asarray(vs["on_time_s"], float)) if vs is not None else (None, None)
    plan, times = [], []
    pose_seg = d.imu_seg[np.clip(d.pose_tick, 0, d.imu_t.size - 1)]
    for s in np.unique(d.imu_seg):
        it = d.imu_t[d.imu_seg == s]
        t0, t1 = float(it[0] - d.dt_s), float(it[-1])
        pm = np.flatnonzero(pose_seg == s)
        if pm.size == 0:
            continue
        j = pm[0]
        if vt is not None:
            m = (vt >= t0) & (vt < t1)
            cmd_t, cmd_on = vt[m] - t0, von[m]
        else:
            cmd_t, cmd_on = np.zeros(0), np.zeros((0, desc.n_thrusters))
        # The replay's poses are of the IMU's point; the plant flies the centre of mass.
        r0 = d.pose_r[j] - (rotmats(d.pose_q[j][None])[0] @ d.imu_from_com_b if d.imu_from_com_b is not None else 0.0)
        plan.append(PlanSegment("other", t1 - t0, r0, d.pose_q[j].copy(), cmd_t, cmd_on))
        times.append(
            {
                "imu_t": it.copy(),
                # capture times on the IMU clock, before they were moved to IMU ticks
                "pose_t": d.pose_tc[pm] - d.pose_align_s[pm],
                "pose_delay": (d.pose_tf - d.pose_tc)[pm],
                "r_sigma_m": np.sqrt(d.pose_R[pm, 0, 0]),
                "att_sigma_rad": np.sqrt(d.pose_R[pm, 3, 3]),
            }
        )
    return description, plan, times, d


def _quantised(a, quantum: float) -> np.ndarray:
    return np.round(np.asarray(a, float) / quantum).astype(np.int64)


def _significant(a, digits: int = SIGMA_DIGITS) -> list:
    return [f"{float(x):.{digits}g}" for x in np.ravel(a)]


def key_contents(log, runs: int, seed: int, prepared=None) -> dict:
    """What a calibration for ``log`` depends on, as the cache keys it: the
    statistics' VERSION, runs, seed, the description (vehicle, sensors,
    noise model; not its segments' absolute times), whether valves were
    logged, and per run its length, valve commands and on-times, IMU time
    stamps, pose capture times and delivery delays (all relative to the
    run's start, in TIME_QUANTUM_S) and its poses' stated sigmas (to
    SIGMA_DIGITS significant digits): the log exactly, less its noise and
    epoch. Another flight of the same vehicle and plan (``family``) whose
    timing has the same shape (``shape_differs``) shares its calibration.
    Not the first pose: the runs start there, but its noise does not move
    the thresholds."""
    description, plan, times, d = prepared or plan_of(log)
    q = TIME_QUANTUM_S
    per_run = []
    for p, tm in zip(plan, times):
        t0 = float(tm["imu_t"][0] - d.dt_s)
        per_run.append(
            {
                "duration": int(_quantised(p.duration_s, q)),
                "cmd_t": _quantised(p.cmd_t_s, q).tolist(),
                "cmd_on": _quantised(p.cmd_on_s, q).tolist(),
                "imu_t": _quantised(tm["imu_t"] - t0, q).tolist(),
                "pose_t": _quantised(tm["pose_t"] - t0, q).tolist(),
                "pose_delay": _quantised(tm["pose_delay"], q).tolist(),
                "r_sigma_m": _significant(tm["r_sigma_m"]),
                "att_sigma_rad": _significant(tm["att_sigma_rad"]),
            }
        )
    return {**_statistics_and_vehicle(log, runs, seed, description), "runs_flown": per_run}


def _statistics_and_vehicle(log, runs: int, seed: int, description: dict) -> dict:
    """What both keys hold: the statistics' VERSION, runs, seed, the
    description and whether valves were logged."""
    return {
        "version": VERSION,
        "runs": int(runs),
        "seed": int(seed),
        "description": description,
        "has_valves": bool(log.has("valves")),
    }


def _sha256(contents: dict) -> str:
    return hashlib.sha256(json.dumps(contents, sort_keys=True, default=str).encode()).hexdigest()


def fingerprint(log, runs: int, seed: int, prepared=None) -> str:
    """SHA-256 of ``key_contents``."""
    return _sha256(key_contents(log, runs, seed, prepared))


def family_contents(log, runs: int, seed: int, prepared=None) -> dict:
    """What every flight sharing a calibration has in common: the
    statistics' VERSION, runs, seed, the description, whether valves were
    logged, and per run how many commands it gave and which valves each
    opened. The rest (command times, the timing of the samples) is
    compared within tolerances (``shape_differs``)."""
    description, plan, _, _ = prepared or plan_of(log)
    opened = [[int(np.dot(on > 0.0, 1 << np.arange(on.size))) for on in p.cmd_on_s] for p in plan]
    return {**_statistics_and_vehicle(log, runs, seed, description), "valves_opened": opened}


def family(log, runs: int, seed: int, prepared=None) -> str:
    """SHA-256 of ``family_contents``."""
    return _sha256(family_contents(log, runs, seed, prepared))


def timing_shape(prepared) -> list:
    """Per run: its length, command times and on-times (from the run's
    start), and the shape of its timing: IMU samples, their median interval,
    jitter (RMS of the intervals about it, gaps left out) and share dropped;
    poses, their median interval and delivery delay, and their median
    stated sigmas."""
    _, plan, times, d = prepared
    out = []
    for p, tm in zip(plan, times):
        di = np.diff(tm["imu_t"])
        step = float(np.median(di)) if di.size else float(d.dt_s)
        kept, gaps = di[di < 1.5 * step], di[di >= 1.5 * step]
        dp = np.diff(np.sort(tm["pose_t"]))
        out.append(
            {
                "duration_s": float(p.duration_s),
                "cmd_t_s": np.asarray(p.cmd_t_s, float).tolist(),
                "cmd_on_s": np.asarray(p.cmd_on_s, float).tolist(),
                "imu_n": int(tm["imu_t"].size),
                "imu_step_s": step,
                "imu_jitter_s": float(np.sqrt(np.mean((kept - step) ** 2))) if kept.size else 0.0,
                "imu_dropped": float(np.sum(np.round(gaps / step) - 1.0) / max(tm["imu_t"].size, 1)),
                "pose_n": int(tm["pose_t"].size),
                "pose_step_s": float(np.median(dp)) if dp.size else 0.0,
                "pose_delay_s": float(np.median(tm["pose_delay"])),
                "r_sigma_m": float(np.median(tm["r_sigma_m"])),
                "att_sigma_rad": float(np.median(tm["att_sigma_rad"])),
            }
        )
    return out


def _apart(a: float, b: float, rel: float, floor: float = 0.0) -> bool:
    return abs(a - b) > rel * max(abs(a), abs(b)) + floor


def _shape_like(m, t: dict) -> bool:
    """Whether ``m`` holds every field of the timing shape ``t`` as finite
    numbers (lists of them for the commands)."""
    if not isinstance(m, dict) or set(m) != set(t):
        return False
    for k, v in m.items():
        if isinstance(v, bool) or not isinstance(v, (int, float, list)):
            return False
        try:
            a = np.asarray(v, float)
        except (TypeError, ValueError):
            return False
        if not np.all(np.isfinite(a)) or (isinstance(v, list) and a.ndim != np.asarray(t[k]).ndim):
            return False
    return True


def shape_differs(made: list, this: list) -> str | None:
    """Where the timing of the flight a calibration was made for (``made``)
    and this log's (``this``, both ``timing_shape``) differ beyond what
    moves the thresholds (None: they share it). Tolerances: the run's length
    to 0.5 % and three samples, commands to COMMAND_TOLERANCE_S from the
    first (which may sit up to an IMU interval elsewhere: the run starts at
    its first sample, whose phase is the clock's), sample
    and pose counts to 1 % and 2 %, their intervals to 0.5 % and 1 %, IMU
    jitter to a factor of two (or 2 % of the interval), drops to 0.5 % of
    the samples, the pose delay to 10 % and 5 ms, the pose sigmas to 5 %."""
    if not isinstance(made, list) or len(made) != len(this):
        return "another number of runs"
    bad = next((i for i, (m, t) in enumerate(zip(made, this)) if not _shape_like(m, t)), None)
    if bad is not None:  # a damaged or edited entry: refused, not read
        return f"shape[{bad}]: not a timing shape (a field missing or not finite numbers)"
    for i, (m, t) in enumerate(zip(made, this)):
        step = t["imu_step_s"]
        checks = (
            ("length", _apart(m["duration_s"], t["duration_s"], 0.005, 3.0 * step)),
            ("IMU interval", _apart(m["imu_step_s"], step, 0.005)),
            ("IMU samples", _apart(m["imu_n"], t["imu_n"], 0.01, 2.0)),
            ("IMU jitter", _apart(m["imu_jitter_s"], t["imu_jitter_s"], 0.5, 0.02 * step)),
            ("IMU samples dropped", abs(m["imu_dropped"] - t["imu_dropped"]) > 0.005),
            ("pose count", _apart(m["pose_n"], t["pose_n"], 0.02, 2.0)),
            ("pose interval", _apart(m["pose_step_s"], t["pose_step_s"], 0.01)),
            ("pose delay", _apart(m["pose_delay_s"], t["pose_delay_s"], 0.1, 0.005)),
            (
                "pose sigmas",
                _apart(m["r_sigma_m"], t["r_sigma_m"], 0.05) or _apart(m["att_sigma_rad"], t["att_sigma_rad"], 0.05),
            ),
        )
        for what, off in checks:
            if off:
                return f"run {i}: {what}"
        ct, tt = np.asarray(m["cmd_t_s"], float), np.asarray(t["cmd_t_s"], float)
        co, to = np.asarray(m["cmd_on_s"], float), np.asarray(t["cmd_on_s"], float)
        if ct.shape != tt.shape or co.shape != to.shape:
            return f"run {i}: another number of commands"
        if ct.size and abs(ct[0] - tt[0]) > step + COMMAND_TOLERANCE_S:
            return f"run {i}: the first command more than an IMU interval later or earlier"
        # From the first command: the run's start is its first IMU sample, whose phase is the clock's.
        apart = max(np.max(np.abs((ct - ct[0]) - (tt - tt[0])), initial=0.0), np.max(np.abs(co - to), initial=0.0))
        if apart > COMMAND_TOLERANCE_S:
            return f"run {i}: command times or on-times more than {COMMAND_TOLERANCE_S * 1e3:.0f} ms apart"
    return None


def null_log_like(log, seed: int, prepared=None):
    """One null log of the flight in ``log`` (fresh noise from ``seed``)."""
    from bench.sim.vehicle_sim import simulate

    description, plan, times, _ = prepared or plan_of(log)
    sim, _ = simulate(description, plan, stated_biases(description, seed), seed=seed, times=times, with_truth=False)
    if not log.has("valves"):
        sim.streams.pop("valves", None)
    return sim


def stated_biases(description: dict, seed: int) -> dict:
    """Constant IMU biases drawn at the description's stated bias stability
    (per axis, 1 sigma, IMU axes): a bias the IMU's data sheet allows is part
    of the null, not a gap. Empty where none is stated."""
    from bench.sim.log_description import resolve

    r = resolve(description)
    rng = np.random.default_rng([int(seed), 0xB1A5])
    out = {}
    if r.accel_bias_stability_mps2 > 0.0:
        out["accel_bias"] = (r.accel_bias_stability_mps2 * rng.standard_normal(3)).tolist()
    if r.gyro_bias_stability_rps > 0.0:
        out["gyro_bias"] = (r.gyro_bias_stability_rps * rng.standard_normal(3)).tolist()
    return out


_SIGNATURES: dict = {}  # per worker process: the last flight's shared Jacobians


def shared_signatures(log, prepared, seed: int) -> dict:
    """The candidates' Jacobians (attribute.signatures) on the null log of
    ``seed``, which every null run of this flight screens with: the flight,
    plan and time stamps are the same in each, only the noise differs, and
    the Jacobians a run would compute for itself move its statistics by a
    few hundredths (docs/GAP.md). Computed once per worker process."""
    hit = _SIGNATURES.get("flight")
    if hit is None or hit[0] is not log or hit[1] != seed:
        from bench.gap.detection import log_signatures
        from bench.gap.load import prepare

        _SIGNATURES["flight"] = hit = (log, seed, log_signatures(prepare(null_log_like(log, seed, prepared))))
    return hit[2]


def null_run(seed, flight):
    """One null run's statistics. ``flight``: (log, prepared) or (log,
    prepared, the seed of the null log whose Jacobians every run shares)."""
    log, prepared, *shared = flight
    from bench.gap.detection import null_statistics

    given = shared_signatures(log, prepared, shared[0]) if shared and shared[0] is not None else None
    return {"seed": int(seed), **null_statistics(null_log_like(log, seed, prepared), given)}


def default_cache_dir() -> Path:
    return Path(os.environ.get("PROXOPS_CACHE", Path.home() / ".cache" / "proxops")) / "null_calibration"


def unusable(cal, key: str | None = None, runs: int | None = None) -> str | None:
    """Why the calibration ``cal`` (made for a log) cannot be used, None when
    it can: it must be of this VERSION, made for ``key`` with ``runs`` runs,
    hold every statistic's null values (finite) and thresholds that are
    finite, positive and the ones its null values give."""
    if not isinstance(cal, dict):
        return "not a calibration"
    if cal.get("version") != VERSION:
        return f"made by version {cal.get('version')} of the statistics, not {VERSION}"
    if key is not None and cal.get("fingerprint") != key:
        return f"made for another log (fingerprint {str(cal.get('fingerprint'))[:12]}, this log's {key[:12]})"
    thr = cal.get("thresholds")
    for k in STATISTICS:
        t = thr.get(k) if isinstance(thr, dict) else None
        vals = cal.get(f"null_{k}")
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not np.isfinite(t) or t <= 0.0:
            return f"thresholds.{k} missing, not finite or not positive"
        if not isinstance(vals, list) or (runs is not None and len(vals) != runs):
            return f"null_{k} missing or not {runs} values"
        try:
            expect = tail_threshold(vals)[0]
        except (TypeError, ValueError):
            return f"null_{k} not finite numbers"
        if not np.isclose(t, expect, rtol=1e-9, atol=0.0):
            return f"thresholds.{k} {t:.4g} is not its null values' {expect:.4g}"
    return None


def _cached(path: Path, key: str, runs: int) -> tuple:
    """(calibration or None, why the entry at ``path`` was not used or None)."""
    if not path.exists():
        return None, None
    try:
        cal = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return None, f"unreadable ({type(exc).__name__})"
    why = unusable(cal, key, runs)
    return (None, why) if why else (cal, None)


def _shared(cdir: Path, fam: str, shape: list, runs: int) -> dict | None:
    """A usable cached calibration made for another flight of the same
    vehicle and plan (``family``) whose timing has this log's shape, or
    None. It says so (``shared_from``)."""
    for path in sorted(cdir.glob(f"{fam[:16]}-*.json")):
        try:
            cal = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if (
            unusable(cal, None, runs) is None
            and cal.get("family") == fam
            and shape_differs(cal.get("shape"), shape) is None
        ):
            cal["_path"] = str(path)
            cal["shared_from"] = f"another flight of this vehicle and plan (fingerprint {str(cal['fingerprint'])[:12]})"
            return cal
    return None


def _store(cal: dict, path: Path, run_store) -> None:
    """Write ``cal`` at ``path`` (atomically); the runs' store goes."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(cal, indent=1) + "\n")
        tmp.replace(path)
        cal["cached_at"] = str(path)
        if run_store is not None:  # every run is in the cache entry now
            shutil.rmtree(run_store.path, ignore_errors=True)
    except OSError as exc:
        print(f"note: calibration not cached ({exc})", file=sys.stderr)


def calibrate_for_log(
    log, runs: int = DEFAULT_RUNS, seed: int = 7100, workers: int | None = None, cache_dir=None, progress: bool = True
) -> dict:
    """The null calibration for ``log`` (from the cache when it was made
    before and its entry holds; a damaged or mismatched entry is made again).
    Its runs are a campaign (bench/runner/runner.py) on the cluster the
    process was configured with, each kept as it finishes next to the cache
    entry, so an interrupted calibration resumes."""
    from bench.runner.runner import Campaign, results
    from bench.runner.store import RunStore
    from bench.sim.flight_log import relative_to_start

    log = relative_to_start(log)  # as diagnose() reads it (the key is relative to each run's start anyway)
    prepared = plan_of(log)
    key = fingerprint(log, runs, seed, prepared)
    fam, shape = family(log, runs, seed, prepared), timing_shape(prepared)
    cdir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = cdir / f"{fam[:16]}-{key}.json"
    cal, why = _cached(path, key, runs)
    if cal is None and why is None:  # none for this log: one for another flight of its vehicle and plan?
        cal = _shared(cdir, fam, shape, runs)
    if cal is not None:
        cal["from_cache"] = cal.pop("_path", str(path))
        return cal
    if why:
        print(f"note: cached calibration {path.name} not used ({why}); making it again", file=sys.stderr)
    t0 = time.time()
    seeds = [int(s) for s in np.random.default_rng(seed).integers(0, 2**31, runs)]
    try:
        store = RunStore("log-null", {"fingerprint": key}, root=cdir).open()
    except OSError:
        store = None
    recs = Campaign(store, workers=workers, progress=progress).map(
        "null",
        null_run,
        seeds,
        idents=[{"seed": s} for s in seeds],
        shared=(log, prepared, seeds[0]),
        label="null calibration for the log",
    )
    failed = [r for r in recs if not r["ok"]]
    if failed:
        from bench.gap.validity import outside_envelope

        fields = outside_envelope(prepared[3].desc)  # what to check in the description, when anything
        raise ValueError(
            (f"/description_json: {'; '.join(fields)}: " if fields else "")
            + f"{len(failed)} of {runs} null runs for the log failed (first: run {failed[0]['index']}, "
            f"seed {failed[0]['seed']}: {str(failed[0]['error'])[:200]})"
        )
    rows = results(recs)
    unfit = [k for k in STATISTICS if not np.all(np.isfinite([float(r[k]) for r in rows]))]
    if unfit:  # the diagnosis does not fit even the log's own flights: name what to check
        from bench.gap.validity import not_judgeable

        raise ValueError(not_judgeable(prepared[3].desc, unfit, runs))
    thr, tails, vals = thresholds_of(rows)
    z, b = vals["map_max_abs_z"], vals["screen_logp"]
    cal = {
        "thresholds": thr,
        "tail": tails,
        "method": "parametric bootstrap of the log's own flight; per statistic, the predictive exponential "
        f"tail of its top {TAIL_FRACTION:.0%}",
        "false_alarm_target_each": FA_EACH,
        "runs": int(runs),
        "seed": int(seed),
        "fingerprint": key,
        "family": fam,
        "shape": shape,
        "for_log": True,
        "null_map_max_abs_z": z.tolist(),
        "null_screen_logp": b.tolist(),
        "false_alarm_rate": float(np.mean((z > thr["map_max_abs_z"]) | (b > thr["screen_logp"]))),
        "elapsed_s": time.time() - t0,
        "version": VERSION,
        **({"made_again_because": why} if why else {}),
    }
    _store(cal, path, store)
    cal["from_cache"] = None
    return cal


class CalibrationMismatch(ValueError):
    """A supplied calibration that does not hold for the log; says why."""


def thresholds_for(log, d, calibration, make_calibration: bool, source, runs, progress) -> tuple:
    """(calibration, its description) for diagnose(): ``{}`` (no
    thresholds), the committed docking calibration when none may be made,
    else ``choose``'s."""
    from bench.gap import null as nullmod

    if calibration == {}:
        return {}, {"source": "none (no thresholds)", "runs": 0, "note": None}
    if calibration is None and not make_calibration:
        return nullmod.load(), {"source": "committed (docking logs of the bench inspector)", "note": None}
    return choose(log, d, calibration, source, runs=runs or DEFAULT_RUNS, progress=progress)


def _bench_like(desc, ref=None) -> list:
    """Where the log's vehicle and sensors differ from ``ref``'s (default the
    bench inspector's; empty: the same)."""
    from bench.sim.log_description import resolve

    ref = ref if ref is not None else resolve(None)
    diffs = []
    if desc.n_thrusters != ref.n_thrusters:
        diffs.append(f"{desc.n_thrusters} thrusters, not {ref.n_thrusters}")
    else:
        for name, a, b in (
            ("thruster positions", [t.position_b_m for t in desc.thrusters], [t.position_b_m for t in ref.thrusters]),
            ("thruster directions", [t.direction_b for t in desc.thrusters], [t.direction_b for t in ref.thrusters]),
            ("thrusts", [t.thrust_n for t in desc.thrusters], [t.thrust_n for t in ref.thrusters]),
        ):
            if not np.allclose(a, b, rtol=1e-6, atol=1e-9):
                diffs.append(f"other {name}")
    for name, a, b in (
        ("mass", desc.mass_kg, ref.mass_kg),
        ("inertia", desc.inertia_kgm2, ref.inertia_kgm2),
        ("centre of mass", desc.com_b_m, ref.com_b_m),
        ("IMU mounting", desc.imu_q_body_imu, ref.imu_q_body_imu),
        ("IMU position", desc.imu_position_b_m, ref.imu_position_b_m),
        ("accelerometer noise", desc.accel_sigma_mps2, ref.accel_sigma_mps2),
        ("gyro noise", desc.gyro_sigma_rps, ref.gyro_sigma_rps),
        ("pose reference point", desc.pose_reference_b_m, ref.pose_reference_b_m),
        ("accelerometer bias stability", desc.accel_bias_stability_mps2, ref.accel_bias_stability_mps2),
        ("gyro bias stability", desc.gyro_bias_stability_rps, ref.gyro_bias_stability_rps),
    ):
        if not np.allclose(a, b, rtol=1e-6, atol=1e-12):
            diffs.append(f"another {name}")
    rate, ref_rate = desc.imu_rate_hz or 10.0, ref.imu_rate_hz or 10.0
    if abs(rate - ref_rate) > 1e-9:
        diffs.append(f"IMU at {rate:g} Hz, not {ref_rate:g} Hz")
    for name, a, b in (
        ("pose clock offset", desc.pose_time_offset_s, ref.pose_time_offset_s),
        ("pose latency", desc.pose_latency_s, ref.pose_latency_s),
    ):
        if abs(a - b) > 1e-9:
            diffs.append(f"another {name}")
    return diffs


def check_supplied(cal: dict, log, d, source: str) -> None:
    """Refuse (CalibrationMismatch) a calibration that does not hold for the log."""
    thr = cal.get("thresholds") if isinstance(cal, dict) else None
    for k in ("map_max_abs_z", "screen_logp"):
        v = thr.get(k) if isinstance(thr, dict) else None
        if not isinstance(v, (int, float)) or not np.isfinite(v):
            raise CalibrationMismatch(
                f"{source}: thresholds.{k} missing or not a finite number: not a null calibration"
            )
    if cal.get("for_log"):
        why = unusable(cal)
        if why:
            raise CalibrationMismatch(f"{source}: {why}. Leave out --calibration to make one for the log")
        runs, seed = int(cal.get("runs", DEFAULT_RUNS)), int(cal.get("seed", 7100))
        prepared = plan_of(log)
        if cal.get("fingerprint") == fingerprint(log, runs, seed, prepared):
            return
        if cal.get("family") != family(log, runs, seed, prepared):
            raise CalibrationMismatch(
                f"{source}: made for another vehicle or plan (its family {str(cal.get('family'))[:12]}): "
                "vehicle, sensors, noise model, runs or the valves each command opened differ"
            )
        off = shape_differs(cal.get("shape"), timing_shape(prepared))
        if off:
            raise CalibrationMismatch(
                f"{source}: made for another flight of this vehicle and plan, timed otherwise ({off})"
            )
        return
    from bench.sim.log_description import DescriptionError, resolve

    try:
        ref = resolve(cal["description"]) if isinstance(cal.get("description"), dict) else None
    except DescriptionError as exc:
        raise CalibrationMismatch(f"{source}: its description is not valid ({exc})") from None
    diffs = _bench_like(d.desc, ref)
    if diffs:
        whose = f"the {cal.get('vehicle', 'described')} vehicle" if ref is not None else "the bench's 3 kg inspector"
        raise CalibrationMismatch(
            f"{source}: made for {whose}; this log's vehicle and sensors differ "
            f"({'; '.join(diffs)}). Leave out --calibration to make one for the log"
        )
    flown = d.desc.manoeuvres()
    cal_m = cal.get("manoeuvres", "docking")
    if flown and "+".join(m for m in ("docking", "characterisation") if m in flown) != cal_m:
        raise CalibrationMismatch(f"{source}: made for logs that fly {cal_m}; this log flies {'+'.join(flown)}")


def choose(
    log,
    d,
    supplied: dict | None = None,
    source: str | None = None,
    runs: int = DEFAULT_RUNS,
    progress: bool = False,
    cache_dir=None,
) -> tuple:
    """(calibration, note): the calibration the diagnosis of ``log`` uses and
    a note for the answer. A supplied one is checked against the log; without
    one, the committed calibration when the log is the bench's vehicle and
    sensors flying the bench's manoeuvres, else one made for the log."""
    from bench.gap import null as nullmod

    if supplied is not None:
        check_supplied(supplied, log, d, source or "the calibration")
        return supplied, {"source": source or "supplied", "runs": supplied.get("runs"), "note": None}
    diffs = _bench_like(d.desc)
    flown = d.desc.manoeuvres()
    known = "+".join(m for m in ("docking", "characterisation") if m in flown)
    if not diffs and (
        not flown or (set(flown) <= {"docking", "characterisation"} and known in nullmod.DATA_BY_MANOEUVRES)
    ):
        cal = nullmod.load(manoeuvres=known or "docking")
        note = (
            None
            if flown
            else ("manoeuvres not stated in the log: thresholds from the committed null calibration of docking logs")
        )
        return cal, {
            "source": f"committed ({known or 'docking'} logs of the bench inspector)",
            "runs": cal.get("runs"),
            "note": note,
        }
    why = (
        (
            "; ".join(diffs[:3])
            + (f" and {len(diffs) - 3} more differences from the bench inspector" if len(diffs) > 3 else "")
        )
        if diffs
        else f"manoeuvres {'+'.join(flown)}"
    )
    cal = calibrate_for_log(log, runs=runs, progress=progress, cache_dir=cache_dir)
    return cal, {
        "source": "made for this log",
        "runs": cal["runs"],
        "elapsed_s": cal["elapsed_s"],
        "from_cache": cal.get("from_cache"),
        **({"made_again_because": cal["made_again_because"]} if cal.get("made_again_because") else {}),
        **({"shared_from": cal["shared_from"]} if cal.get("shared_from") else {}),
        "note": f"null calibration made for this log ({why}): {cal['runs']} simulated flights of its own "
        f"commands, "
        + (
            f"from the cache, made for {cal['shared_from']}"
            if cal.get("shared_from")
            else ("from the cache" if cal.get("from_cache") else f"{cal['elapsed_s']:.0f} s")
        ),
    }
