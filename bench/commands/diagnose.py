"""`proxops diagnose LOG --report DIR --json OUT`: where the sim-to-real gap
lies, which unmodelled effect causes it, how far it shrinks on held-out data,
and what the log let it examine."""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

from bench.commands.args import HelpFormatter, number, one_line_errors

MAX_CALIBRATION_BYTES = 64 << 20  # a calibration of 100000 runs is about 4 MiB


def register(sub):
    p = sub.add_parser(
        "diagnose",
        help="diagnose the sim-to-real gap of a flight log (where, which, how far)",
        formatter_class=HelpFormatter,
    )
    one_line_errors(p, "proxops diagnose")
    p.add_argument("log", help="flight log (HDF5, format version 1 or 2, docs/FLIGHT_LOG.md)")
    p.add_argument("--report", default=None, help="write the Markdown report and plots into this folder")
    p.add_argument(
        "--json",
        default=None,
        help="write the diagnosis as strict JSON here (non-finite numbers as null, listed under "
        "non_finite_as_null); '-' for stdout",
    )
    p.add_argument(
        "--calibration",
        default=None,
        help="null calibration JSON, checked against the log (default: the committed one when the log is "
        "the bench inspector flying the bench's manoeuvres, else one made for the log and cached)",
    )
    p.add_argument(
        "--null-runs",
        type=number(int, 10, 100000),
        default=40,
        help="simulated flights in a calibration made for the log (10 to 100000)",
    )
    p.add_argument(
        "--workers",
        type=number(int, 1, 1024),
        default=None,
        help="local Dask worker processes for a calibration made for the log (1 to 1024; default: all cores)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="make a calibration for the log on the existing Dask cluster at this address",
    )
    p.add_argument(
        "--quiet", action="store_true", help="no progress output (it is shown only when stderr is a terminal)"
    )
    p.set_defaults(func=main)


def _check_output(path: str | None, what: str) -> None:
    if path is None:
        return
    p = Path(path)
    if what == "json" and path != "-" and p.is_dir():
        raise ValueError(f"--json {path}: is a folder; give a file name")
    if what == "report" and p.exists() and not p.is_dir():
        raise ValueError(f"--report {path}: is a file; give a folder")


def _load_calibration(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"--calibration {path}: no such file")
    if p.stat().st_size > MAX_CALIBRATION_BYTES:
        raise ValueError(f"--calibration {path}: larger than {MAX_CALIBRATION_BYTES >> 20} MiB, not a null calibration")
    try:
        cal = json.loads(p.read_text())
    except RecursionError:
        raise ValueError(f"--calibration {path}: not JSON (nested too deeply)") from None
    except ValueError as exc:
        raise ValueError(f"--calibration {path}: not JSON ({str(exc)[:120]})") from None
    from bench.gap.calibration_file import problem

    why = problem(cal)
    if why:  # {} or a damaged file must not become "no gap"
        raise ValueError(f"--calibration {path}: {why}")
    return cal


def main(args):
    from bench.gap.diagnose import diagnose, public
    from bench.gap.log_null import CalibrationMismatch
    from bench.report import write_json
    from bench.runner import cluster
    from bench.sim.flight_log import FlightLogError, read_flight_log

    _check_output(args.json, "json")
    _check_output(args.report, "report")
    if args.scheduler is not None and "://" not in args.scheduler:
        raise ValueError(f"--scheduler {args.scheduler}: expected an address such as tcp://HOST:PORT")
    cluster.configure(args.scheduler, args.workers)
    log = read_flight_log(args.log, relative_time=True)  # any epoch: stamps from the log's start
    cal = _load_calibration(args.calibration) if args.calibration else None
    try:
        res = diagnose(
            log,
            calibration=cal,
            # Redrawn in place with "\r": only on a terminal, never into a log file.
            progress=not args.quiet and sys.stderr.isatty(),
            calibration_source=args.calibration,
            calibration_runs=args.null_runs,
        )
    except CalibrationMismatch as exc:
        raise ValueError(str(exc)) from None
    except FlightLogError as exc:  # a log the diagnosis cannot look at (too short, a run without a pose)
        raise FlightLogError(f"{args.log}: {exc}") from None
    out = public(res)
    if args.report:
        from bench.gap.report import write_report

        page = _write_report_atomically(res, args.report, Path(args.log).name, write_report)
        print(f"report: {page}", file=sys.stderr if args.json == "-" else sys.stdout)
    if args.json == "-":
        from bench.report import json_text

        sys.stdout.write(json_text(out, strict=True))
        return 0
    if args.json:
        write_json(args.json, out, strict=True)
    print_answers(out)
    print(f"diagnosed in {out['elapsed_s']:.1f} s")
    return 0


def _write_report_atomically(res, folder, name, write_report) -> Path:
    """The report goes into a fresh folder that replaces ``folder`` only once complete."""
    dest = Path(folder)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", dir=dest.parent))
    try:
        write_report(res, tmp, name)
        if dest.exists():
            old = dest.with_name(f".{dest.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            dest.rename(old)
            tmp.rename(dest)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return dest / "README.md"


def print_answers(out: dict, indent: str = "") -> None:
    """The three answers (where, which, how far) and what was examined."""
    from bench.gap.answers import answer_lines

    for label, text in answer_lines(out):
        print(f"{indent}{(label + ':') if label else '':<18}{text}")
