"""`proxops hil` when the flight side dies or falls silent: the bench stops
within the stated time, says so in one line, exits 1, and leaves the user's
earlier outputs as they were."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("serial")

from hil_sim.pty_link import SILENCE_S, find_fsw_node  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

# Starts the real fsw_node, then after DELAY seconds sends it SIG (KILL: the
# flight side dies; STOP: it hangs). SIGTERM (the bench closing) ends both.
WRAPPER = """#!/bin/sh
"$REAL_FSW_NODE" "$@" &
pid=$!
trap 'kill -KILL $pid 2>/dev/null; exit 143' TERM
sleep "$DELAY"
kill -"$SIG" "$pid"
wait "$pid"
"""


def _run_hil(tmp_path: Path, sig: str, delay_s: float, args: list, timeout_s: float):
    wrapper = tmp_path / "fsw_node_wrapper.sh"
    wrapper.write_text(WRAPPER)
    wrapper.chmod(0o755)
    env = dict(
        os.environ,
        PROXOPS_FSW_NODE=str(wrapper),
        REAL_FSW_NODE=find_fsw_node(),
        SIG=sig,
        DELAY=str(delay_s),
        PYTHONPATH=str(ROOT),
    )
    t0 = time.monotonic()
    p = subprocess.run(
        [sys.executable, "-m", "bench.cli", "hil", *args],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )
    return p, time.monotonic() - t0


def _outputs(tmp_path: Path):
    out_json = tmp_path / "earlier.json"
    out_json.write_text('{"earlier": true}\n')
    report = tmp_path / "report"
    report.mkdir()
    (report / "hil.json").write_text('{"earlier": true}\n')
    return out_json, report


def _assert_untouched(tmp_path: Path, out_json: Path, report: Path):
    assert out_json.read_text() == '{"earlier": true}\n'
    assert sorted(f.name for f in report.iterdir()) == ["hil.json"]
    assert (report / "hil.json").read_text() == '{"earlier": true}\n'
    assert sorted(f.name for f in tmp_path.iterdir()) == ["earlier.json", "fsw_node_wrapper.sh", "report"]


def _error_lines(stderr: str) -> list:
    return [ln for ln in stderr.splitlines() if ln.startswith("proxops hil:")]


def test_killed_flight_side_stops_a_realtime_run(tmp_path):
    out_json, report = _outputs(tmp_path)
    p, wall = _run_hil(
        tmp_path,
        "KILL",
        2.0,
        ["--realtime", "--duration", "30", "--json", str(out_json), "--report", str(report)],
        timeout_s=120,
    )
    assert p.returncode == 1, p.stderr
    errors = _error_lines(p.stderr)
    assert len(errors) == 1 and "fsw_node exited" in errors[0], p.stderr
    assert "Traceback" not in p.stderr
    assert wall < 20.0  # a 30 s real-time run, stopped soon after the 2 s kill
    _assert_untouched(tmp_path, out_json, report)


def test_silent_flight_side_stops_a_realtime_run(tmp_path):
    out_json, report = _outputs(tmp_path)
    p, wall = _run_hil(
        tmp_path,
        "STOP",
        2.0,
        ["--realtime", "--duration", "30", "--json", str(out_json), "--report", str(report)],
        timeout_s=120,
    )
    assert p.returncode == 1, p.stderr
    errors = _error_lines(p.stderr)
    assert len(errors) == 1 and "silent" in errors[0], p.stderr
    # In real time half of each 0.1 s step is spent waiting: SILENCE_S of
    # waiting takes about twice that of wall time.
    assert wall < 2.0 + 2 * SILENCE_S + 10.0
    _assert_untouched(tmp_path, out_json, report)


def test_flight_side_dying_during_a_plate_run_does_not_hang_the_bench(tmp_path):
    out_json, report = _outputs(tmp_path)
    p, _ = _run_hil(
        tmp_path,
        "KILL",
        1.0,
        ["--scenario", "plate", "--images", "2000", "--json", str(out_json), "--report", str(report)],
        timeout_s=120,
    )
    assert p.returncode == 1, p.stderr
    errors = _error_lines(p.stderr)
    assert len(errors) == 1 and "fsw_node exited" in errors[0], p.stderr
    _assert_untouched(tmp_path, out_json, report)
