"""The plate over the link: range images of the paper's vibrating plate
(bench/sim/structure.py) sent as range_image_segment packets to the flight
executable behind a pseudo-terminal, its modal estimate back as tm_modal.

Lockstep: each image's segments go out in one write, then the bench waits
for that image's tm_modal (up to a timeout: with a lost last segment the
flight side closes the image only when the next image's first segment
arrives, so its answer comes one image late). The on-board plate model is
told a first period prior_period_factor times the truth's, so every a
priori frequency is off by that factor.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from bench.sim import structure as st
from hil_sim import packets as pk
from hil_sim.faults import FaultConfig
from hil_sim.pty_link import BAUD, open_link

SEG = pk.APID_BY_NAME["range_image_segment"].apid
TM_MODAL = pk.APID_BY_NAME["tm_modal"].apid
CONFIG = pk.APID_BY_NAME["cmd_config"].apid
RESET = pk.APID_BY_NAME["cmd_reset"].apid
PARAM_MODAL_PERIOD1 = 15  # cmd_config id (docs/LINK.md)
RESET_MODAL = 0x4  # cmd_reset target bit


@dataclass
class PlateHilConfig:
    images: int = 120
    dt_s: float = 60.0
    seed: int = 0
    faults: FaultConfig = field(default_factory=FaultConfig)
    prior_period_factor: float = 1.05
    answer_timeout_s: float = 0.5
    command_repeats: int = 3  # the modal configuration and reset, sent this often (a lost one is harmless)
    device: str | None = None  # a flight computer on this serial port instead of fsw_node on a pty
    baud: int = BAUD


def parse_tm_modal(p: pk.Packet) -> dict:
    v = p.values()
    return dict(
        t_s=p.t_s,
        image_id=v[0],
        status=v[1],
        decomposition=v[2],
        fused=bool(v[3]),
        n_modes=v[4],
        n_used=v[5],
        n_skipped=v[6],
        rcond=v[7],
        nis=v[8],
        omega_radps=np.array(v[9:19]),
        alpha_ps=np.array(v[19:29]),
        amplitude=np.array(v[29:39]),
        amplitude_sigma=np.array(v[39:49]),
    )


def plate_image_points(plate, sensor, coeffs, rng, noise_frac=0.03):
    """One ray-cast range image as the points the link carries: (n, 3)
    structure-frame points of the rays that hit, and each point's deflection
    1-sigma (the range noise projected on the vertical)."""
    r_meas, d = st.plate_range_image(plate, sensor, coeffs, rng, noise_frac=noise_frac)
    keep = np.isfinite(r_meas)
    p = sensor.pos_m[None, :] + r_meas[keep, None] * d[keep]
    sigma = np.abs(noise_frac * r_meas[keep] * d[keep, 2])
    return p, sigma


class _PlateLink:
    """The bench's end of the link during a plate run: sends in pieces,
    relaying between them, and collects the flight side's modal answers."""

    def __init__(self, link):
        self.link = link
        self.down = pk.Deframer(pk.FROM_FLIGHT)
        self.answers: dict = {}
        self.uplink = bytearray()  # every byte sent, for replay in-process

    def send(self, data: bytes) -> None:
        # In pieces, relaying between them: the relay runs in this thread and
        # a pty holds only a few kB, so one 30 kB write would block forever.
        self.uplink.extend(data)
        for i in range(0, len(data), 1024):
            self.link.write(data[i : i + 1024])
            self.link.pump(0.0)
            self.collect_now()

    def collect_now(self) -> None:
        data = self.link.read_available()
        for item in self.down.feed(data) if data else []:
            if isinstance(item, pk.Packet) and item.apid == TM_MODAL:
                m = parse_tm_modal(item)
                self.answers[m["image_id"]] = m

    def collect(self, deadline: float, want=None) -> bool:
        while True:
            self.link.pump(0.005)
            self.collect_now()
            if want is not None and want in self.answers:
                return True
            if time.perf_counter() >= deadline:
                return False


def _configure(io: _PlateLink, sender, plate, cfg: PlateHilConfig) -> None:
    """Tell the flight side the a priori lowest period and reset its modal
    tracker (repeated: the link may drop a command)."""
    period = float(2 * np.pi / plate.omega_radps[0]) * cfg.prior_period_factor
    for _ in range(cfg.command_repeats):
        io.send(
            sender.frame(CONFIG, 0.0, pk.pack_payload(CONFIG, PARAM_MODAL_PERIOD1, 0, period))
            + sender.frame(
                RESET, 0.0, pk.pack_payload(RESET, RESET_MODAL, 0, *[0.0] * 6, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            )
        )
    io.collect(time.perf_counter() + 0.05)


def run_plate_hil(cfg: PlateHilConfig, progress=None) -> dict:
    """Fly the plate's range images to fsw_node over the link, one image per
    step, and collect its modal answers with their latency."""
    rng = np.random.default_rng(cfg.seed)
    plate = st.Plate(n_modes=pk.MODAL_TM_MODES)
    sensor = st.plate_sensor(plate)
    amp, phase = st.plate_truth(plate, rng)
    link = open_link(faults_up=cfg.faults, faults_down=cfg.faults, seed=cfg.seed, device=cfg.device, baud=cfg.baud)
    sender, io = pk.Sender(), _PlateLink(link)
    latency, points_sent, truth = [], [], []
    wall0 = time.perf_counter()
    try:
        _configure(io, sender, plate, cfg)
        for k in range(cfg.images):
            t = k * cfg.dt_s
            coeffs = st.plate_coeffs(plate, amp, phase, t)
            p, sigma = plate_image_points(plate, sensor, coeffs, rng)
            data = b"".join(sender.frame(SEG, t, pl, seq_flags=f) for f, pl in pk.range_image_segments(k, p, sigma))
            t0 = time.perf_counter()
            io.send(data)
            io.collect(t0 + cfg.answer_timeout_s, want=k)
            latency.append(time.perf_counter() - t0)
            points_sent.append(len(p))
            truth.append(coeffs)
            if progress and (k + 1) % 20 == 0:
                progress(k + 1, cfg.images)
        io.collect(time.perf_counter() + cfg.answer_timeout_s)
    finally:
        wall = time.perf_counter() - wall0
        ended = link.close()
    return dict(
        plate=plate,
        amp=amp,
        phase=phase,
        answers=io.answers,
        points_sent=np.array(points_sent),
        truth=np.array(truth),
        latency_s=np.array(latency),
        wall_s=wall,
        uplink=bytes(io.uplink),
        bytes_up=link.bytes_up,
        bytes_down=link.bytes_down,
        faults_up=link.up.counts.__dict__,
        faults_down=link.down.counts.__dict__,
        bench_rejected_by_reason=dict(io.down.rejected),
        fsw_node_exit_code=ended["exit_code"],
        fsw_node_summary=ended["stderr"].strip(),
        cfg=cfg,
    )


def plate_hil_summary(res: dict) -> dict:
    """What a reader checks: images answered and fused, points lost to the
    link, and the final frequencies of the well-excited modes."""
    cfg, ans, plate = res["cfg"], res["answers"], res["plate"]
    n = cfg.images
    sent = res["points_sent"]
    used = np.array([ans[k]["n_used"] if k in ans else 0 for k in range(n)])
    fused = sum(1 for k in range(n) if k in ans and ans[k]["fused"])
    last = ans[max(ans)] if ans else None
    strong = res["amp"] >= 0.2
    w_true = plate.omega_radps
    rel = (last["omega_radps"] / w_true - 1) if last is not None else np.full(len(w_true), np.nan)
    lat = res["latency_s"] * 1e3
    return {
        "images_sent": n,
        "images_answered": len([k for k in range(n) if k in ans]),
        "images_fused": fused,
        "images_with_points_lost": int(np.sum(used < sent)),
        "points_sent": int(sent.sum()),
        "points_used": int(used.sum()),
        "lowest_mode_periods": float(n * cfg.dt_s * w_true[0] / (2 * np.pi)),
        "prior_frequency_error": float(1 / cfg.prior_period_factor - 1),
        "strong_modes": [int(i) for i in np.nonzero(strong)[0]],
        "final_frequency_rel_error": [float(x) for x in rel],
        "strong_modes_within_1pct": int(np.sum(np.abs(rel[strong]) < 0.01)),
        "answer_latency_p50_ms": float(np.percentile(lat, 50)) if len(lat) else float("nan"),
        "answer_latency_p99_ms": float(np.percentile(lat, 99)) if len(lat) else float("nan"),
        "bytes_up": res["bytes_up"],
        "bytes_down": res["bytes_down"],
        "faults_up": res["faults_up"],
        "faults_down": res["faults_down"],
        "bench_rejected_by_reason": res["bench_rejected_by_reason"],
        "wall_s": res["wall_s"],
        "fsw_node_exit_code": res["fsw_node_exit_code"],
        "fsw_node_summary": res["fsw_node_summary"],
    }
