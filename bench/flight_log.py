"""The flight log: a versioned HDF5 file that the bench, the HIL recorder and
a user with real data can all write, and that everything downstream reads.

The contract is docs/FLIGHT_LOG.md; this module is its executable form. A
user can write a log with plain h5py by following that page; ``validate``
names the stream, the field, the row and what is wrong.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import json

import numpy as np

FORMAT_NAME = "proxops-flight-log"
FORMAT_VERSION = 1
QUAT_NORM_TOL = 1e-6


@dataclass(frozen=True)
class FieldSpec:
    name: str
    width: int | None  # None: one value per row; k: k values per row
    unit: str
    quaternion: bool = False
    integer: bool = False


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
    StreamSpec("imu", "t_s", (
        FieldSpec("t_s", None, "s"),
        FieldSpec("accel_b_mps2", 3, "m/s^2"),
        FieldSpec("omega_bi_b_rps", 3, "rad/s"),
    ), True, "IMU samples; each is the mean over the interval ending at t_s"),
    StreamSpec("pose", "t_capture_s", (
        FieldSpec("t_capture_s", None, "s"),
        FieldSpec("t_delivered_s", None, "s"),
        FieldSpec("r_hill_m", 3, "m"),
        FieldSpec("q_hb", 4, "1", quaternion=True),
        FieldSpec("r_sigma_m", None, "m"),
        FieldSpec("att_sigma_rad", None, "rad"),
    ), True, "LED pose measurements: inspector position in the Hill frame and attitude body->Hill"),
    StreamSpec("valves", "t_s", (
        FieldSpec("t_s", None, "s"),
        FieldSpec("interval_s", None, "s"),
        FieldSpec("mask", None, "bit i = thruster i open", integer=True),
    ), False, "thruster valve states held from t_s for interval_s"),
    StreamSpec("estimate", "t_s", (
        FieldSpec("t_s", None, "s"),
        FieldSpec("r_hill_m", 3, "m"),
        FieldSpec("v_hill_mps", 3, "m/s"),
        FieldSpec("q_hb", 4, "1", quaternion=True),
        FieldSpec("p_diag", 9, "SI^2 over [dr, dv, dtheta_body]"),
    ), False, "navigation telemetry after each predict"),
    StreamSpec("update", "t_s", (
        FieldSpec("t_s", None, "s"),
        FieldSpec("status", None, "0 ok, 1 gated, 2 not positive definite, 3 bad input", integer=True),
        FieldSpec("fused", None, "0/1", integer=True),
        FieldSpec("innovation", 6, "[m, m, m, rad, rad, rad]"),
        FieldSpec("nis", None, "1"),
        FieldSpec("log_likelihood", None, "1"),
    ), False, "navigation pose-update records", strictly_increasing=False),
    StreamSpec("truth", "t_s", (
        FieldSpec("t_s", None, "s"),
        FieldSpec("r_hill_m", 3, "m"),
        FieldSpec("v_hill_mps", 3, "m/s"),
        FieldSpec("q_hb", 4, "1", quaternion=True),
        FieldSpec("omega_bi_b_rps", 3, "rad/s"),
    ), False, "truth, when the log comes from a simulation or has an external reference"),
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

    def has(self, stream: str) -> bool:
        return stream in self.streams

    def __getitem__(self, stream: str) -> dict:
        return self.streams[stream]


def _check_stream(name: str, data: dict) -> list:
    spec = STREAM_BY_NAME[name]
    problems = []
    lengths = {}
    for f in spec.fields:
        where = f"{name}/{f.name}"
        if f.name not in data:
            problems.append(Problem(where, None, "missing field"))
            continue
        arr = np.asarray(data[f.name])
        if not np.issubdtype(arr.dtype, np.number):
            problems.append(Problem(where, None, f"not numeric (dtype {arr.dtype})"))
            continue
        expected = "(N,)" if f.width is None else f"(N, {f.width})"
        if (f.width is None and arr.ndim != 1) or (f.width is not None and (arr.ndim != 2 or arr.shape[1] != f.width)):
            problems.append(Problem(where, None, f"wrong shape {arr.shape}, expected {expected}"))
            continue
        lengths[f.name] = arr.shape[0]
        finite = np.isfinite(arr) if f.width is None else np.all(np.isfinite(arr), axis=1)
        if not np.all(finite):
            row = int(np.argmin(finite))
            problems.append(Problem(where, row, f"not finite ({arr[row]})"))
            continue
        if f.quaternion:
            norms = np.linalg.norm(arr, axis=1)
            bad = np.abs(norms - 1.0) > QUAT_NORM_TOL
            if np.any(bad):
                row = int(np.argmax(bad))
                problems.append(Problem(where, row, f"quaternion [w, x, y, z] norm {norms[row]:.9g}, expected 1 within {QUAT_NORM_TOL:g}"))
        if f.integer and np.any(arr != np.round(arr)):
            row = int(np.argmax(arr != np.round(arr)))
            problems.append(Problem(where, row, f"expected an integer, got {arr[row]}"))
    if len(set(lengths.values())) > 1:
        problems.append(Problem(name, None, "fields differ in length: " + ", ".join(f"{k}={v}" for k, v in lengths.items())))
    t = data.get(spec.time_field)
    if t is not None and not any(p.where == f"{name}/{spec.time_field}" for p in problems):
        t = np.asarray(t)
        if t.ndim == 1 and t.size > 1:
            d = np.diff(t)
            bad = d <= 0 if spec.strictly_increasing else d < 0
            if np.any(bad):
                row = int(np.argmax(bad)) + 1
                problems.append(Problem(f"{name}/{spec.time_field}", row,
                                        f"time not increasing ({t[row - 1]!r} then {t[row]!r})"))
    return problems


def validate_log(log: FlightLog) -> list:
    """Every contract violation in an in-memory log (empty list: valid)."""
    problems = []
    for spec in STREAMS:
        if spec.name not in log.streams:
            if spec.required:
                problems.append(Problem(spec.name, None, "missing stream"))
            continue
        problems.extend(_check_stream(spec.name, log.streams[spec.name]))
    for name in log.streams:
        if name not in STREAM_BY_NAME:
            problems.append(Problem(name, None, f"unknown stream (known: {', '.join(STREAM_BY_NAME)})"))
    return problems


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
        for name, data in log.streams.items():
            g = h.create_group(name)
            spec = STREAM_BY_NAME.get(name)
            units = {f.name: f.unit for f in spec.fields} if spec else {}
            for key, arr in data.items():
                ds = g.create_dataset(key, data=np.asarray(arr), compression="gzip", compression_opts=4, shuffle=True)
                if key in units:
                    ds.attrs["unit"] = units[key]
    return path


def read_flight_log(path, validate: bool = True) -> FlightLog:
    """Read and (by default) validate a log; FlightLogError names what is wrong."""
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
        version = int(h.attrs.get("format_version", -1))
        if version != FORMAT_VERSION:
            raise FlightLogError(f"/: format_version {version} not supported (this reader: {FORMAT_VERSION})")
        config = json.loads(h.attrs.get("config_json", "{}"))
        streams = {name: {k: np.asarray(ds[()]) for k, ds in g.items()} for name, g in h.items()}
    log = FlightLog(streams=streams, config=config)
    if validate:
        problems = validate_log(log)
        if problems:
            raise FlightLogError(f"{path}: " + "; ".join(str(p) for p in problems[:5]))
    return log
