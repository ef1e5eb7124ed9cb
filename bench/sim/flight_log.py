"""The flight log: a versioned HDF5 file that the bench, the HIL recorder and
a user with real data can all write, and that everything downstream reads.

The contract is docs/FLIGHT_LOG.md; this module is its executable form. A
user can write a log with plain h5py by following that page; ``validate``
names the stream, the field, the row and what is wrong.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.sim import flight_log_bounds as bounds
from bench.sim import flight_log_dims

FORMAT_NAME = "proxops-flight-log"
FORMAT_VERSION = 2
READ_VERSIONS = (1, 2)
QUAT_NORM_TOL = 1e-6
PER_THRUSTER = -1  # FieldSpec.width: one column per thruster of the described vehicle
# A valve pulse may run past the next command by up to this much (command
# stamps jitter): it is clipped to end at the next command, and the diagnosis
# counts it. A longer overlap is refused.
VALVE_OVERLAP_TOL_S = 2e-3
# An overlap this small is the rounding of the stamps themselves (float64
# resolves 0.24 us at a Unix epoch of 1.7e9 s): clipped, not counted.
STAMP_ROUNDING_S = 1e-6


@dataclass(frozen=True)
class FieldSpec:
    name: str
    width: int | None  # None: one value per row; k: k values per row; PER_THRUSTER: one per thruster
    unit: str
    quaternion: bool = False
    integer: bool = False
    optional: bool = False  # the stream is valid without it (see the stream's own rule)
    nonnegative: bool = False
    stamp: bool = False  # a time stamp (any epoch), not a duration
    positive: bool = False  # a standard deviation: > 0
    max_abs: float = bounds.MAX_VALUE  # largest magnitude of a value (flight_log_bounds)
    min_value: float | None = None  # smallest value, where one exists (a pose sigma)


@dataclass(frozen=True)
class StreamSpec:
    name: str
    time_field: str
    fields: tuple
    required: bool
    description: str
    strictly_increasing: bool = True


# The schema. Frames and units as in docs/CONVENTIONS.md; quaternions [w, x, y, z].
STREAMS = (
    StreamSpec(
        "imu",
        "t_s",
        (
            FieldSpec("t_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("accel_b_mps2", 3, "m/s^2", max_abs=bounds.MAX_ACCEL_MPS2),
            FieldSpec("omega_bi_b_rps", 3, "rad/s", max_abs=bounds.MAX_RATE_RPS),
        ),
        True,
        "IMU samples; each is the mean over the interval ending at t_s",
    ),
    StreamSpec(
        "pose",
        "t_capture_s",
        (
            FieldSpec("t_capture_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("t_delivered_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("r_hill_m", 3, "m", max_abs=bounds.MAX_POSITION_M),
            FieldSpec("q_hb", 4, "1", quaternion=True),
            FieldSpec(
                "r_sigma_m",
                None,
                "m",
                positive=True,
                min_value=bounds.POSE_R_SIGMA_M[0],
                max_abs=bounds.POSE_R_SIGMA_M[1],
            ),
            FieldSpec(
                "att_sigma_rad",
                None,
                "rad",
                positive=True,
                min_value=bounds.POSE_ATT_SIGMA_RAD[0],
                max_abs=bounds.POSE_ATT_SIGMA_RAD[1],
            ),
        ),
        True,
        "LED pose measurements: inspector position in the Hill frame and attitude body->Hill",
    ),
    StreamSpec(
        "valves",
        "t_s",
        (
            FieldSpec("t_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("on_time_s", PER_THRUSTER, "s", optional=True, nonnegative=True, max_abs=bounds.MAX_ON_TIME_S),
            FieldSpec("interval_s", None, "s", optional=True, nonnegative=True, max_abs=bounds.MAX_ON_TIME_S),
            FieldSpec("mask", None, "bit i = thruster i open", integer=True, optional=True, nonnegative=True),
        ),
        False,
        "valve commands: thruster i open from t_s for on_time_s[i] (pulse-width modulation), "
        "or every thruster in mask open from t_s for interval_s",
    ),
    StreamSpec(
        "estimate",
        "t_s",
        (
            FieldSpec("t_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("r_hill_m", 3, "m", max_abs=bounds.MAX_POSITION_M),
            FieldSpec("v_hill_mps", 3, "m/s", max_abs=bounds.MAX_VELOCITY_MPS),
            FieldSpec("q_hb", 4, "1", quaternion=True),
            FieldSpec("p_diag", 9, "SI^2 over [dr, dv, dtheta_body]"),
        ),
        False,
        "navigation telemetry after each predict",
    ),
    StreamSpec(
        "update",
        "t_s",
        (
            FieldSpec("t_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("status", None, "0 ok, 1 gated, 2 not positive definite, 3 bad input", integer=True),
            FieldSpec("fused", None, "0/1", integer=True),
            FieldSpec("innovation", 6, "[m, m, m, rad, rad, rad]"),
            FieldSpec("nis", None, "1"),
            FieldSpec("log_likelihood", None, "1"),
        ),
        False,
        "navigation pose-update records",
        strictly_increasing=False,
    ),
    StreamSpec(
        "truth",
        "t_s",
        (
            FieldSpec("t_s", None, "s", stamp=True, max_abs=bounds.MAX_STAMP_S),
            FieldSpec("r_hill_m", 3, "m", max_abs=bounds.MAX_POSITION_M),
            FieldSpec("v_hill_mps", 3, "m/s", max_abs=bounds.MAX_VELOCITY_MPS),
            FieldSpec("q_hb", 4, "1", quaternion=True),
            FieldSpec("omega_bi_b_rps", 3, "rad/s", max_abs=bounds.MAX_RATE_RPS),
        ),
        False,
        "truth, when the log comes from a simulation or has an external reference",
    ),
)
STREAM_BY_NAME = {s.name: s for s in STREAMS}

STATUS_CODES = {"ok": 0, "gated": 1, "not_pos_def": 2, "bad_input": 3}


class FlightLogError(ValueError):
    """A log that breaks the contract; the message names stream, field and row."""


@dataclass
class Problem:
    where: str  # "stream/field" or "/" for the file
    row: int | None
    what: str

    def __str__(self):
        row = f" row {self.row}" if self.row is not None else ""
        return f"{self.where}{row}: {self.what}"


@dataclass
class FlightLog:
    """In-memory form: streams[name][field] -> numpy array; config is a dict
    of JSON-serialisable values (orbit, vehicle, noise settings)."""

    streams: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    # Format version 2: the vehicle, IMU, pose sensor, orbit and segments
    # (bench/sim/log_description.py); None: everything at the bench's defaults.
    description: dict | None = None
    # The absolute time of the stamps' zero: relative_to_start moves every
    # stamp (and segment time) by it, so stamp + time_origin_s is the time
    # the log was written with.
    time_origin_s: float = 0.0

    def has(self, stream: str) -> bool:
        return stream in self.streams

    def __getitem__(self, stream: str) -> dict:
        return self.streams[stream]


def _check_stream(name: str, data: dict, n_thrusters: int | None = 8) -> list:
    """The stream's problems; ``n_thrusters`` None (the description is wrong)
    leaves out what depends on the thruster count."""
    spec = STREAM_BY_NAME[name]
    problems = []
    lengths = {}
    if not isinstance(data, dict):
        return [Problem(name, None, "expected a group of fields, not a single dataset")]
    for f in spec.fields:
        where = f"{name}/{f.name}"
        if f.name not in data:
            if not f.optional:
                problems.append(Problem(where, None, "missing field"))
            continue
        arr = np.asarray(data[f.name])
        if not np.issubdtype(arr.dtype, np.number):
            problems.append(Problem(where, None, f"not numeric (dtype {arr.dtype})"))
            continue
        if arr.dtype.kind not in "iuf":  # complex: its imaginary part would be dropped unseen
            problems.append(Problem(where, None, f"not real numbers (dtype {arr.dtype})"))
            continue
        width = n_thrusters if f.width == PER_THRUSTER else f.width
        if f.width == PER_THRUSTER and width is None:
            width = arr.shape[1] if arr.ndim == 2 else -1
        expected = (
            "(N,)"
            if width is None
            else f"(N, {width})" + (" (one column per thruster)" if f.width == PER_THRUSTER else "")
        )
        if (width is None and arr.ndim != 1) or (width is not None and (arr.ndim != 2 or arr.shape[1] != width)):
            problems.append(Problem(where, None, f"wrong shape {arr.shape}, expected {expected}"))
            continue
        lengths[f.name] = arr.shape[0]
        problems.extend(_check_values(where, f, arr))
    if name == "valves":
        problems.extend(_check_valve_form(data, n_thrusters))
    if len(set(lengths.values())) > 1:
        problems.append(
            Problem(name, None, "fields differ in length: " + ", ".join(f"{k}={v}" for k, v in lengths.items()))
        )
    t = data.get(spec.time_field)
    if t is not None and not any(p.where == f"{name}/{spec.time_field}" for p in problems):
        t = np.asarray(t)
        if t.ndim == 1 and t.size > 1:
            d = np.diff(t)
            bad = d <= 0 if spec.strictly_increasing else d < 0
            if np.any(bad):
                row = int(np.argmax(bad)) + 1
                problems.append(
                    Problem(
                        f"{name}/{spec.time_field}",
                        row,
                        f"time not increasing ({float(t[row - 1])!r} then {float(t[row])!r})",
                    )
                )
    return problems


def _check_values(where: str, f: FieldSpec, arr: np.ndarray) -> list:
    """The field's values: finite, within its bounds, and what its kind
    requires (unit quaternions, integers, positive or non-negative)."""
    problems = []
    finite = np.isfinite(arr) if f.width is None else np.all(np.isfinite(arr), axis=1)
    if not np.all(finite):
        row = int(np.argmin(finite))
        problems.append(Problem(where, row, f"not finite ({arr[row]})"))
        return problems
    big = np.abs(arr) > f.max_abs
    if np.any(big):
        row = int(np.argmax(big if arr.ndim == 1 else np.any(big, axis=1)))
        worst = float(np.max(np.abs(arr[row])))
        problems.append(Problem(where, row, f"beyond the bound of {f.max_abs:g} {f.unit} (|value| {worst:.6g})"))
        return problems
    if f.quaternion:
        norms = np.linalg.norm(arr, axis=1)
        bad = np.abs(norms - 1.0) > QUAT_NORM_TOL
        if np.any(bad):
            row = int(np.argmax(bad))
            problems.append(
                Problem(
                    where,
                    row,
                    f"quaternion [w, x, y, z] norm {norms[row]:.9g}, expected 1 within {QUAT_NORM_TOL:g}",
                )
            )
    if f.integer and np.any(arr != np.round(arr)):
        row = int(np.argmax(arr != np.round(arr)))
        problems.append(Problem(where, row, f"expected an integer, got {arr[row]}"))
    if f.positive and np.any(arr <= 0):
        row = int(np.argmax(arr <= 0))
        problems.append(Problem(where, row, f"not positive ({arr[row]})"))
    elif f.min_value is not None and np.any(arr < f.min_value):
        row = int(np.argmax(arr < f.min_value))
        problems.append(Problem(where, row, f"below the bound of {f.min_value:g} {f.unit} ({arr[row]})"))
    if f.nonnegative and np.any(arr < 0):
        row = int(np.argmax(arr < 0 if arr.ndim == 1 else np.any(arr < 0, axis=1)))
        problems.append(Problem(where, row, f"negative ({arr[row]})"))
    return problems


def _check_valve_form(data: dict, n_thrusters: int | None) -> list:
    """Exactly one of the two forms; a pulse ends before the next command
    (within VALVE_OVERLAP_TOL_S); a mask names only described thrusters."""
    has_on, has_mask = "on_time_s" in data, ("mask" in data or "interval_s" in data)
    if has_on and has_mask:
        return [Problem("valves", None, "give on_time_s or mask with interval_s, not both")]
    if not has_on and not has_mask:
        return [Problem("valves/on_time_s", None, "missing field (or give mask with interval_s)")]
    t = np.asarray(data.get("t_s", []))
    if t.ndim == 1 and t.size > 1 and np.issubdtype(t.dtype, np.number) and np.all(np.isfinite(t)):
        dur = np.asarray(data["on_time_s"] if has_on else data.get("interval_s", np.zeros(t.size)))
        if np.issubdtype(dur.dtype, np.number) and dur.shape[:1] == t.shape:
            longest = dur.reshape(t.size, -1).max(axis=1)
            over = longest[:-1] > np.diff(t) + VALVE_OVERLAP_TOL_S
            if np.any(over):
                row = int(np.argmax(over))
                field_ = "on_time_s" if has_on else "interval_s"
                return [
                    Problem(
                        f"valves/{field_}",
                        row,
                        f"pulse of {float(longest[row]):.6g} s runs past the next "
                        f"command ({float(np.diff(t)[row]):.6g} s later) by more than the "
                        f"{VALVE_OVERLAP_TOL_S * 1e3:g} ms allowed",
                    )
                ]
    if has_mask:
        missing = [k for k in ("mask", "interval_s") if k not in data]
        if missing:
            return [Problem(f"valves/{missing[0]}", None, "missing field (mask and interval_s go together)")]
        m = np.asarray(data["mask"])
        if n_thrusters is None:
            return []
        if np.issubdtype(m.dtype, np.number) and m.ndim == 1 and m.size and np.all(np.isfinite(m)):
            over = m.astype(np.int64) >> n_thrusters
            if np.any(over != 0):
                row = int(np.argmax(over != 0))
                return [
                    Problem("valves/mask", row, f"opens a thruster beyond the vehicle's {n_thrusters} ({int(m[row])})")
                ]
    return []


def validate_log(log: FlightLog) -> list:
    """Every contract violation in an in-memory log (empty list: valid). A
    wrong description is named alone for what depends on it (the valves'
    thruster count, the segments), so no knock-on problem follows it."""
    from bench.sim.log_description import DescriptionError, resolve

    problems = []
    desc = None
    try:
        desc = resolve(log.description, log.config)
    except DescriptionError as exc:
        problems.append(Problem("/description_json", None, str(exc)))
    n_thr = desc.n_thrusters if desc is not None else None
    for spec in STREAMS:
        if spec.name not in log.streams:
            if spec.required:
                problems.append(Problem(spec.name, None, "missing stream"))
            continue
        problems.extend(_check_stream(spec.name, log.streams[spec.name], n_thr))
    for spec in STREAMS:
        data = log.streams.get(spec.name)
        if spec.required and isinstance(data, dict) and spec.time_field in data and np.size(data[spec.time_field]) < 2:
            problems.append(
                Problem(
                    f"{spec.name}/{spec.time_field}",
                    None,
                    f"{np.size(data[spec.time_field])} samples (at least 2 needed)",
                )
            )
    for name in log.streams:
        if name not in STREAM_BY_NAME:
            problems.append(Problem(name, None, f"unknown stream (known: {', '.join(STREAM_BY_NAME)})"))
    if desc is not None and desc.imu_rate_hz is not None and not problems:
        problems.extend(_check_rate(log, desc.imu_rate_hz))
    if desc is not None and desc.segments and not problems:
        problems.extend(_check_segments(log, desc))
    return problems


def _check_rate(log: FlightLog, rate_hz: float) -> list:
    """A stated IMU rate whose averaging interval 1 / rate_hz is longer than
    twice the stamps' median spacing: each sample would mean over its
    neighbours' intervals too (and a null calibration flies that interval)."""
    t = np.asarray(log["imu"]["t_s"], np.float64)
    spacing = float(np.median(np.diff(t)))
    if 1.0 / rate_hz > 2.0 * spacing:
        return [
            Problem(
                "/description_json",
                None,
                f"imu.rate_hz: {rate_hz:g} Hz means each sample over {1.0 / rate_hz:.6g} s, more than twice "
                f"the IMU stamps' median spacing ({spacing:.6g} s)",
            )
        ]
    return []


def _check_segments(log: FlightLog, desc) -> list:
    """The first stated segment that holds no IMU sample or no pose capture
    (on the IMU clock): a run needs both (its first pose starts it)."""
    t = np.asarray(log["imu"]["t_s"], np.float64)
    tc = np.asarray(log["pose"]["t_capture_s"], np.float64) + desc.pose_time_offset_s - desc.pose_latency_s
    for i, sg in enumerate(desc.segments):
        span = f"{sg.t_start_s:.9g} to {sg.t_end_s:.9g} s"
        if not np.any((t >= sg.t_start_s) & (t <= sg.t_end_s + 1e-9)):
            return [
                Problem(
                    "/description_json",
                    None,
                    f"segments[{i}]: holds no IMU sample ({span}, the IMU stamps run from {t[0]:.9g} to {t[-1]:.9g} s)",
                )
            ]
        if not np.any((tc >= sg.t_start_s) & (tc <= sg.t_end_s + 1e-9)):
            return [
                Problem(
                    "/description_json",
                    None,
                    f"segments[{i}]: holds no pose capture ({span}, the captures on the IMU clock run from "
                    f"{tc[0]:.9g} to {tc[-1]:.9g} s): a run starts at its first pose",
                )
            ]
    return []


def time_origin(log: FlightLog) -> float:
    """The log's own zero: its earliest IMU stamp rounded down to a whole
    second (0 when the IMU stamps are missing or unreadable: the validator
    names them). Subtracting a whole number of seconds is exact in float64,
    so every stamp keeps its fractional part as it was stored."""
    imu = log.streams.get("imu")
    t = imu.get("t_s") if isinstance(imu, dict) else None
    a = np.asarray(t) if t is not None else np.zeros(0)
    if a.ndim != 1 or not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        return 0.0
    a = a[np.isfinite(a)]
    return float(np.floor(np.min(a))) if a.size else 0.0


def relative_to_start(log: FlightLog) -> FlightLog:
    """The log with every time stamp of every stream and the description's
    segment times measured from its time_origin (kept in ``time_origin_s``):
    a log on a Unix epoch and the same log from zero read alike. The log
    itself is not changed."""
    origin = time_origin(log)
    if origin == 0.0:
        return log
    streams = {}
    for name, data in log.streams.items():
        spec = STREAM_BY_NAME.get(name)
        if spec is not None and isinstance(data, dict):
            data = dict(data)
            for f in spec.fields:
                a = np.asarray(data.get(f.name, np.zeros(0)))
                if (
                    f.stamp
                    and f.name in data
                    and (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating))
                ):
                    data[f.name] = a.astype(np.float64) - origin
        streams[name] = data
    description = copy.deepcopy(log.description)
    segs = description.get("segments") if isinstance(description, dict) else None
    for sg in segs if isinstance(segs, list) else []:
        for key in ("t_start_s", "t_end_s") if isinstance(sg, dict) else ():
            v = sg.get(key)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                sg[key] = float(v) - origin
    return FlightLog(streams, copy.deepcopy(log.config), description, log.time_origin_s + origin)


def valve_on_times(valves: dict, n_thrusters: int) -> tuple:
    """(t (N,), on (N, K), clipped) of a valves stream in either form: each
    command's open time per thruster, every pulse ended at the next command
    at the latest. ``clipped`` counts the pulses that ran past it by more
    than STAMP_ROUNDING_S (the validator refuses more than
    VALVE_OVERLAP_TOL_S)."""
    t = np.asarray(valves["t_s"], np.float64)
    if "on_time_s" in valves:
        on = np.array(valves["on_time_s"], dtype=np.float64).reshape(t.size, -1)
    else:
        mask = np.asarray(valves["mask"]).astype(np.int64)
        bits = (mask[:, None] >> np.arange(n_thrusters)[None, :]) & 1
        on = bits * np.asarray(valves["interval_s"], np.float64)[:, None]
    room = np.diff(t)[:, None]
    clipped = int(np.sum(on[:-1] > room + STAMP_ROUNDING_S))
    on[:-1] = np.minimum(on[:-1], room)
    return t, on, clipped


def write_flight_log(path, log: FlightLog, validate: bool = True) -> Path:
    """Write ``log`` as HDF5. Refuses (FlightLogError) to write an invalid log."""
    import h5py

    if validate:
        problems = validate_log(log)
        if problems:
            raise FlightLogError("; ".join(str(p) for p in problems[:5]))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as h:
        h.attrs["format"] = FORMAT_NAME
        h.attrs["format_version"] = FORMAT_VERSION
        h.attrs["quaternion_order"] = "wxyz"
        h.attrs["frame"] = "hill: x radial, y along-track, z orbit normal"
        h.attrs["config_json"] = json.dumps(log.config, sort_keys=True)
        if log.description is not None:
            h.attrs["description_json"] = json.dumps(_plain(log.description), sort_keys=True)
        for name, data in log.streams.items():
            g = h.create_group(name)
            spec = STREAM_BY_NAME.get(name)
            units = {f.name: f.unit for f in spec.fields} if spec else {}
            for key, arr in data.items():
                ds = g.create_dataset(key, data=np.asarray(arr), compression="gzip", compression_opts=4, shuffle=True)
                if key in units:
                    ds.attrs["unit"] = units[key]
            if spec is not None:
                flight_log_dims.label(g, spec)
    return path


def _plain(x):
    """numpy values to JSON-ready Python."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) > bounds.MAX_JSON_INT_DIGITS:
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits (at most {bounds.MAX_JSON_INT_DIGITS})")
    return int(text)


def _json_depth(val) -> int:
    """How deeply ``val``'s objects and lists nest (iteratively: no recursion to exhaust)."""
    deepest, todo = 0, [(val, 1)]
    while todo:
        v, depth = todo.pop()
        if isinstance(v, (dict, list)):
            deepest = max(deepest, depth)
            if deepest > bounds.MAX_JSON_DEPTH:
                return deepest
            todo.extend((x, depth + 1) for x in (v.values() if isinstance(v, dict) else v))
    return deepest


def _json_attr(h, name: str, path) -> dict:
    raw = h.attrs.get(name, "{}")
    if isinstance(raw, np.ndarray) and raw.shape == ():
        raw = raw[()]
    if isinstance(raw, (bytes, np.bytes_)):
        try:
            raw = bytes(raw).decode()
        except UnicodeDecodeError:
            raise FlightLogError(f"{path}: /{name}: not UTF-8 text") from None
    if not isinstance(raw, str):
        raise FlightLogError(f"{path}: /{name}: expected JSON text, got {type(raw).__name__}")
    if len(raw) > bounds.MAX_JSON_BYTES:
        raise FlightLogError(f"{path}: /{name}: {len(raw)} characters, more than {bounds.MAX_JSON_BYTES}")
    try:
        val = json.loads(raw, parse_int=_json_int)
    except RecursionError:
        raise FlightLogError(f"{path}: /{name}: nested deeper than {bounds.MAX_JSON_DEPTH} levels") from None
    except (TypeError, ValueError) as exc:
        raise FlightLogError(f"{path}: /{name}: not valid JSON ({str(exc)[:120]})") from None
    if not isinstance(val, dict):
        raise FlightLogError(f"{path}: /{name}: expected a JSON object, got {type(val).__name__}")
    if _json_depth(val) > bounds.MAX_JSON_DEPTH:
        raise FlightLogError(f"{path}: /{name}: nested deeper than {bounds.MAX_JSON_DEPTH} levels")
    return val


def _format_version(raw, path) -> int:
    """The file's format_version: a whole number (2.7 or "2" is no version of this format)."""
    if isinstance(raw, np.ndarray) and raw.shape == ():
        raw = raw[()]
    ok = isinstance(raw, (int, np.integer)) and not isinstance(raw, (bool, np.bool_))
    if isinstance(raw, (float, np.floating)) and math.isfinite(raw) and float(raw).is_integer():
        ok = abs(raw) < 2**31
    if not ok:
        raw = raw.item() if isinstance(raw, np.generic) else raw
        text = repr(raw) if len(repr(raw)) <= 40 else repr(raw)[:37] + "..."
        raise FlightLogError(
            f"{path}: /format_version: {text} is not an integer (this reader: {', '.join(map(str, READ_VERSIONS))})"
        )
    return int(raw)


def _plain_member(h5, group, name: str, where: str, path):
    """``group[name]`` when it is an object stored in this file under a hard
    link: a soft link (dangling or cyclic) or an external link is refused,
    never followed."""
    link = group.get(name, getlink=True)
    if not isinstance(link, h5.HardLink):
        kind = "an external link" if isinstance(link, h5.ExternalLink) else "a soft link"
        raise FlightLogError(f"{path}: {where}: {kind}, not data stored in the file (links are not followed)")
    return group[name]


def _checked_field(h5, ds, where: str, path, budget: list):
    """``ds`` once its kind and size, from the file's metadata, are within
    the bounds; ``budget``: [bytes the whole log may still take]."""
    if not isinstance(ds, h5.Dataset):
        raise FlightLogError(f"{path}: {where}: a group inside a stream, expected a dataset")
    if ds.is_virtual or ds.external:
        raise FlightLogError(f"{path}: {where}: data stored in another file (not read)")
    shape = ds.shape
    if shape is None or len(shape) > 2:
        raise FlightLogError(f"{path}: {where}: shape {shape}, expected (N,) or (N, K)")
    rows = shape[0] if shape else 1
    cols = shape[1] if len(shape) == 2 else 1
    if rows > bounds.MAX_ROWS or cols > bounds.MAX_COLUMNS:
        raise FlightLogError(
            f"{path}: {where}: shape {shape}, more than {bounds.MAX_ROWS} rows or {bounds.MAX_COLUMNS} columns"
        )
    size = rows * cols * ds.dtype.itemsize
    if ds.dtype.kind == "O" or size > bounds.MAX_DATASET_BYTES:
        raise FlightLogError(f"{path}: {where}: dtype {ds.dtype} of shape {shape}: not a numeric field of this format")
    if size > budget[0]:
        raise FlightLogError(f"{path}: {where}: the log's fields exceed {bounds.MAX_LOG_BYTES >> 30} GiB together")
    budget[0] -= size
    return ds


def _read_field(ds, where: str, path) -> np.ndarray:
    try:
        return np.asarray(ds[()])
    except (OSError, RuntimeError, ValueError, TypeError) as exc:
        raise FlightLogError(f"{path}: {where}: unreadable ({str(exc)[:120]})") from None


def read_flight_log(path, validate: bool = True, relative_time: bool = False) -> FlightLog:
    """Read and (by default) validate a log; FlightLogError names what is
    wrong. ``relative_time``: every stamp from the log's own origin
    (relative_to_start) before it is validated, as the diagnosis reads it."""
    import h5py

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"flight log not found: {path}")
    try:
        h = h5py.File(path, "r")
    except OSError as exc:
        raise FlightLogError(f"{path}: not an HDF5 file ({exc})") from None
    with h:
        fmt = h.attrs.get("format")
        if isinstance(fmt, bytes):
            fmt = fmt.decode()
        if fmt != FORMAT_NAME:
            raise FlightLogError(f"/: attribute 'format' is {fmt!r}, expected {FORMAT_NAME!r}")
        version = _format_version(h.attrs.get("format_version", None), path)
        if version not in READ_VERSIONS:
            raise FlightLogError(
                f"{path}: /format_version: {version} not supported (this reader: {', '.join(map(str, READ_VERSIONS))})"
            )
        config = _json_attr(h, "config_json", path)
        description = _json_attr(h, "description_json", path) if version >= 2 else None
        if version < 2 and "description_json" in h.attrs:
            raise FlightLogError(f"{path}: /description_json: needs format_version 2")
        streams = _read_streams(h5py, h, path)
    log = FlightLog(streams=streams, config=config, description=description)
    if relative_time:
        log = relative_to_start(log)
    if validate:
        problems = validate_log(log)
        if problems:
            origin = f" (times from {log.time_origin_s:.0f} s, the log's first IMU second)" if log.time_origin_s else ""
            raise FlightLogError(f"{path}: " + "; ".join(str(p) for p in problems[:5]) + origin)
    return log


def _read_streams(h5, h, path) -> dict:
    """{stream: {field: array}}: each stream a group of datasets stored in
    the file, each within the size bounds (flight_log_bounds)."""
    names = list(h.keys())
    if len(names) > bounds.MAX_MEMBERS:
        raise FlightLogError(f"{path}: /: {len(names)} streams, more than {bounds.MAX_MEMBERS}")
    found, budget = {}, [bounds.MAX_LOG_BYTES]
    for name in names:
        g = _plain_member(h5, h, name, name, path)
        if not isinstance(g, h5.Group):
            raise FlightLogError(f"{path}: {name}: expected a group of fields, not a single dataset")
        fields = list(g.keys())
        if len(fields) > bounds.MAX_MEMBERS:
            raise FlightLogError(f"{path}: {name}: {len(fields)} fields, more than {bounds.MAX_MEMBERS}")
        members = {k: _plain_member(h5, g, k, f"{name}/{k}", path) for k in fields}
        found[name] = {
            k: _checked_field(h5, ds, f"{name}/{k}", path, budget)
            for k, ds in members.items()
            if not (isinstance(ds, h5.Dataset) and flight_log_dims.is_dimension(ds, k))
        }
    # Read only once every field's size is known to fit.
    return {
        name: {k: _read_field(ds, f"{name}/{k}", path) for k, ds in fields.items()} for name, fields in found.items()
    }


def _run_streams(run, offset: float) -> dict:
    """One run's streams in the log's layout, its time tags moved by ``offset``."""
    t = run.t + offset
    u = run.updates
    return {
        "imu": {"t_s": run.imu_t + offset, "accel_b_mps2": run.imu_accel, "omega_bi_b_rps": run.imu_gyro},
        "pose": {
            "t_capture_s": u.t_capture + offset,
            "t_delivered_s": u.t_fused + offset,
            "r_hill_m": u.r_meas,
            "q_hb": u.q_meas,
            "r_sigma_m": u.r_sigma,
            "att_sigma_rad": u.att_sigma,
        },
        "estimate": {
            "t_s": t,
            "r_hill_m": run.est[:, 0:3],
            "v_hill_mps": run.est[:, 3:6],
            "q_hb": run.est[:, 6:10],
            "p_diag": np.array([np.diag(P) for P in run.P]),
        },
        "update": {
            "t_s": u.t_fused + offset,
            "status": np.array([STATUS_CODES[s] for s in u.status], dtype=int),
            "fused": np.asarray(u.fused, dtype=int),
            "innovation": np.asarray(u.innovation).reshape(-1, 6),
            "nis": u.nis,
            "log_likelihood": u.loglik,
        },
        "truth": {
            "t_s": t,
            "r_hill_m": run.r_true,
            "v_hill_mps": run.v_true,
            "q_hb": run.q_true,
            "omega_bi_b_rps": run.w_true,
        },
    }


def runs_to_flight_log(runs, config: dict) -> FlightLog:
    """One flight log over chained runs (time tags run on from run to run)."""
    if not runs:
        raise ValueError("a flight log needs at least one run")
    per_run, offset = [], 0.0
    for run in runs:
        per_run.append(_run_streams(run, offset))
        # The first record of each run is its initial state (same time as the
        # previous run's end + offset): keep the time strictly increasing.
        offset = run.t[-1] + offset + 0.1
    streams = {
        name: {field: np.concatenate([r[name][field] for r in per_run]) for field in fields}
        for name, fields in per_run[0].items()
    }
    return FlightLog(streams=streams, config=config)
