"""Small helpers shared by commands: JSON output and report folders."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np


def _default(o):
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def strict_json_data(data):
    """data with every NaN or infinite float replaced by None, and, when
    there were any, a key "non_finite_as_null" mapping each such field's
    path (e.g. "runs.0.nis") to the value it had ("nan", "inf", "-inf"):
    the result is strict JSON (no bare NaN or Infinity)."""
    found = {}

    def walk(x, path):
        if isinstance(x, np.ndarray):
            x = x.tolist()
        if isinstance(x, (float, np.floating)):
            if not math.isfinite(x):
                found[path] = "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
                return None
            return float(x)
        if isinstance(x, dict):
            return {k: walk(v, f"{path}.{k}" if path else str(k)) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [walk(v, f"{path}.{i}" if path else str(i)) for i, v in enumerate(x)]
        return x

    out = walk(data, "")
    if found and isinstance(out, dict):
        out["non_finite_as_null"] = found
    return out


def json_text(data, strict: bool = False) -> str:
    if strict:
        return json.dumps(strict_json_data(data), indent=2, default=_default, allow_nan=False) + "\n"
    return json.dumps(data, indent=2, default=_default) + "\n"


def write_json(path, data, strict: bool = False) -> Path:
    """Writes data as JSON to path, atomically: the text goes to a temporary
    file in the same folder, which replaces path only once it is complete
    (an error part-way leaves an existing file as it was). strict: no bare
    NaN or Infinity (strict_json_data)."""
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    text = json_text(data, strict)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


@contextlib.contextmanager
def atomic_path(path):
    """A temporary file name next to path; when the block ends without an
    error the file replaces path, otherwise it is removed."""
    path = Path(path)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


@contextlib.contextmanager
def staged_report_dir(path):
    """A temporary folder next to the report folder path; when the block
    ends without an error each file in it replaces its namesake in path
    (created if needed), otherwise nothing in path changes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}."))
    try:
        yield tmp
        path.mkdir(parents=True, exist_ok=True)
        for f in sorted(tmp.iterdir()):
            os.replace(f, path / f.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def report_dir(path) -> Path:
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


def matplotlib_agg():
    """matplotlib with the non-interactive backend (no screen here)."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def restore_non_finite(data):
    """The inverse of strict_json_data on loaded JSON: each field listed
    under "non_finite_as_null" gets its NaN or infinity back."""
    found = data.pop("non_finite_as_null", None) if isinstance(data, dict) else None
    for path, what in (found or {}).items():
        keys = path.split(".")
        node = data
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        last = keys[-1]
        value = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}[what]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return data
