"""fsw_node on a pseudo-terminal whose far end does not read: the flight
executable keeps running, drops telemetry, counts it, and reports the count
in housekeeping once the ground reads again."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import time
import tty

import pytest

pytest.importorskip("serial")

from hil_sim import packets as pk  # noqa: E402
from hil_sim.pty_link import find_fsw_node  # noqa: E402

IMU = pk.APID_BY_NAME["imu_sample"].apid
RESET = pk.APID_BY_NAME["cmd_reset"].apid
HK = pk.APID_BY_NAME["tm_housekeeping"].apid
INN = pk.APID_BY_NAME["tm_innovation"].apid


class Node:
    """fsw_node on one pty; this end (the master) is the ground."""

    def __init__(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.proc = subprocess.Popen(
            [find_fsw_node(), "--device", os.ttyname(self.slave)], stdin=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        line = b""
        deadline = time.monotonic() + 10.0
        while b"running" not in line:
            r, _, _ = select.select([self.proc.stderr], [], [], max(0.0, deadline - time.monotonic()))
            assert r, "fsw_node did not start"
            chunk = os.read(self.proc.stderr.fileno(), 4096)
            assert chunk, f"fsw_node exited at start: {line!r}"
            line += chunk
        self.sender = pk.Sender()

    def send(self, data: bytes, timeout_s: float = 5.0):
        view = memoryview(data)
        deadline = time.monotonic() + timeout_s
        while view:
            assert time.monotonic() < deadline, "fsw_node stopped reading its port"
            try:
                view = view[os.write(self.master, view) :]
            except BlockingIOError:
                select.select([], [self.master], [], 0.01)

    def read_all(self, quiet_s: float = 0.3) -> bytes:
        out = bytearray()
        while True:
            r, _, _ = select.select([self.master], [], [], quiet_s)
            if not r:
                return bytes(out)
            try:
                out += os.read(self.master, 65536)
            except BlockingIOError:
                pass

    def imu(self, t_s: float) -> bytes:
        return self.sender.frame(IMU, t_s, pk.pack_payload(IMU, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))

    def stop(self) -> tuple:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            _, err = self.proc.communicate(timeout=5.0)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
            os.close(self.master)
            os.close(self.slave)
        return self.proc.returncode, err.decode(errors="replace")


def _reset(node: Node) -> bytes:
    return node.sender.frame(
        RESET, 0.0, pk.pack_payload(RESET, 0x1, 0, 0.0, -0.7, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.05, 0.01, 0.05)
    )


def test_fsw_node_keeps_running_when_the_ground_stops_reading():
    node = Node()
    try:
        node.send(_reset(node))
        # 1500 IMU samples (about 0.5 MB of telemetry) while nothing is read,
        # over about 3 s: the port fills within a fraction of a second.
        for k in range(1, 1501):
            node.send(node.imu(0.1 * k))
            if k % 50 == 0:
                time.sleep(0.1)
                assert node.proc.poll() is None, "fsw_node exited while the ground was not reading"
        # The ground reads again: old telemetry, then answers to new samples.
        down = pk.Deframer(pk.FROM_FLIGHT)
        down.feed(node.read_all())
        for k in range(1501, 1521):
            node.send(node.imu(0.1 * k))
        items = down.feed(node.read_all(quiet_s=1.0))
        hk = [pk.decode_housekeeping(p.payload) for p in items if isinstance(p, pk.Packet) and p.apid == HK]
        answered = [p for p in items if isinstance(p, pk.Packet) and p.apid == INN]
        assert len(answered) >= 20
        assert hk, "no housekeeping after the ground read again"
        assert hk[-1]["cycle_count"] == 1520
        assert hk[-1]["tx_dropped"] > 0
        assert node.proc.poll() is None
    finally:
        code, err = node.stop()
    assert code == 0, err
    dropped = int(err.split("dropped ")[1].split(",")[0])
    assert dropped == hk[-1]["tx_dropped"]  # nothing dropped once the ground read again


def test_burst_of_imu_samples_loses_no_telemetry_when_the_ground_reads():
    """300 IMU samples in one write (about 20 kB); the ground reads as fast as
    it can: every sample is answered in full."""
    node = Node()
    try:
        node.send(_reset(node))
        burst = b"".join(node.imu(0.1 * k) for k in range(1, 301))
        down = pk.Deframer(pk.FROM_FLIGHT)
        items = []
        view = memoryview(burst)
        deadline = time.monotonic() + 20.0
        while view and time.monotonic() < deadline:
            try:
                view = view[os.write(node.master, view) :]
            except BlockingIOError:
                pass
            r, _, _ = select.select([node.master], [], [], 0.001)
            if r:
                try:
                    items += down.feed(os.read(node.master, 65536))
                except BlockingIOError:
                    pass
        items += down.feed(node.read_all(quiet_s=1.0))
        inn = [p for p in items if isinstance(p, pk.Packet) and p.apid == INN]
        hk = [pk.decode_housekeeping(p.payload) for p in items if isinstance(p, pk.Packet) and p.apid == HK]
        assert not any(isinstance(p, pk.Rejection) for p in items)
        assert len(inn) == 301
        assert hk and hk[-1]["tx_dropped"] == 0
    finally:
        code, err = node.stop()
    assert code == 0, err
