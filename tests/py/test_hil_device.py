"""`proxops hil --device PATH`: the HIL loop against a flight computer on a
serial port. A second pseudo-terminal stands in for the device: fsw_node
runs on one pty, a thread joins its master to the master of another pty
(the cable), and the bench opens that other pty's device as the port."""

from __future__ import annotations

import json
import os
import select
import subprocess
import threading
import tty

import numpy as np
import pytest

pytest.importorskip("serial")

from bench import cli  # noqa: E402
from hil_sim.pty_link import find_fsw_node  # noqa: E402
from hil_sim.run import HilConfig, run_hil  # noqa: E402


class FlightComputer:
    """fsw_node on pty A; pty B's device is the bench's serial port."""

    def __init__(self):
        self.ma, self.sa = os.openpty()
        self.mb, self.sb = os.openpty()
        for fd in (self.sa, self.sb):
            tty.setraw(fd)
        self.device = os.ttyname(self.sb)
        self.proc = subprocess.Popen(
            [find_fsw_node(), "--device", os.ttyname(self.sa), "--baud", "921600"],
            stdin=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        line = b""
        while b"running" not in line:
            r, _, _ = select.select([self.proc.stderr], [], [], 10.0)
            assert r, "fsw_node did not start"
            chunk = os.read(self.proc.stderr.fileno(), 4096)
            assert chunk, line
            line += chunk
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._cable, daemon=True)
        self._thread.start()

    def _cable(self):
        while not self._stop.is_set():
            r, _, _ = select.select([self.ma, self.mb], [], [], 0.05)
            for src, dst in ((self.ma, self.mb), (self.mb, self.ma)):
                if src in r:
                    try:
                        data = os.read(src, 65536)
                    except OSError:
                        data = b""
                    view = memoryview(data)
                    while view and not self._stop.is_set():
                        try:
                            view = view[os.write(dst, view) :]
                        except BlockingIOError:
                            select.select([], [dst], [], 0.01)
                        except OSError:
                            break

    def close(self) -> int:
        self.proc.terminate()
        self.proc.communicate(timeout=10)
        self._stop.set()
        self._thread.join(timeout=5)
        for fd in (self.ma, self.sa, self.mb, self.sb):
            os.close(fd)
        return self.proc.returncode


def test_hil_against_a_device_gives_the_same_run_as_over_the_pty_relay():
    fc = FlightComputer()
    try:
        dev = run_hil(HilConfig(duration_s=20.0, seed=4, device=fc.device, step_timeout_s=1.0))
    finally:
        code = fc.close()
    assert code == 0
    pty = run_hil(HilConfig(duration_s=20.0, seed=4, step_timeout_s=1.0))
    assert dev["step_timeouts"] == 0 and pty["step_timeouts"] == 0
    assert dev["steps"] == pty["steps"] > 150
    assert dev["fsw_node_exit_code"] is None and "not started by the bench" in dev["fsw_node_summary"]
    for a, b in zip(dev["runs"], pty["runs"]):
        np.testing.assert_array_equal(a.est, b.est)


def test_hil_cli_with_device(tmp_path, capsys):
    fc = FlightComputer()
    out = tmp_path / "hil.json"
    try:
        code = cli.main(["hil", "--device", fc.device, "--baud", "921600", "--duration", "5", "--json", str(out)])
    finally:
        assert fc.close() == 0
    assert code == 0, capsys.readouterr().err
    s = json.loads(out.read_text())
    assert s["step_timeouts"] == 0 and s["docking_runs"] >= 1


def test_hil_device_refuses_link_faults_and_a_missing_port(tmp_path, capsys):
    code = cli.main(["hil", "--device", str(tmp_path / "no-such-port"), "--duration", "5"])
    assert code == 2
    assert "no-such-port" in capsys.readouterr().err
    fc = FlightComputer()
    try:
        code = cli.main(["hil", "--device", fc.device, "--ber", "1e-4", "--duration", "5"])
    finally:
        fc.close()
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--device" in err[0]
