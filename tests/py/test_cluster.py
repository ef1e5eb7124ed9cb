"""`--scheduler`: an address where nothing accepts a connection is refused
in one line within 5 s (Dask's client retried for its whole 20 s timeout
first), before any run starts; so is one that is not tcp://HOST:PORT."""

from __future__ import annotations

import socket
import time

import pytest

from bench import cli
from bench.runner import cluster


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_nothing_listening_is_refused_at_once():
    address = f"tcp://127.0.0.1:{_closed_port()}"
    t0 = time.monotonic()
    with pytest.raises(ValueError, match=f"--scheduler {address}: cannot connect"):
        cluster.check_reachable(address)
    assert time.monotonic() - t0 < 5.0


@pytest.mark.parametrize("address", ["tcp://127.0.0.1", "tcp://127.0.0.1:99999", "http://127.0.0.1:8786", "tcp://:1"])
def test_an_address_of_the_wrong_form_is_refused(address):
    with pytest.raises(ValueError, match="expected an address such as tcp://HOST:PORT"):
        cluster.check_reachable(address)


def test_validate_gap_refuses_an_unreachable_scheduler_in_one_line_within_5_s(tmp_path, capsys):
    address = f"tcp://127.0.0.1:{_closed_port()}"
    out = tmp_path / "v.json"
    t0 = time.monotonic()
    rc = cli.main(["validate-gap", "--runs", "2", "--seed", "1", "--json", str(out), "--scheduler", address])
    wall = time.monotonic() - t0
    lines = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "cannot connect" in lines[0], lines
    assert wall < 5.0 and not out.exists()
