"""Named dimensions and CF units in a flight log's HDF5 file, so xarray
(``xarray.open_dataset(log, group="imu", engine="h5netcdf")``) and other
netCDF-4 readers open each stream as a tidy dataset: the stream's time
field is its time coordinate, a vector's columns a named dimension, and
every field with a unit carries the CF ``units`` attribute.

The dimensions are HDF5 dimension scales: the time field is one (it stays
a field of the format), the column dimensions are extra datasets whose
names are listed here; the flight-log reader leaves them out."""

from __future__ import annotations

import numpy as np

# Column dimensions by the field's width (PER_THRUSTER: "thruster").
COLUMN_DIMS = {3: "axis", 4: "quaternion", 6: "innovation_row", 9: "covariance_row"}
THRUSTER_DIM = "thruster"
DIM_NAMES = frozenset(COLUMN_DIMS.values()) | {THRUSTER_DIM}
LONG_NAMES = {
    "axis": "vector component: 0 x, 1 y, 2 z",
    "quaternion": "quaternion component: 0 w, 1 x, 2 y, 3 z",
    "innovation_row": "pose innovation row: position x, y, z [m], then attitude x, y, z [rad]",
    "covariance_row": "covariance diagonal row: position [m^2], velocity [(m/s)^2], attitude [rad^2], x y z each",
    THRUSTER_DIM: "thruster index (bit i of the valve mask)",
}
# Units a CF reader (udunits) understands; any other unit text is a comment.
CF_UNITS = frozenset({"s", "m", "m/s", "m/s^2", "rad", "rad/s", "1"})


def _column_dim(g, width: int, per_thruster: bool):
    name = THRUSTER_DIM if per_thruster else COLUMN_DIMS.get(width, f"column_{width}")
    if name not in g:
        ds = g.create_dataset(name, data=np.arange(width, dtype=np.int32))
        ds.make_scale(name)
        ds.attrs["long_name"] = LONG_NAMES.get(name, f"{name} index")
    return g[name]


def label(g, spec) -> None:
    """Attaches the time scale and column dimensions to every field of the
    group ``g`` written from stream ``spec`` (a StreamSpec), with units."""
    fields = {f.name: f for f in spec.fields}
    t = g.get(spec.time_field)
    t = t if t is not None and t.ndim == 1 else None  # an invalid log (validate=False) is written as it is
    if t is not None:
        t.make_scale(spec.time_field)
        t.attrs["standard_name"] = "time"
        t.attrs["axis"] = "T"
    for key in list(g.keys()):
        ds, f = g[key], fields.get(key)
        if f is None or key in DIM_NAMES:
            continue
        if f.unit in CF_UNITS:
            ds.attrs["units"] = f.unit
        else:
            ds.attrs["comment"] = f.unit
        if t is not None and key != spec.time_field and ds.ndim >= 1 and ds.shape[0] == t.shape[0]:
            ds.dims[0].attach_scale(t)
        if ds.ndim == 2:
            per_thruster = f.width is not None and f.width < 0  # flight_log.PER_THRUSTER
            ds.dims[1].attach_scale(_column_dim(g, ds.shape[1], per_thruster))


def is_dimension(ds, key: str) -> bool:
    """Whether ``ds`` (named ``key`` in its stream) is a column dimension
    written by ``label``, not a field."""
    return key in DIM_NAMES and ds.is_scale
