"""Records the self-test firmware's input (firmware/data/selftest_input.bin):
the uplink of a docking run and of the vibrating plate's range images, as
link frames (COBS, each ending in 0x00).

Navigation: one docking run of the bench (bench/sim/scenario_docking.py: plant,
IMU, LED poses, controller, thruster valve commands) with its navigation in
the flight application in-process (hil_sim/link_nav.LinkNav over a link that
records every byte sent up), so the recording is what the ground sent to a
flight side that answered: cmd_config, cmd_reset, imu_sample, led_pose,
thruster_valves.

Valve plan: after the docking run, a plan refused at its load (two
openings of one valve overlapping), then a plan of four openings uplinked
entry by entry, loaded, started and flown open loop on a second docking
run (hil_sim/plan_link.py: the plant fires the valves the flight side
commands), finished, started again and aborted.

Structure: range images of the range-image paper's 10-mode plate (bench/sim/structure.py),
one a minute, each thinned to points spread evenly over its rays, as
range_image_segment packets; enough images for the tracker's frequency
acquisition (2 periods of the lowest mode). Their packets are interleaved
with the navigation ones (time tags are ordered per packet stream).

    python firmware/make_input.py [--out firmware/data/selftest_input.bin]
"""
from __future__ import annotations

import argparse
import dataclasses
import types

import numpy as np

import fsw_bindings as fb
from bench.sim import structure as st
from bench.sim.scenario_docking import ScenarioConfig, nav_config, run_docking
from hil_sim import packets as pk
from hil_sim.link_nav import LinkNav
from hil_sim.plan_link import FlightValves, PlanLinkNav

SEG = pk.APID_BY_NAME["range_image_segment"].apid
IMU = pk.APID_BY_NAME["imu_sample"].apid
ENTRY, PLAN_CMD = pk.APID_BY_NAME["cmd_plan_entry"].apid, pk.APID_BY_NAME["cmd_plan"].apid
# The plan flown: (valve, open, close) from its start [s], and its length.
PLAN = [(0, 1.0, 2.0), (3, 1.5, 2.5), (5, 3.0, 3.3), (0, 4.0, 4.5)]
PLAN_DURATION_S = 6.0
REFUSED_PLAN = [(3, 0.0, 1.0), (3, 0.5, 1.5)]


class RecordingLink:
    """LinkNav's link: the flight application in-process behind it, every
    write kept as one chunk of the uplink."""

    def __init__(self):
        self.app = fb.FlightApp(fb.NavConfig())
        self.chunks: list[bytes] = []
        self._rx = b""
        self.down = types.SimpleNamespace(cfg=types.SimpleNamespace(clean=True), originals=())

    def write(self, data: bytes):
        self.chunks.append(bytes(data))
        self._rx += self.app.on_bytes(bytes(data))

    def pump(self, timeout_s: float = 0.0) -> int:
        return 0

    def read_available(self) -> bytes:
        data, self._rx = self._rx, b""
        return data


def navigation_chunks(seed: int, duration_s: float) -> list[bytes]:
    sc = dataclasses.replace(ScenarioConfig(), t_max_s=duration_s)
    link = RecordingLink()
    nav = LinkNav(link, step_timeout_s=10.0, send_valves=True)
    nav.configure_nav(nav_config(sc), t_s=0.0)
    run = run_docking(seed, sc, nav=nav)
    c = link.app.counters()
    if c["pose_fused"] == 0 or c["learner_samples"] == 0:
        raise RuntimeError(f"the docking run fused no pose or fed no learner sample: {c}")
    plan_phase(link, nav, seed + 1, float(run.summary.t_end_s) + 1.0)
    c = link.app.counters()
    want = {"plans_loaded": 1, "plan_commands_refused": 1, "plans_finished": 1, "plan_aborts": 1}
    if any(c[k] != v for k, v in want.items()):
        raise RuntimeError(f"the plan phase did not load, refuse, finish and abort once each: {c}")
    return link.chunks


def plan_phase(link: RecordingLink, nav: LinkNav, seed: int, t0: float) -> None:
    """The valve plan from mission time t0 (module docstring), on the
    same link and sequence counts as the docking run before it."""
    frames = b"".join(nav.sender.frame(ENTRY, t0, pl) for pl in pk.plan_entry_payloads(1, REFUSED_PLAN))
    link.write(frames + nav.sender.frame(PLAN_CMD, t0, pk.plan_command_payload("load", 1, 2, 2.0)))
    sc = ScenarioConfig()
    n = int(round(PLAN_DURATION_S / sc.dt_s)) + 2
    pnav = PlanLinkNav(link, PLAN, PLAN_DURATION_S, plan_id=2, dt_s=sc.dt_s, step_timeout_s=10.0)
    pnav.sender, pnav.deframer, pnav.time_offset_s = nav.sender, nav.deframer, t0
    sc = dataclasses.replace(sc, t_max_s=(n + 1) * sc.dt_s, valve_script=FlightValves(pnav, n))
    run = run_docking(seed, sc, nav=pnav)
    if not (pnav.started and pnav.ended == "finished"):
        raise RuntimeError(f"the plan was not flown to its end: {pnav.verdict}, {pnav.ended}")
    # Started again at the next tick and aborted within its fourth interval.
    t = t0 + float(run.summary.t_end_s) + sc.dt_s
    out = nav.sender.frame(PLAN_CMD, t, pk.plan_command_payload("start", 2))
    for k in range(4):
        out += nav.sender.frame(IMU, t + k * sc.dt_s, pk.pack_payload(IMU, *[0.0] * 6))
    link.write(out + nav.sender.frame(PLAN_CMD, t + 3.5 * sc.dt_s, pk.plan_command_payload("abort", 2)))


def plate_images(seed: int, n_images: int, points: int, dt_s: float = 60.0) -> list[bytes]:
    rng = np.random.default_rng(seed)
    plate = st.Plate(n_modes=10)
    sensor = st.plate_sensor(plate)
    amp, phase = st.plate_truth(plate, rng)
    sender = pk.Sender()
    out = []
    for k in range(n_images):
        t = k * dt_s
        r_meas, d = st.plate_range_image(plate, sensor, st.plate_coeffs(plate, amp, phase, t), rng)
        hit = np.nonzero(np.isfinite(r_meas))[0]  # missed rays are not sent
        keep = hit[np.linspace(0, len(hit) - 1, min(points, len(hit))).round().astype(int)]
        p = sensor.pos_m[None, :] + r_meas[keep, None] * d[keep]
        sigma = np.abs(0.03 * r_meas[keep] * d[keep, 2])
        out.append(b"".join(sender.frame(SEG, t, pl, seq_flags=f)
                            for f, pl in pk.range_image_segments(k, p, sigma)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="firmware/data/selftest_input.bin")
    ap.add_argument("--seed", type=int, default=27)
    ap.add_argument("--duration-s", type=float, default=60.0, help="docking run length [s]")
    ap.add_argument("--images", type=int, default=84, help="range images (one a minute)")
    ap.add_argument("--points", type=int, default=96, help="points per range image")
    a = ap.parse_args(argv)
    nav = navigation_chunks(a.seed, a.duration_s)
    img = plate_images(a.seed, a.images, a.points)
    # One image after every len(nav) / len(img) navigation chunks.
    out = bytearray()
    step = len(nav) / len(img)
    j = 0
    for i, chunk in enumerate(nav):
        out += chunk
        while j < len(img) and (j + 1) * step <= i + 1:
            out += img[j]
            j += 1
    for rest in img[j:]:
        out += rest
    with open(a.out, "wb") as f:
        f.write(out)
    print(f"{a.out}: {len(out)} bytes, {len(nav)} navigation writes, {len(img)} range images of {a.points} points")


if __name__ == "__main__":
    main()
