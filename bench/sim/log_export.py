"""A flight log's streams (bench/sim/log_columns.py) written for the tools a
team already has, docs/FLIGHT_LOG.md, "Export":

- csv: a folder, `<stream>.csv` per stream (header of column names, the
  time column first) and `units.csv` (stream, column, unit);
- parquet: a folder, `<stream>.parquet` per stream, each column's unit in
  its field metadata (`unit`), the stream's time column in the schema's;
- mcap: one file, a channel `/<stream>` per stream, each row a JSON message
  with a JSON schema per stream, log time the row's stamp in ns.

Each format is written beside its destination and moved there when
complete, so a failed export leaves no partial output."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

FORMATS = ("csv", "parquet", "mcap")
UNITS_FILE = "units.csv"
MCAP_PROFILE = ""  # plain JSON messages: no ROS profile
NS_PER_S = 1_000_000_000


def _arrow_table(table):
    import pyarrow as pa

    fields = [
        pa.field(c.name, pa.int64() if c.integer else pa.float64(), nullable=False, metadata={"unit": c.unit})
        for c in table.columns
    ]
    meta = {"stream": table.stream, "time_column": table.time_column, "description": table.description}
    return pa.Table.from_arrays([c.values for c in table.columns], schema=pa.schema(fields, metadata=meta))


def _write_csv(tables, folder: Path) -> None:
    import pyarrow.csv as pcsv

    # The header written here, unquoted (pyarrow quotes names); every
    # column name is a plain identifier, and the values are numbers.
    opts = pcsv.WriteOptions(include_header=False, quoting_style="none")
    units = ["stream,column,unit"]
    for t in tables:
        with open(folder / f"{t.stream}.csv", "wb") as f:
            f.write((",".join(c.name for c in t.columns) + "\n").encode())
            pcsv.write_csv(_arrow_table(t), f, write_options=opts)
        units += [f"{t.stream},{c.name},{_csv_text(c.unit)}" for c in t.columns]
    (folder / UNITS_FILE).write_text("\n".join(units) + "\n")


def _csv_text(text: str) -> str:
    return '"' + text.replace('"', '""') + '"' if any(ch in text for ch in ',"\n') else text


def _write_parquet(tables, folder: Path) -> None:
    import pyarrow.parquet as pq

    for t in tables:
        pq.write_table(_arrow_table(t), folder / f"{t.stream}.parquet")


def stamps_ns(t: np.ndarray, where: str) -> np.ndarray:
    """Stamps in seconds (float64) as unsigned ns, from the whole seconds
    and the fraction apart so an epoch of 1.7e9 s keeps the stamps' own
    resolution; MCAP's times are unsigned, so a stamp before 0 is refused."""
    t = np.asarray(t, np.float64)
    if t.size and t.min() < 0:
        row = int(np.argmax(t < 0))
        raise ValueError(f"{where} row {row}: stamp {t[row]:g} s is before 0, and MCAP log times are unsigned")
    whole = np.floor(t)
    return whole.astype(np.uint64) * np.uint64(NS_PER_S) + np.rint((t - whole) * NS_PER_S).astype(np.uint64)


def json_schema(table) -> dict:
    """The JSON schema of one stream's messages: every column a number with its unit."""
    props = {c.name: {"type": "integer" if c.integer else "number", "description": c.unit} for c in table.columns}
    return {
        "title": table.stream,
        "description": table.description,
        "type": "object",
        "properties": props,
        "required": list(props),
    }


def _write_mcap(tables, path: Path, log_metadata: dict) -> None:
    from mcap.writer import Writer

    times = [stamps_ns(t.columns[0].values, f"{t.stream}/{t.time_column}") for t in tables]
    # Messages in log-time order across streams, as a player reads them.
    which = np.concatenate([np.full(tm.size, i) for i, tm in enumerate(times)] or [np.zeros(0, int)])
    row = np.concatenate([np.arange(tm.size) for tm in times] or [np.zeros(0, int)])
    order = np.lexsort((row, which, np.concatenate(times or [np.zeros(0, np.uint64)])))
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile=MCAP_PROFILE, library="proxops")
        channels, rows = [], []
        for t in tables:
            sid = w.register_schema(t.stream, "jsonschema", json.dumps(json_schema(t)).encode())
            units = json.dumps({c.name: c.unit for c in t.columns})
            meta = {"time_column": t.time_column, "units": units}
            channels.append(w.register_channel(f"/{t.stream}", "json", sid, meta))
            names = [c.name for c in t.columns]
            rows.append([dict(zip(names, r)) for r in zip(*(c.values.tolist() for c in t.columns))])
        for i, r in zip(which[order].tolist(), row[order].tolist()):
            ns = int(times[i][r])
            w.add_message(channels[i], log_time=ns, data=json.dumps(rows[i][r]).encode(), publish_time=ns, sequence=r)
        w.add_metadata("proxops-flight-log", log_metadata)
        w.finish()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def export(tables, fmt: str, out, log_metadata: dict) -> list:
    """Writes ``tables`` as ``fmt`` to ``out`` (a folder for csv and parquet,
    a file for mcap); the paths written. ``log_metadata``: the log's
    attributes as text (MCAP's metadata record)."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r} (one of {', '.join(FORMATS)})")
    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    if fmt == "mcap":
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", dir=parent)
        os.close(fd)
        try:
            _write_mcap(tables, Path(tmp), log_metadata)
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's file is private; the export is not
            os.replace(tmp, out)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return [out]
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    try:
        (_write_csv if fmt == "csv" else _write_parquet)(tables, tmp)
        out.mkdir(exist_ok=True)
        written = []
        for p in sorted(tmp.iterdir()):
            os.replace(p, out / p.name)
            written.append(out / p.name)
        return written
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
