"""The Cortex-M7 firmware under QEMU: run its self-test, read its output,
compare it with the host float build's, and summarise the instructions per
step (docs/FIRMWARE.md).

    python -m hil_sim.firmware --elf build/firmware/firmware/proxops_fw.elf \\
        --host-exe build/cpp/fw_selftest_host [--input firmware/data/selftest_input.bin]

The self-test's output format is described in firmware/selftest.hpp.
Telemetry frames are decoded with hil_sim.packets (the bench's own
implementation of the link), so the comparison does not rely on the C++
framing it checks.
"""

from __future__ import annotations

import argparse
import re
import shutil
import statistics
import subprocess
import sys
from dataclasses import dataclass, field

import numpy as np

from hil_sim import packets as pk

QEMU = "qemu-system-arm"
# mps2-an500: the Cortex-M7 board of QEMU's Arm MPS2 family. -icount shift=6:
# each instruction advances the virtual clock by 64 ns, which the firmware's
# timer reads as 1.6 ticks (firmware/target/main.cpp).
QEMU_ARGS = [
    "-M",
    "mps2-an500",
    "-nographic",
    "-monitor",
    "none",
    "-serial",
    "none",
    "-semihosting-config",
    "enable=on,target=native",
    "-icount",
    "shift=6",
]
DEFAULT_INPUT = "firmware/data/selftest_input.bin"


def qemu_command(elf: str) -> list:
    return [QEMU, *QEMU_ARGS, "-kernel", elf]


def run_qemu(elf: str, timeout_s: float = 300.0) -> subprocess.CompletedProcess:
    if shutil.which(QEMU) is None:
        raise FileNotFoundError(f"{QEMU} not found (Debian package qemu-system-arm)")
    return subprocess.run(qemu_command(elf), capture_output=True, text=True, timeout=timeout_s)


def run_host(exe: str, input_path: str, timeout_s: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run([exe, input_path], capture_output=True, text=True, timeout=timeout_s)


@dataclass
class SelfTestOutput:
    frames: list = field(default_factory=list)  # (index, apid, instructions)
    telemetry: list = field(default_factory=list)  # bytes per frame (b"" if none)
    app_counters: dict = field(default_factory=dict)
    calls: list = field(default_factory=list)  # (step, instructions)
    counter_check: tuple | None = None  # (expected, measured)
    status: int | None = None


def parse(text: str) -> SelfTestOutput:
    out = SelfTestOutput()
    for line in text.splitlines():
        p = line.split()
        if not p or p[0] == "#":
            continue
        tag = p[0]
        if tag == "F":
            out.frames.append((int(p[1]), int(p[2]), int(p[3])))
            out.telemetry.append(b"")
        elif tag == "T":
            out.telemetry[-1] = bytes.fromhex(p[1])
        elif tag == "A":
            out.app_counters[p[1]] = int(p[2])
        elif tag == "C":
            out.calls.append((p[1], int(p[2])))
        elif tag == "K":
            out.counter_check = (int(p[1]), int(p[2]))
        elif tag == "E":
            out.status = int(p[1]) if p[1].lstrip("-").isdigit() else p[1]
        else:
            raise ValueError(f"self-test output: unknown line {line[:80]!r}")
    return out


def _field_kinds(apid: int) -> list:
    kinds = []
    for n, c in re.findall(r"(\d*)([a-zA-Z])", pk.APIDS[apid].fmt[1:]):
        if c != "x":
            kinds += [c] * (int(n) if n else 1)
    return kinds


# Tolerances of the firmware's float telemetry against the host float build.
# The two run the same source on the same inputs; they differ by rounding
# only: the host's Eigen uses SSE (4-wide sums, other summation order), the
# Cortex-M7 build is scalar, and newlib's float functions are not glibc's.
# Each bound is far below what the quantity means: the navigation ones are
# at most a thousandth of the filter's smallest 1-sigma over the recorded
# run (position 8.7 mm, velocity 1.5 mm/s, attitude 3.8 mrad).
#   name: [(slice of the payload's fields, absolute, relative)]
TOLERANCES = {
    "tm_estimate": [
        (slice(0, 3), 5e-6, 0.0),  # r_hill_m [m]
        (slice(3, 6), 1e-6, 0.0),  # v_hill_mps [m/s]
        (slice(6, 10), 1e-6, 0.0),  # q_hb (a component error e is an angle of about 2 e)
    ],
    "tm_covariance_diag": [(slice(2, 17), 0.0, 1e-4)],  # variances: 0.01 %
    "tm_innovation": [
        (slice(5, 8), 5e-6, 0.0),  # innovation, position [m]
        (slice(8, 11), 2e-6, 0.0),  # innovation, attitude [rad]
        (slice(11, 12), 1e-4, 1e-4),  # NIS (chi2 6 dof; gate 22.5)
        (slice(12, 13), 1e-3, 1e-4),  # log-likelihood
    ],
    "tm_learner": [
        (slice(2, 8), 1e-8, 1e-4),  # mean dv [m/s], dw [rad/s] per firing: 0.01 %
        (slice(8, 14), 0.0, 1e-3),  # predictive variances: 0.1 %
    ],
    "tm_housekeeping": [(slice(0, 3), 0.0, 1e-7)],  # uptime and CPU times: as sent
    "tm_modal": [
        (slice(7, 8), 0.0, 1e-4),  # rcond of M_Y
        (slice(8, 9), 1e-4, 1e-3),  # NIS
        (slice(9, 19), 0.0, 1e-4),  # omega: 1e-4 (1 % of the 1 % criterion; the search's grid step is 2e-3)
        (slice(19, 29), 1e-9, 0.0),  # alpha [1/s]: 1e-9 (estimates below 1e-10: zero at float resolution)
        (slice(29, 39), 1e-4, 0.0),  # amplitudes (unit: the mode's peak deflection, 0.1 .. 1): 1e-4
        (slice(39, 49), 0.0, 1e-3),  # amplitude sigmas: 0.1 %
    ],
}


@dataclass
class Comparison:
    failures: list = field(default_factory=list)
    packets: int = 0
    values: int = 0
    # Largest |difference| / allowed per telemetry field group: (ratio, abs diff, value, frame index).
    worst: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.failures


def compare(target: SelfTestOutput, host: SelfTestOutput) -> Comparison:
    """The firmware's telemetry against the host's: the same packets (APID,
    sequence count, time tag, every integer field equal) and every float
    field within TOLERANCES; the same counters, step sequence and status."""
    c = Comparison()
    if [f[:2] for f in target.frames] != [f[:2] for f in host.frames]:
        c.failures.append("the input frames differ (index, APID)")
        return c
    for name in ("app_counters", "status"):
        if getattr(target, name) != getattr(host, name):
            c.failures.append(f"{name}: target {getattr(target, name)} host {getattr(host, name)}")
    if [k for k, _ in target.calls] != [k for k, _ in host.calls]:
        c.failures.append("the component calls differ (step kinds or order)")
    dt, dh = pk.Deframer(pk.FROM_FLIGHT), pk.Deframer(pk.FROM_FLIGHT)
    for i, (a, b) in enumerate(zip(target.telemetry, host.telemetry)):
        pa, pb = dt.feed(a), dh.feed(b)
        if len(pa) != len(pb):
            c.failures.append(f"frame {i}: {len(pa)} telemetry packets on the target, {len(pb)} on the host")
            continue
        for x, y in zip(pa, pb):
            if not isinstance(x, pk.Packet) or not isinstance(y, pk.Packet):
                c.failures.append(f"frame {i}: telemetry rejected by the bench deframer: {x} / {y}")
                continue
            name = pk.APIDS[y.apid].name
            if (x.apid, x.header.seq_count, x.t_s) != (y.apid, y.header.seq_count, y.t_s):
                c.failures.append(f"frame {i}: packet {name} differs in APID, sequence count or time tag")
                continue
            c.packets += 1
            va, vb, kinds = x.values(), y.values(), _field_kinds(y.apid)
            tol = np.full(len(kinds), np.nan), np.full(len(kinds), np.nan)
            groups = {}
            for sl, atol, rtol in TOLERANCES.get(name, []):
                for j in range(*sl.indices(len(kinds))):
                    tol[0][j], tol[1][j] = atol, rtol
                    groups[j] = f"{name}[{sl.start}:{sl.stop}]"
            for j, (k, u, v) in enumerate(zip(kinds, va, vb)):
                c.values += 1
                if k != "d":
                    if u != v:
                        c.failures.append(f"frame {i}: {name} field {j}: {u} on the target, {v} on the host")
                    continue
                if np.isnan(tol[0][j]):
                    if u != v:
                        c.failures.append(f"frame {i}: {name} field {j} (no tolerance): {u!r} vs {v!r}")
                    continue
                allowed = tol[0][j] + tol[1][j] * abs(v)
                d = abs(u - v)
                ratio = d / allowed if allowed > 0 else (0.0 if d == 0 else np.inf)
                g = groups[j]
                if g not in c.worst or ratio > c.worst[g][0]:
                    c.worst[g] = (ratio, d, v, i)
                if not d <= allowed:
                    c.failures.append(
                        f"frame {i}: {name} field {j}: {u!r} on the target, {v!r} on the host "
                        f"(|diff| {d:.3g} > {allowed:.3g})"
                    )
    return c


# Steps of the instruction table: (label, C-line step names).
STEP_TABLE = [
    ("navigation predict (NavUkf::predict, 9 states)", ["nav_predict"]),
    ("navigation pose update (NavUkf::update_pose, fused)", ["nav_update"]),
    ("deframe one uplink frame (Deframer::feed, COBS + CRC + checks)", ["deframe"]),
    ("frame one telemetry packet (Framer::frame_message, tm_estimate)", ["frame_tm_estimate"]),
    ("modal: one range-image segment (24 points into M_Y)", ["modal_segment"]),
    ("modal: image step at 10 modes (solve, joint UKF predict + update)", ["modal_image"]),
    ("modal: image step with the frequency acquisition and replay", ["modal_image_acquisition"]),
    ("learner add (window not full)", ["learner_add"]),
    ("learner add, evicting the oldest (window 30)", ["learner_add_evict"]),
    ("learner remove_oldest", ["learner_remove"]),
    ("learner predict (Cholesky refresh)", ["learner_predict"]),
]
APP_TABLE = [
    ("app: imu_sample (predict, learner, telemetry)", 0x010),
    ("app: led_pose (update, telemetry)", 0x011),
    ("app: thruster_valves", 0x012),
    ("app: range_image_segment (incl. image steps)", 0x013),
    ("app: cmd_reset", 0x020),
    ("app: cmd_plan_entry (one opening staged)", 0x022),
    ("app: cmd_plan (load: the whole plan checked; start; abort)", 0x023),
]


def instruction_table(out: SelfTestOutput) -> list:
    """[(label, n, min, median, max)] over the self-test's calls."""
    rows = []
    for label, keys in STEP_TABLE:
        v = [n for k, n in out.calls if k in keys]
        if v:
            rows.append((label, len(v), min(v), int(statistics.median(v)), max(v)))
    for label, apid in APP_TABLE:
        v = [n for _, a, n in out.frames if a == apid]
        if v:
            rows.append((label, len(v), min(v), int(statistics.median(v)), max(v)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elf", default="build/firmware/firmware/proxops_fw.elf")
    ap.add_argument("--host-exe", default="build/cpp/fw_selftest_host")
    ap.add_argument("--input", default=DEFAULT_INPUT, help="the recording the firmware was built with")
    ap.add_argument("--mhz", type=float, default=400.0, help="clock for the time estimate [MHz]")
    ap.add_argument("--cpi", type=float, default=1.0, help="cycles per instruction for the time estimate")
    a = ap.parse_args(argv)
    print("$ " + " ".join(qemu_command(a.elf)))
    tgt_run = run_qemu(a.elf)
    if tgt_run.returncode != 0:
        print(tgt_run.stdout[-2000:], tgt_run.stderr[-2000:], sep="\n")
        return f"QEMU run failed (exit {tgt_run.returncode})"
    tgt = parse(tgt_run.stdout)
    host = parse(run_host(a.host_exe, a.input).stdout)
    print(f"instruction counter check: expected {tgt.counter_check[0]}, measured {tgt.counter_check[1]}")
    print(f"\n{'step':66s} {'n':>5s} {'min':>10s} {'median':>10s} {'max':>10s}  {'median us @ %g MHz' % a.mhz:>18s}")
    for label, n, lo, med, hi in instruction_table(tgt):
        print(f"{label:66s} {n:5d} {lo:10d} {med:10d} {hi:10d}  {med * a.cpi / a.mhz:18.1f}")
    c = compare(tgt, host)
    print(f"\ncomparison with the host float build: {c.packets} telemetry packets, {c.values} values")
    for g, (ratio, d, _v, i) in sorted(c.worst.items()):
        print(f"  {g:28s} worst |diff| {d:.3g} ({ratio:.3f} of the tolerance) at frame {i}")
    for f in c.failures[:20]:
        print("  FAIL " + f)
    return 0 if c.ok and tgt.status == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
