"""`proxops export LOG --to {csv,parquet,mcap} --out PATH`: every stream of
a flight log, with its time column and units, for pandas, PlotJuggler and
Foxglove (bench/sim/log_export.py; docs/FLIGHT_LOG.md, "Export")."""

from __future__ import annotations

import json
from pathlib import Path

from bench.commands.args import HelpFormatter, one_line_errors

FORMATS = ("csv", "parquet", "mcap")  # as bench.sim.log_export.FORMATS, without importing pyarrow for --help


def register(sub):
    p = sub.add_parser(
        "export",
        help="write a flight log's streams as CSV, Parquet or MCAP (pandas, PlotJuggler, Foxglove)",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops export")
    p.add_argument("log", help="flight log (HDF5, format version 1 or 2, docs/FLIGHT_LOG.md)")
    p.add_argument(
        "--to",
        required=True,
        choices=FORMATS,
        help="csv: a folder of <stream>.csv and units.csv; parquet: a folder of <stream>.parquet, "
        "units in the field metadata; mcap: one file, a JSON channel per stream",
    )
    p.add_argument("--out", required=True, help="the folder (csv, parquet) or file (mcap) to write")
    p.set_defaults(func=main)


def _check_out(out: str, fmt: str) -> None:
    p = Path(out)
    if fmt == "mcap" and p.is_dir():
        raise ValueError(f"--out {out}: is a folder; give a file name for mcap")
    if fmt != "mcap" and p.exists() and not p.is_dir():
        raise ValueError(f"--out {out}: is a file; give a folder for {fmt}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"--out {out}: {parent} is not a folder")


def main(args):
    from bench.sim.flight_log import read_flight_log
    from bench.sim.log_columns import stream_tables
    from bench.sim.log_export import export

    _check_out(args.out, args.to)
    log = read_flight_log(args.log)  # stamps as stored: an epoch stays an epoch
    meta = {
        "config_json": json.dumps(log.config, sort_keys=True),
        "description_json": json.dumps(log.description, sort_keys=True) if log.description is not None else "",
    }
    tables = stream_tables(log)
    try:
        export(tables, args.to, args.out, meta)
    except OSError as exc:
        raise ValueError(f"--out {args.out}: cannot write ({exc.strerror or exc})") from None
    rows = ", ".join(f"{t.stream} {t.rows}" for t in tables)
    print(f"wrote {len(tables)} streams to {args.out} ({args.to}; rows: {rows})")
    return 0
