"""The navigation filter behind the serial link, with the same interface as
the in-process ``fsw_bindings.NavUkf`` (init / predict / update_pose /
state() / P), so a bench scenario runs unchanged over the HIL loop.

Lockstep: every call sends its packet and waits until the flight software's
answer for that step (tm_innovation, tm_estimate, tm_covariance_diag) has
arrived, or until ``step_timeout_s`` passes (a packet lost on a faulty link).
Packets are built and parsed with hil_sim/packets.py (PyPI packages only).

What crosses the link: the pose covariance travels as one position sigma
and one attitude sigma (docs/LINK.md), so R and P0 must be isotropic per
block; telemetry carries the covariance diagonal only, so ``P`` here is
diagonal (NEES over the link uses that diagonal).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from hil_sim import packets as pk
from hil_sim.pty_link import PtyLink

STATUS_NAMES = ("ok", "gated", "not_pos_def", "bad_input")
_KIND_POSE = 1  # StepKind::PoseUpdate (fsw/include/fsw/app/flight_app.hpp)
_IMU = pk.APID_BY_NAME["imu_sample"].apid
_POSE = pk.APID_BY_NAME["led_pose"].apid
_RESET = pk.APID_BY_NAME["cmd_reset"].apid
_CONFIG = pk.APID_BY_NAME["cmd_config"].apid
_EST = pk.APID_BY_NAME["tm_estimate"].apid
_COV = pk.APID_BY_NAME["tm_covariance_diag"].apid
_INN = pk.APID_BY_NAME["tm_innovation"].apid
_LINKC = pk.APID_BY_NAME["tm_link_counters"].apid
_HK = pk.APID_BY_NAME["tm_housekeeping"].apid
_VALVES = pk.APID_BY_NAME["thruster_valves"].apid
_LEARNER = pk.APID_BY_NAME["tm_learner"].apid


@dataclass
class LinkRecord:
    """The step record as telemetry carries it (innovation covariance is not
    transmitted: NaN)."""

    status: str = "bad_input"
    fused: bool = False
    innovation: np.ndarray = field(default_factory=lambda: np.zeros(6))
    innovation_cov: np.ndarray = field(default_factory=lambda: np.full((6, 6), np.nan))
    nis: float = 0.0
    log_likelihood: float = 0.0
    step_index: int = -1
    received: bool = False  # False: the answer was lost on the link


def _isotropic_sigma(block: np.ndarray, name: str) -> float:
    d = np.diag(block)
    off = block - np.diag(d)
    if np.any(off != 0.0) or not np.allclose(d, d[0], rtol=1e-12, atol=0.0):
        raise ValueError(f"{name}: must be a multiple of the identity to cross the link (docs/LINK.md)")
    return math.sqrt(d[0])


class LinkNav:
    def __init__(self, link: PtyLink, step_timeout_s: float = 0.05, send_valves: bool = False):
        self.link = link
        self.send_valves = send_valves
        self.step_timeout_s = step_timeout_s
        self.sender = pk.Sender()
        self.deframer = pk.Deframer(pk.FROM_FLIGHT)
        self._est = np.full(10, np.nan)
        self._p_diag = np.full(9, np.nan)
        self._last_step_index = 0
        self._pending_record = None
        self.t_s = float("nan")
        self.timeouts = 0
        self.packets_sent = 0
        self.step_latency_s: list = []
        self.reset_attempts = 50
        self.time_offset_s = 0.0  # added to every outgoing time tag (chained runs)
        self.delivered_not_sent = 0  # telemetry packets delivered that the flight side never sent
        self.link_counters = None  # last tm_link_counters: accepted, frames, gaps, duplicates, rejected[...]
        self.housekeeping = None  # last tm_housekeeping as a dict (packets.decode_housekeeping)
        self.learner_outputs: list = []  # (t_s, tm_learner values): the flight learner's prediction per firing
        self.deferred_pose_results: list = []  # (status, fused) of poses fused after a later predict
        # Poses not sent: their covariance came from an estimate the link never
        # brought back (NaN), so there was no sigma to send.
        self.poses_not_sent = 0
        self._current_apid = None
        self._tx = b""  # framed packets held for the next write

    # -- interface of fsw_bindings.NavUkf --------------------------------
    def init(self, t_s, r_hill_m, v_hill_mps, q_hb, P0):
        P0 = np.asarray(P0, float)
        sig = [_isotropic_sigma(P0[i : i + 3, i : i + 3], f"P0[{i}:{i + 3}]") for i in (0, 3, 6)]
        if np.any(P0 - np.diag(np.diag(P0))):
            raise ValueError("P0: must be block diagonal to cross the link")
        payload = pk.pack_payload(
            _RESET, 0x1, 0, *np.asarray(r_hill_m, float), *np.asarray(v_hill_mps, float), *np.asarray(q_hb, float), *sig
        )
        # A telecommand whose answer is lost is sent again (re-initialising
        # at the same time is harmless); the bench needs a first estimate and
        # covariance from this reset, not ones left from an earlier run.
        self._est[:] = np.nan
        self._p_diag[:] = np.nan
        # The flight side starts a new time base at a reset (docs/LINK.md):
        # its telemetry may now be tagged earlier than before.
        self.deframer.reset_time_history()
        for _ in range(self.reset_attempts):
            rec = self._step(_RESET, t_s, payload)
            if rec.received or np.any(np.isfinite(self._est)) or np.any(np.isfinite(self._p_diag)):
                break  # the flight side has the reset (part of its answer came back)
        # Whatever of the answer was lost is what the reset set: the commanded
        # state (quaternion normalised) and the diagonal of P0.
        if rec.received or np.any(np.isfinite(self._est)) or np.any(np.isfinite(self._p_diag)):
            if not np.all(np.isfinite(self._est)):
                q = np.asarray(q_hb, float)
                self._est = np.concatenate(
                    [np.asarray(r_hill_m, float), np.asarray(v_hill_mps, float), q / np.linalg.norm(q)]
                )
            if not np.all(np.isfinite(self._p_diag)):
                self._p_diag = np.diag(P0).copy()
        return rec

    def predict(self, t_s, accel_b_mps2, omega_bi_b_rps):
        payload = pk.pack_payload(_IMU, *np.asarray(accel_b_mps2, float), *np.asarray(omega_bi_b_rps, float))
        return self._step(_IMU, t_s, payload)

    def update_pose(self, t_capture_s, r_hill_m, q_hb, R):
        R = np.asarray(R, float)
        if not np.all(np.isfinite(R)):
            self.poses_not_sent += 1
            return LinkRecord()
        r_sigma = _isotropic_sigma(R[0:3, 0:3], "R[0:3, 0:3]")
        a_sigma = _isotropic_sigma(R[3:6, 3:6], "R[3:6, 3:6]")
        payload = pk.pack_payload(_POSE, *np.asarray(r_hill_m, float), *np.asarray(q_hb, float), r_sigma, a_sigma)
        return self._step(_POSE, t_capture_s, payload)

    def note_valves(self, t_s: float, interval_s: float, mask: int):
        """thruster_valves for the firing interval starting at t_s (no answer
        expected; the IMU sample that ends the interval brings tm_learner)."""
        if mask and self.send_valves:
            self._send(_VALVES, t_s, pk.pack_payload(_VALVES, float(interval_s), int(mask)), hold=True)

    def configure(self, param_id: int, value: float, t_s: float = 0.0):
        """cmd_config (no answer expected)."""
        self._send(_CONFIG, t_s, pk.pack_payload(_CONFIG, param_id, 0, value))

    # cmd_config parameter ids (fsw/include/fsw/app/flight_app.hpp, docs/LINK.md)
    NAV_PARAMS = {
        "accel_sigma_mps2": 4,
        "gyro_sigma_rps": 5,
        "gate_chi2": 6,
        "max_delay_s": 7,
        "n_radps": 8,
        "dt_imu_s": 9,
    }

    def configure_nav(self, nav_config, t_s: float = 0.0):
        """Sends the filter settings of an fsw_bindings.NavConfig; the flight
        side applies them at the next init (cmd_reset)."""
        for name, pid in self.NAV_PARAMS.items():
            self.configure(pid, float(getattr(nav_config, name)), t_s)

    def state(self):
        return self._est.copy()

    @property
    def P(self):
        return np.diag(self._p_diag)

    @property
    def r_hill_m(self):
        return self._est[0:3].copy()

    @property
    def v_hill_mps(self):
        return self._est[3:6].copy()

    @property
    def q_hb(self):
        return self._est[6:10].copy()

    # -- link -------------------------------------------------------------
    def _send(self, apid, t_s, payload, hold: bool = False):
        """Frames and writes one packet; hold=True keeps it to go out in the
        same write as the next packet (one pass through the link, not two)."""
        self._tx += self.sender.frame(apid, float(t_s) + self.time_offset_s, payload)
        self.packets_sent += 1
        if not hold:
            self.link.write(self._tx)
            self._tx = b""

    def _step(self, apid, t_s, payload) -> LinkRecord:
        t0 = time.perf_counter()
        self._current_apid = apid
        self._send(apid, t_s, payload)
        rec = LinkRecord()
        deadline = t0 + self.step_timeout_s
        done = False
        while not done:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                self.timeouts += 1
                break
            self.link.pump(min(remaining, 0.01))
            data = self.link.read_available()
            if not data:
                continue
            for item in self.deframer.feed(data):
                if isinstance(item, pk.Rejection):
                    continue
                if (
                    not self.link.down.cfg.clean
                    and pk.frame(item.raw + pk.crc16(item.raw).to_bytes(2, "big")) not in self.link.down.originals
                ):
                    self.delivered_not_sent += 1
                    continue
                done = self._on_packet(item, rec) or done
        self.step_latency_s.append(time.perf_counter() - t0)
        if rec.received:
            self.t_s = float(t_s) if apid != _POSE else self.t_s
        return rec

    def _on_packet(self, p, rec: LinkRecord) -> bool:
        """Updates the estimate; True when this step's answer is complete."""
        v = p.values()
        if p.apid == _INN:
            kind, status, fused, meas_dim, step_index = v[0:5]
            if kind == _KIND_POSE and self._current_apid != _POSE:
                # A pose that arrived before its IMU tick, fused by the flight
                # side after this step's predict: not this step's record.
                self.deferred_pose_results.append((status, bool(fused)))
                return False
            rec.status = STATUS_NAMES[status] if status < len(STATUS_NAMES) else "bad_input"
            rec.fused = bool(fused)
            rec.innovation = np.array(v[5:11])
            rec.nis, rec.log_likelihood = v[11], v[12]
            rec.step_index = step_index
            rec.received = True
            self._last_step_index = step_index
            # Nothing follows a step the filter could not take before initialisation.
            return bool(np.all(np.isnan(self._est))) and status != 0
        if p.apid == _EST:
            self._est = np.array(v, float)
            return False
        if p.apid == _COV:
            n_valid = v[0]
            self._p_diag = np.array(v[2 : 2 + n_valid], float)[:9]
            return rec.received  # the covariance closes a step's answer
        if p.apid == _LINKC:
            self.link_counters = v
            return False
        if p.apid == _HK:
            self.housekeeping = pk.decode_housekeeping(p.payload)
            return False
        if p.apid == _LEARNER:
            self.learner_outputs.append((p.t_s - self.time_offset_s, v))
            return False
        return False

    def rejected_by_reason(self) -> dict:
        """The flight side's rejection counters from the latest tm_link_counters."""
        if self.link_counters is None:
            return {}
        return {name: int(n) for name, n in zip(pk.REJECT_REASONS, self.link_counters[4:])}
