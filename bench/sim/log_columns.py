"""A flight log's streams as flat tables, one named column per number, each
with its unit: what `proxops export` writes as CSV, Parquet and MCAP.

A stream's time field is its first column, under its own name (`t_s`,
`t_capture_s`). A vector field becomes one column per component, named
after the field and the component (`accel_b_mps2_x`, `q_hb_w`,
`innovation_att_x`, `p_diag_v_y`, `on_time_s_3` for thruster 3), so a
column reads alone in any tool; the names follow the components of the
log's own dimensions (bench/sim/flight_log_dims.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.sim.flight_log import PER_THRUSTER, STREAM_BY_NAME, FlightLog

_XYZ = ("x", "y", "z")
COMPONENTS = {
    3: _XYZ,
    4: ("w", "x", "y", "z"),
    6: tuple(f"{b}_{a}" for b in ("r", "att") for a in _XYZ),
    9: tuple(f"{b}_{a}" for b in ("r", "v", "att") for a in _XYZ),
}
# Fields whose components differ in unit (the format states them in words).
COMPONENT_UNITS = {
    "innovation": ("m",) * 3 + ("rad",) * 3,
    "p_diag": ("m^2",) * 3 + ("(m/s)^2",) * 3 + ("rad^2",) * 3,
}


@dataclass(frozen=True)
class Column:
    name: str
    values: np.ndarray  # (N,), float64 or int64
    unit: str
    integer: bool


@dataclass(frozen=True)
class StreamTable:
    stream: str
    time_column: str
    description: str
    columns: tuple  # Column, the time column first

    @property
    def rows(self) -> int:
        return int(self.columns[0].values.size)


def _field_columns(spec_field, arr: np.ndarray) -> list:
    arr = np.asarray(arr)
    arr = arr.astype(np.int64) if spec_field.integer else arr.astype(np.float64)
    if arr.ndim == 1:
        return [Column(spec_field.name, arr, spec_field.unit, spec_field.integer)]
    width = arr.shape[1]
    names = tuple(map(str, range(width))) if spec_field.width == PER_THRUSTER else COMPONENTS.get(width)
    names = names or tuple(map(str, range(width)))
    units = COMPONENT_UNITS.get(spec_field.name, (spec_field.unit,) * width)
    return [
        Column(f"{spec_field.name}_{c}", np.ascontiguousarray(arr[:, i]), units[i], spec_field.integer)
        for i, c in enumerate(names)
    ]


def stream_table(log: FlightLog, stream: str) -> StreamTable:
    """One stream of a read (validated) log as a table; fields the format
    does not define are not in a valid log, so every field has a unit."""
    spec = STREAM_BY_NAME[stream]
    data = log[stream]
    order = [spec.time_field] + [f.name for f in spec.fields if f.name != spec.time_field]
    by_name = {f.name: f for f in spec.fields}
    columns = []
    for name in order:
        if name in data:
            columns += _field_columns(by_name[name], data[name])
    return StreamTable(stream, spec.time_field, spec.description, tuple(columns))


def stream_tables(log: FlightLog) -> list:
    """Every stream of ``log``, in the format's order."""
    return [stream_table(log, s) for s in STREAM_BY_NAME if log.has(s)]
