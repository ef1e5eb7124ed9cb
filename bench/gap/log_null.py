"""A null calibration made for one flight log (a parametric bootstrap).

The committed null calibrations (bench/gap/null.py) hold for the bench's
3 kg inspector flying the bench's manoeuvres. Any other log (another
vehicle, other sensors, other time stamps or valve commands) gets its own:
the log's own flight is flown again by the truth plant with nothing
unmodelled (bench/sim/vehicle_sim.py): the vehicle, IMU and pose sensor its
description states, every run from its first pose at rest, the log's own
valve commands, IMU time stamps and pose capture times, fresh sensor noise
per run. Each such null log is diagnosed without thresholds, and each
detection statistic gets the threshold that leaves FA_EACH of a fitted tail
above it.

The tail: a Gumbel distribution fitted by moments to the logarithm of the
statistic (a Frechet tail). Both statistics are maxima (of |z| over the gap
map's cells, of -log10 p over the candidates), and their null tails are
heavier than a Gumbel on the raw values gives: on the committed 1000-run
docking calibration the raw Gumbel fit puts the 99.5 % point of the map
statistic at 5.16 against 5.54 measured; the fit on the logarithm at 5.69.
Over 300 random 40-run subsets of that calibration the two thresholds
together flagged a median 0.5 % (95th percentile 1.4 %) of the 1000 null
runs in one seeded draw; tests/py/test_log_null.py repeats the check with
its own seed and requires a median of at most 1 % and a 95th percentile of
at most 2 %, on both committed calibrations.

Made on demand and cached (``cache_dir``, default ~/.cache/proxops) under
the SHA-256 of everything it depends on; the answer carries its size, wall
time and whether it came from the cache.
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
VERSION = 1  # bump when the bootstrap or the diagnosis statistics change
EULER_GAMMA = 0.5772156649015329


def frechet_threshold(values, fa: float = FA_EACH) -> float:
    """The (1 - fa) quantile of a Gumbel fitted by moments to log(values)."""
    v = np.log(np.maximum(np.asarray(values, float), 1e-12))
    beta = float(np.std(v, ddof=1)) * np.sqrt(6.0) / np.pi
    mu = float(np.mean(v)) - EULER_GAMMA * beta
    return float(np.exp(mu - beta * np.log(-np.log(1.0 - fa))))


def plan_of(log):
    """(description, [PlanSegment], per-run times) of the flight in ``log``:
    each run from its first pose, at rest, with the log's valve commands,
    IMU time stamps and pose capture times."""
    from bench.gap.replay import prepare
    from bench.sim.vehicle_sim import PlanSegment

    d = prepare(log)
    desc = d.desc
    description = dict(log.description or {})
    if "segments" in description:
        description.pop("segments")
    seg_ids = np.unique(d.imu_seg)
    valves = log["valves"] if log.has("valves") else None
    plan, times = [], []
    vt = von = None
    if valves is not None:
        vt = np.asarray(valves["t_s"], float)
        if "on_time_s" in valves:
            von = np.asarray(valves["on_time_s"], float).reshape(vt.size, -1)
        else:
            mask = np.asarray(valves["mask"]).astype(np.int64)
            von = ((mask[:, None] >> np.arange(desc.n_thrusters)[None, :]) & 1) * np.asarray(
                valves["interval_s"], float
            )[:, None]
    pose_seg = d.imu_seg[np.clip(d.pose_tick, 0, d.imu_t.size - 1)]
    for s in seg_ids:
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
        plan.append(PlanSegment("other", t1 - t0, d.pose_r[j].copy(), d.pose_q[j].copy(), cmd_t, cmd_on))
        # capture times on the IMU clock, before they were moved to IMU ticks
        tc = d.pose_tc[pm] - d.pose_align_s[pm]
        times.append({"imu_t": it.copy(), "pose_t": tc, "pose_delay": (d.pose_tf - d.pose_tc)[pm]})
    return description, plan, times, d


def fingerprint(log, runs: int, seed: int) -> str:
    """SHA-256 of everything a calibration for ``log`` depends on."""
    description, plan, times, d = plan_of(log)
    h = hashlib.sha256()
    h.update(
        json.dumps(
            {"v": VERSION, "runs": runs, "seed": seed, "description": description, "has_valves": log.has("valves")},
            sort_keys=True,
            default=str,
        ).encode()
    )
    for p, tm in zip(plan, times):
        for a in (p.r0_hill_m, p.q0_hb, p.cmd_t_s, p.cmd_on_s, tm["imu_t"], tm["pose_t"], tm["pose_delay"]):
            h.update(np.ascontiguousarray(np.asarray(a, float)).tobytes())
    h.update(np.ascontiguousarray(d.pose_R[:, [0, 3], [0, 3]]).tobytes())
    return h.hexdigest()


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


def _one(seed, flight):
    log, prepared = flight
    from bench.gap.detection import null_statistics

    return {"seed": int(seed), **null_statistics(null_log_like(log, seed, prepared))}


def default_cache_dir() -> Path:
    return Path(os.environ.get("PROXOPS_CACHE", Path.home() / ".cache" / "proxops")) / "null_calibration"


def calibrate_for_log(
    log, runs: int = DEFAULT_RUNS, seed: int = 7100, workers: int | None = None, cache_dir=None, progress: bool = True
) -> dict:
    """The null calibration for ``log`` (from the cache when it was made before).
    Its runs are a campaign (bench/runner/runner.py) on the cluster the
    process was configured with, each kept as it finishes next to the cache
    entry, so an interrupted calibration resumes."""
    from bench.runner.runner import Campaign, results
    from bench.runner.store import RunStore

    prepared = plan_of(log)
    key = fingerprint(log, runs, seed)
    cdir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = cdir / f"{key}.json"
    if path.exists():
        try:
            cal = json.loads(path.read_text())
            cal["from_cache"] = str(path)
            return cal
        except ValueError:
            pass  # a damaged cache entry is made again
    t0 = time.time()
    seeds = [int(s) for s in np.random.default_rng(seed).integers(0, 2**31, runs)]
    try:
        store = RunStore("log-null", {"fingerprint": key}, root=cdir).open()
    except OSError:
        store = None
    recs = Campaign(store, workers=workers, progress=progress).map(
        "null",
        _one,
        seeds,
        idents=[{"seed": s} for s in seeds],
        shared=(log, prepared),
        label="null calibration for the log",
    )
    failed = [r for r in recs if not r["ok"]]
    if failed:
        raise ValueError(
            f"{len(failed)} of {runs} null runs for the log failed (first: run {failed[0]['index']}, "
            f"seed {failed[0]['seed']}: {failed[0]['error']})"
        )
    rows = results(recs)
    z = np.array([r["map_max_abs_z"] for r in rows])
    b = np.array([r["screen_logp"] for r in rows])
    thr = {"map_max_abs_z": frechet_threshold(z), "screen_logp": frechet_threshold(b)}
    cal = {
        "thresholds": thr,
        "method": "parametric bootstrap of the log's own flight, Frechet tail per statistic",
        "false_alarm_target_each": FA_EACH,
        "runs": int(runs),
        "seed": int(seed),
        "fingerprint": key,
        "for_log": True,
        "null_map_max_abs_z": z.tolist(),
        "null_screen_logp": b.tolist(),
        "false_alarm_rate": float(np.mean((z > thr["map_max_abs_z"]) | (b > thr["screen_logp"]))),
        "elapsed_s": time.time() - t0,
        "version": VERSION,
    }
    try:
        cdir.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(cal, indent=1) + "\n")
        tmp.replace(path)
        cal["cached_at"] = str(path)
        if store is not None:  # every run is in the cache entry now
            shutil.rmtree(store.path, ignore_errors=True)
    except OSError as exc:
        print(f"note: calibration not cached ({exc})", file=sys.stderr)
    cal["from_cache"] = None
    return cal


class CalibrationMismatch(ValueError):
    """A supplied calibration that does not hold for the log; says why."""


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
        key = fingerprint(log, int(cal.get("runs", DEFAULT_RUNS)), int(cal.get("seed", 7100)))
        if cal.get("fingerprint") != key:
            raise CalibrationMismatch(
                f"{source}: made for another log (its fingerprint {str(cal.get('fingerprint'))[:12]}, "
                f"this log's {key[:12]}): vehicle, sensors, valve commands or time stamps differ"
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
        "note": f"null calibration made for this log ({why}): {cal['runs']} simulated flights of its own "
        f"commands, " + ("from the cache" if cal.get("from_cache") else f"{cal['elapsed_s']:.0f} s"),
    }
