"""fsw_node's command line (docs/REQUIREMENTS.md, FSW-EXE-04): a bad
argument is refused with the usage line and exit code 2, a port that cannot
be opened with one line and exit code 1; nothing runs in either case."""

from __future__ import annotations

import subprocess

import pytest

from hil_sim.pty_link import find_fsw_node


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([find_fsw_node(), *args], capture_output=True, text=True, timeout=20)


@pytest.mark.parametrize(
    "args",
    [
        [],
        ["--baud", "115200"],
        ["--device"],
        ["--device", "/dev/null", "--speed", "9600"],
        ["--device", "/dev/null", "--baud", "fast"],
        ["--device", "/dev/null", "--baud", "9600x"],
        ["--device", "/dev/null", "--baud", ""],
        ["--device", "/dev/null", "--baud", "-9600"],
        ["--device", "/dev/null", "--baud", "99999999999999999999"],
    ],
)
def test_fsw_node_refuses_bad_arguments_with_usage(args):
    r = _run(*args)
    assert r.returncode == 2, (args, r.returncode, r.stderr)
    assert r.stderr.startswith("usage: ") and r.stderr.count("\n") == 1, r.stderr


def test_fsw_node_refuses_a_port_it_cannot_open(tmp_path):
    missing = tmp_path / "no_such_port"
    r = _run("--device", str(missing))
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and f"cannot open {missing}" in r.stderr, r.stderr
    # A rate the port does not support: refused before the port is touched.
    r = _run("--device", str(missing), "--baud", "12345")
    assert r.returncode == 1
    assert "unsupported baud rate" in r.stderr and r.stderr.count("\n") == 1, r.stderr
