"""Run results as JSON that reads back bit for bit.

Floats are written with their shortest exact representation (NaN and
infinities as JSON's NaN / Infinity), numpy arrays as their raw bytes in
base64 with dtype and shape, numpy scalars as Python numbers, dataclasses
as dicts, dicts with keys other than strings as key-value pairs, tuples as
lists. A result is passed through ``roundtrip`` whether it was just computed
or read from the store, so a summary sees the same values either way.
"""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import json

import numpy as np

ARRAY = "__ndarray__"
ITEMS = "__dict_items__"  # a dict whose keys are not all strings, as [key, value] pairs


def _prepare(o):
    """Dicts with keys other than strings kept as pairs (JSON would turn
    their keys into strings)."""
    if isinstance(o, dict):
        if all(isinstance(k, str) for k in o):
            return {k: _prepare(v) for k, v in o.items()}
        return {ITEMS: [[_prepare(k), _prepare(v)] for k, v in o.items()]}
    if isinstance(o, (list, tuple)):
        return [_prepare(v) for v in o]
    if dataclasses.is_dataclass(o) and not isinstance(o, type):
        return _prepare({f.name: getattr(o, f.name) for f in dataclasses.fields(o)})
    return o


def _encode(o):
    if isinstance(o, np.ndarray):
        if o.dtype.kind in "biufc":
            a = np.ascontiguousarray(o)
            return {ARRAY: base64.b64encode(a.tobytes()).decode("ascii"), "dtype": a.dtype.str, "shape": list(a.shape)}
        return {ARRAY: o.tolist(), "dtype": o.dtype.str if o.dtype.kind != "O" else "object", "shape": list(o.shape)}
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if dataclasses.is_dataclass(o) and not isinstance(o, type):
        return {f.name: getattr(o, f.name) for f in dataclasses.fields(o)}
    if isinstance(o, (set, frozenset)):
        return sorted(o)
    raise TypeError(f"cannot store a {type(o).__name__} in a run record")


def _decode(d: dict):
    if ITEMS in d and len(d) == 1:
        return {(tuple(k) if isinstance(k, list) else k): v for k, v in d[ITEMS]}
    if ARRAY not in d:
        return d
    data, dtype, shape = d[ARRAY], d["dtype"], tuple(d["shape"])
    if isinstance(data, str):
        return np.frombuffer(base64.b64decode(data), dtype=np.dtype(dtype)).reshape(shape).copy()
    return np.array(data, dtype=object if dtype == "object" else np.dtype(dtype)).reshape(shape)


def dumps(obj, indent=None) -> str:
    return json.dumps(_prepare(obj), default=_encode, indent=indent, allow_nan=True)


def loads(text: str):
    return json.loads(text, object_hook=_decode)


def roundtrip(obj):
    """``obj`` as the store gives it back."""
    return loads(dumps(obj))


def sha256(obj) -> str:
    """The SHA-256 of ``obj``'s canonical JSON (keys sorted)."""
    return hashlib.sha256(
        json.dumps(_prepare(obj), default=_encode, sort_keys=True, allow_nan=True).encode()
    ).hexdigest()
