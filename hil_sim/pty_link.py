"""The serial link of the HIL loop: two pseudo-terminals joined by a relay.

    fsw_node <-> /dev/pts/A (raw, termios) | master A <-relay-> master B | /dev/pts/B <-> pyserial (bench)

Each end sees a real tty device, as with a cable between two UARTs. The
relay in between is where link faults are injected (hil_sim/faults.py), in
each direction separately. The relay is pumped by the bench's own loop (no
threads), so a run with a seeded fault generator replays exactly.
"""

from __future__ import annotations

import errno
import os
import select
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
import tty
from pathlib import Path

import numpy as np
import serial

from hil_sim.faults import FaultConfig, FaultInjector

BAUD = 921600
# The bench gives up on the flight side once it has waited this long in all
# for telemetry without receiving a byte (waiting only: time the bench spends
# computing does not count). An exited fsw_node is noticed at the next wait.
SILENCE_S = 2.0


class FlightSideLost(RuntimeError):
    """The flight side exited or stopped answering; the message says which."""


def find_fsw_node() -> str:
    """Path of the flight executable: $PROXOPS_FSW_NODE, the environment's
    scripts folder (pip install), or a CMake build folder."""
    env = os.environ.get("PROXOPS_FSW_NODE")
    if env:
        if not os.access(env, os.X_OK):
            raise FileNotFoundError(f"PROXOPS_FSW_NODE={env} is not an executable")
        return env
    candidates = [Path(sysconfig.get_path("scripts")) / "fsw_node", Path(sys.prefix) / "bin" / "fsw_node"]
    root = Path(__file__).resolve().parent.parent
    candidates += sorted(root.glob("build/*/fsw_node"))
    for c in candidates:
        if c.exists() and os.access(c, os.X_OK):
            return str(c)
    found = shutil.which("fsw_node")
    if found:
        return found
    raise FileNotFoundError("fsw_node not found: run `make run` (it builds and installs it) or set PROXOPS_FSW_NODE")


def open_link(
    faults_up: FaultConfig = FaultConfig(),
    faults_down: FaultConfig = FaultConfig(),
    seed: int = 0,
    device: str | None = None,
    baud: int = BAUD,
):
    """The HIL link: fsw_node started on a pseudo-terminal pair with the
    fault-injecting relay (PtyLink), or, with device, a flight computer on a
    serial port (DeviceLink; no fault injection there)."""
    if device is None:
        return PtyLink(faults_up=faults_up, faults_down=faults_down, seed=seed)
    if not (faults_up.clean and faults_down.clean):
        raise ValueError("link faults are injected by the pseudo-terminal relay; they cannot be used with --device")
    return DeviceLink(device, baud=baud)


def _open_pty():
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


class PtyLink:
    """Starts fsw_node on one pty, opens the bench's end with pyserial, and
    relays between them with fault injection."""

    def __init__(
        self,
        faults_up: FaultConfig = FaultConfig(),
        faults_down: FaultConfig = FaultConfig(),
        seed: int = 0,
        node_path: str | None = None,
        baud: int = BAUD,
        start_timeout_s: float = 10.0,
        silence_s: float = SILENCE_S,
    ):
        rng = np.random.default_rng(seed)
        self.up = FaultInjector(faults_up, np.random.default_rng(rng.integers(2**63)))  # bench -> flight
        self.down = FaultInjector(faults_down, np.random.default_rng(rng.integers(2**63)))  # flight -> bench
        self.node_path = node_path or find_fsw_node()
        self._ma, self._sa, self.flight_device = _open_pty()
        self._mb, self._sb, self.bench_device = _open_pty()
        self.proc = subprocess.Popen(
            [self.node_path, "--device", self.flight_device, "--baud", str(baud)],
            stdin=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        self._wait_ready(start_timeout_s)
        self.port = serial.Serial(self.bench_device, baudrate=baud, timeout=0)
        self.bytes_up = 0
        self.bytes_down = 0
        self._stalled_until = {"up": 0.0, "down": 0.0}
        self._queued = {"up": b"", "down": b""}
        self.silence_s = silence_s
        self._silent_wait_s = 0.0  # time spent waiting in pump() since the flight side last sent a byte
        self._intact_when_heard = 0  # intact frames passed up when the flight side last sent a byte

    def _wait_ready(self, timeout_s: float):
        # fsw_node flushes its port when it opens it: nothing may be sent
        # before it says it is running.
        line = b""
        deadline = time.monotonic() + timeout_s
        while b"running" not in line:
            r, _, _ = select.select([self.proc.stderr], [], [], max(0.0, deadline - time.monotonic()))
            if not r:
                self.proc.kill()
                raise RuntimeError(f"fsw_node did not start within {timeout_s} s")
            chunk = os.read(self.proc.stderr.fileno(), 4096)
            if not chunk:
                raise RuntimeError(f"fsw_node exited at start: {line.decode(errors='replace')}")
            line += chunk

    # -- bench side -------------------------------------------------------
    def write(self, data: bytes):
        # No flush(): on a tty it is tcdrain(), which waits for the far side.
        self.port.write(data)

    def read_available(self) -> bytes:
        n = self.port.in_waiting
        return self.port.read(n) if n else b""

    # -- relay ------------------------------------------------------------
    def _move(self, src: int, dst: int, faults: FaultInjector, key: str) -> int:
        try:
            data = os.read(src, 65536)
        except BlockingIOError:
            data = b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # no process holds the other end yet
                data = b""
            else:
                raise
        moved = len(data)
        if data:
            stall = faults.stall_now()
            if stall and time.monotonic() >= self._stalled_until[key]:
                # A stall delays what is queued by stall_s; a chunk arriving
                # during it does not extend it (at stall_rate 1 the link would
                # otherwise never deliver again).
                self._stalled_until[key] = time.monotonic() + stall
            self._queued[key] += faults.apply(data)
        if self._queued[key] and time.monotonic() >= self._stalled_until[key]:
            # What the far pty does not take now stays queued for the next
            # pump: never wait here (a dead reader would hang the bench).
            try:
                k = os.write(dst, self._queued[key])
            except BlockingIOError:
                k = 0
            except OSError as exc:
                if exc.errno != errno.EIO:
                    raise
                k = 0
            self._queued[key] = self._queued[key][k:]
        return moved

    def pump(self, timeout_s: float = 0.0) -> int:
        """Relays whatever is waiting in both directions; waits up to
        timeout_s for something to arrive. Returns the bytes moved."""
        # The bench's own port is watched too: a tty hands bytes over
        # asynchronously, so they may land there after the relay moved them.
        self.check_flight_side()
        t0 = time.monotonic()
        r, _, _ = select.select([self._ma, self._mb, self.port.fileno()], [], [], timeout_s)
        waited = time.monotonic() - t0
        moved = 0
        if self._mb in r or self._queued["up"]:
            n = self._move(self._mb, self._ma, self.up, "up")
            self.bytes_up += n
            moved += n
        heard = 0
        if self._ma in r or self._queued["down"]:
            heard = self._move(self._ma, self._mb, self.down, "down")
            self.bytes_down += heard
            moved += heard
        if heard or self.up.cfg.clean:
            self._silent_wait_s = 0.0 if heard else self._silent_wait_s + waited
        elif self.up.counts.frames_intact > self._intact_when_heard:
            # Silence counts only once a frame reached the flight side intact:
            # a link that destroys every frame leaves fsw_node nothing to answer.
            self._silent_wait_s += waited
        if heard:
            self._intact_when_heard = self.up.counts.frames_intact
        return moved

    def check_flight_side(self):
        """Raises FlightSideLost when fsw_node has exited, or when the bench
        has waited silence_s in all without a byte from it (with link faults:
        waited since an intact frame reached it)."""
        code = self.proc.poll()
        if code is not None:
            how = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
            raise FlightSideLost(f"the flight side stopped: fsw_node exited ({how})")
        if self._silent_wait_s > self.silence_s:
            raise FlightSideLost(
                f"the flight side is silent: no telemetry from fsw_node in {self._silent_wait_s:.1f} s of waiting"
            )

    def node_alive(self) -> bool:
        return self.proc.poll() is None

    def close(self, timeout_s: float = 5.0) -> dict:
        """Stops fsw_node with SIGTERM; returns how it ended."""
        result = {"exit_code": None, "stderr": ""}
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            _, err = self.proc.communicate(timeout=timeout_s)
            result["stderr"] = err.decode(errors="replace") if err else ""
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.communicate()
            result["stderr"] = "fsw_node did not stop on SIGTERM; killed"
        result["exit_code"] = self.proc.returncode
        self.port.close()
        for fd in (self._ma, self._sa, self._mb, self._sb):
            try:
                os.close(fd)
            except OSError:
                pass
        return result

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class DeviceLink:
    """The bench's end of a real serial port with a flight computer on it
    (e.g. a USB serial adapter): the same interface as PtyLink for the HIL
    loop, without the relay (no fault injection) and without starting
    fsw_node (the flight computer runs its own). The flight side counts as
    silent after silence_s of waiting without a byte from it, as with
    PtyLink; there is no process to watch."""

    def __init__(self, device: str, baud: int = BAUD, silence_s: float = SILENCE_S):
        self.device = device
        self.silence_s = silence_s
        try:
            self.port = serial.Serial(device, baudrate=baud, timeout=0, write_timeout=silence_s)
        except (serial.SerialException, ValueError) as exc:
            raise FileNotFoundError(f"--device {device}: cannot open at {baud} baud: {exc}") from None
        self.port.reset_input_buffer()
        clean = FaultConfig()
        self.up = FaultInjector(clean, np.random.default_rng(0))
        self.down = FaultInjector(clean, np.random.default_rng(0))
        self.flight_device = device
        self.bench_device = device
        self.proc = None
        self.bytes_up = 0
        self.bytes_down = 0
        self._silent_wait_s = 0.0
        self._pending = b""  # read by pump() while watching, handed out by read_available()

    def write(self, data: bytes):
        try:
            self.port.write(data)
        except serial.SerialTimeoutException:
            raise FlightSideLost(
                f"the flight side is not reading: {self.device} took no bytes for {self.silence_s:g} s"
            ) from None
        except serial.SerialException as exc:
            raise FlightSideLost(f"the flight side is gone: {self.device}: {exc}") from None
        self.bytes_up += len(data)

    def read_available(self) -> bytes:
        out, self._pending = self._pending, b""
        try:
            n = self.port.in_waiting
            more = self.port.read(n) if n else b""
        except (OSError, serial.SerialException) as exc:
            raise FlightSideLost(f"the flight side is gone: {self.device}: {exc}") from None
        self.bytes_down += len(more)
        if more:
            self._silent_wait_s = 0.0
        return out + more

    def pump(self, timeout_s: float = 0.0) -> int:
        self.check_flight_side()
        t0 = time.monotonic()
        try:
            r, _, _ = select.select([self.port.fileno()], [], [], timeout_s)
            data = self.port.read(self.port.in_waiting or 1) if r else b""
        except (OSError, serial.SerialException) as exc:
            raise FlightSideLost(f"the flight side is gone: {self.device}: {exc}") from None
        waited = time.monotonic() - t0
        self._pending += data
        self.bytes_down += len(data)
        self._silent_wait_s = 0.0 if data else self._silent_wait_s + waited
        return len(data)

    def check_flight_side(self):
        if self._silent_wait_s > self.silence_s:
            raise FlightSideLost(
                f"the flight side is silent: no telemetry on {self.device} in {self._silent_wait_s:.1f} s of waiting"
            )

    def node_alive(self) -> bool:
        return True

    def close(self, timeout_s: float = 5.0) -> dict:
        self.port.close()
        return {"exit_code": None, "stderr": f"flight computer on {self.device} (not started by the bench)"}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
