"""The serial link on the bench side, built only from PyPI packages.

Packets are CCSDS Space Packets (``spacepackets``), a CRC-16/CCITT-FALSE
(``crc``) appended big-endian, COBS-encoded (``cobs``) and ended by 0x00. This
module never calls the C++ framing: it is the independent implementation that
the cross-check tests compare against. The format is specified in
docs/LINK.md; the tables here are a second, hand-written copy of it.

Layout of every packet::

    primary header (6 bytes, big-endian) | time tag t_s (float64, little-endian)
    | payload (little-endian, exact length per APID) | CRC-16 (big-endian)
"""

from __future__ import annotations

import binascii
import math
import struct
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple, Union

import numpy as np
from cobs import cobs
from crc import Calculator, Configuration
from spacepackets.ccsds.spacepacket import (
    PacketType,
    SequenceFlags,
    SpacePacket,
    SpacePacketHeader,
)

# CRC-16/CCITT-FALSE (= CRC-16/IBM-3740): poly 0x1021, init 0xFFFF, no reflection, no final XOR.
CRC16_CCITT_FALSE = Configuration(
    width=16,
    polynomial=0x1021,
    init_value=0xFFFF,
    final_xor_value=0x0000,
    reverse_input=False,
    reverse_output=False,
)
CRC16_CHECK = 0x29B1  # over b"123456789"
_CRC = Calculator(CRC16_CCITT_FALSE, optimized=True)

PRIMARY_HEADER_SIZE = 6
SECONDARY_HEADER_SIZE = 8
PACKET_HEADER_SIZE = PRIMARY_HEADER_SIZE + SECONDARY_HEADER_SIZE
CRC_SIZE = 2
SEQ_MODULO = 1 << 14
QUAT_NORM_TOL = 1e-6

TO_FLIGHT = "to_flight"  # telecommand, type 1
FROM_FLIGHT = "from_flight"  # telemetry, type 0


@dataclass(frozen=True)
class ApidDef:
    apid: int
    name: str
    direction: str
    fmt: str  # struct format of the payload (little-endian)
    f64_offset: int
    f64_count: int
    quat_offset: Optional[int] = None
    segmentable: bool = False

    @property
    def payload_len(self) -> int:
        return struct.calcsize(self.fmt)

    @property
    def packet_type(self) -> PacketType:
        return PacketType.TC if self.direction == TO_FLIGHT else PacketType.TM


RANGE_POINTS_PER_SEGMENT = 24
PLAN_VALVES = 8  # valves a tm_plan_valves carries
# The valve plan (fsw/include/fsw/app/valve_plan.hpp): cmd_plan actions,
# PlanState and PlanVerdict by their codes.
PLAN_ACTIONS = {"load": 1, "start": 2, "abort": 3}
PLAN_STATES = ("empty", "loaded", "running", "finished", "aborted")
PLAN_VERDICTS = (
    "accepted",
    "incomplete",
    "too_long",
    "valve_out_of_range",
    "on_time_too_short",
    "on_time_too_long",
    "bad_times",
    "overlap",
    "total_on_time_too_long",
    "duration_too_long",
    "no_plan",
    "running",
    "not_running",
    "unknown_action",
)
MAX_RANGE_POINTS_PER_IMAGE = 4096
MODAL_TM_MODES = 10  # modes carried by tm_modal

# The APID table (docs/LINK.md).
APIDS: Dict[int, ApidDef] = {
    a.apid: a
    for a in [
        # accel_b_mps2[3], omega_bi_b_rps[3]
        ApidDef(0x010, "imu_sample", TO_FLIGHT, "<6d", 0, 6),
        # r_hill_m[3], q_hb_wxyz[4], r_sigma_m, att_sigma_rad
        ApidDef(0x011, "led_pose", TO_FLIGHT, "<9d", 0, 9, quat_offset=24),
        # interval_s, valve_mask, 7 reserved
        ApidDef(0x012, "thruster_valves", TO_FLIGHT, "<dB7x", 0, 1),
        # image_id, points_total, first_point, n_points, reserved, 24 x (p_m[3], sigma_m)
        ApidDef(0x013, "range_image_segment", TO_FLIGHT, "<IHHHH" + "d" * 96, 12, 96, segmentable=True),
        # target_mask, reserved, r_hill_m[3], v_hill_mps[3], q_hb_wxyz[4], pos/vel/att sigma
        ApidDef(0x020, "cmd_reset", TO_FLIGHT, "<II13d", 8, 13, quat_offset=56),
        # param_id, reserved, value
        ApidDef(0x021, "cmd_config", TO_FLIGHT, "<IId", 8, 1),
        # plan_id, entry_index, entry_count, valve, 7 reserved, t_open_s, t_close_s
        ApidDef(0x022, "cmd_plan_entry", TO_FLIGHT, "<IHHB7x2d", 16, 2),
        # action (1 load, 2 start, 3 abort), plan_id, entry_count, reserved, duration_s
        ApidDef(0x023, "cmd_plan", TO_FLIGHT, "<4Id", 16, 1),
        # r_hill_m[3], v_hill_mps[3], q_hb_wxyz[4]
        ApidDef(0x040, "tm_estimate", FROM_FLIGHT, "<10d", 0, 10, quat_offset=48),
        # n_valid, reserved, p_diag[15]
        ApidDef(0x041, "tm_covariance_diag", FROM_FLIGHT, "<II15d", 8, 15),
        # step_kind, status, fused, meas_dim, step_index, innovation[6], nis, log_likelihood
        ApidDef(0x042, "tm_innovation", FROM_FLIGHT, "<BBBBI8d", 8, 8),
        # n_samples, status, dv_b_mps[3], dw_b_rps[3], variance[6]
        ApidDef(0x043, "tm_learner", FROM_FLIGHT, "<II12d", 8, 12),
        # packets_accepted, frames_total, seq_gaps_total, duplicates_total, rejected[28]
        ApidDef(0x044, "tm_link_counters", FROM_FLIGHT, "<32I", 0, 0),
        # uptime_s, last_step_cpu_s, max_step_cpu_s, cycle_count, mode, tx_packets, tx_dropped
        ApidDef(0x045, "tm_housekeeping", FROM_FLIGHT, "<3d4I", 0, 3),
        # image_id, status, decomposition, fused, n_modes, n_used, n_skipped, rcond, nis,
        # omega_radps[10], alpha_ps[10], amplitude[10], amplitude_sigma[10]
        ApidDef(0x046, "tm_modal", FROM_FLIGHT, "<IBBBBII42d", 16, 42),
        # plan_id, state, action, verdict, reserved, entry_count, entries_received, plans_loaded,
        # commands_refused, duration_s, total_on_time_s
        ApidDef(0x047, "tm_plan_status", FROM_FLIGHT, "<IBBBx4I2d", 24, 2),
        # plan_id, valve_mask, state, reserved, interval_s, plan_time_s, on_time_s[8]
        ApidDef(0x048, "tm_plan_valves", FROM_FLIGHT, "<IBBH10d", 8, 10),
    ]
}
APID_BY_NAME: Dict[str, ApidDef] = {a.name: a for a in APIDS.values()}
MAX_PAYLOAD_LEN = max(a.payload_len for a in APIDS.values())
MAX_PACKET_WITH_CRC = PACKET_HEADER_SIZE + MAX_PAYLOAD_LEN + CRC_SIZE
MAX_FRAME_LEN = MAX_PACKET_WITH_CRC + MAX_PACKET_WITH_CRC // 254 + 1  # COBS bytes, without 0x00

# Stable rejection names, in the order of their numeric codes (tm_link_counters slots).
REJECT_REASONS: Tuple[str, ...] = (
    "empty_frame",
    "frame_too_long",
    "cobs_error",
    "too_short",
    "bad_crc",
    "wrong_version",
    "wrong_type",
    "wrong_secondary_header_flag",
    "length_field_too_long",
    "length_field_too_short",
    "unknown_apid",
    "wrong_sequence_flags",
    "wrong_payload_length",
    "bad_time_tag",
    "duplicate_sequence",
    "time_backwards",
    "stale_sequence",
    "non_finite_payload",
    "non_unit_quaternion",
    "invalid_field",
)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data``: the standard library's
    ``binascii.crc_hqx`` (CRC-CCITT, poly 0x1021, no reflection) started at
    0xFFFF, in compiled code; ``crc16_reference`` is the pure-Python ``crc``
    package, and the tests hold the two equal."""
    return binascii.crc_hqx(bytes(data), 0xFFFF)


def crc16_reference(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` with the ``crc`` package."""
    return _CRC.checksum(bytes(data))


# ----------------------------------------------------------------------------- build


def build_packet(
    apid: int,
    seq_count: int,
    t_s: float,
    payload: bytes,
    seq_flags: SequenceFlags = SequenceFlags.UNSEGMENTED,
    packet_type: Optional[PacketType] = None,
) -> bytes:
    """Packet bytes with the CRC appended. ``packet_type`` defaults to the APID's direction."""
    if packet_type is None:
        packet_type = APIDS[apid].packet_type
    sec = struct.pack("<d", t_s)
    header = SpacePacketHeader(
        packet_type=packet_type,
        apid=apid,
        seq_count=seq_count % SEQ_MODULO,
        data_len=len(sec) + len(payload) - 1,
        sec_header_flag=True,
        seq_flags=seq_flags,
    )
    body = bytes(SpacePacket(header, sec_header=sec, user_data=bytes(payload)).pack())
    return body + crc16(body).to_bytes(2, "big")


def frame(packet_with_crc: bytes) -> bytes:
    """COBS-encode and append the 0x00 delimiter."""
    return cobs.encode(bytes(packet_with_crc)) + b"\x00"


def build_frame(apid: int, seq_count: int, t_s: float, payload: bytes, **kw) -> bytes:
    return frame(build_packet(apid, seq_count, t_s, payload, **kw))


def pack_payload(apid: int, *values) -> bytes:
    """Payload bytes from the APID's struct fields, in table order."""
    return struct.pack(APIDS[apid].fmt, *values)


def unpack_payload(apid: int, payload: bytes) -> tuple:
    return struct.unpack(APIDS[apid].fmt, payload)


def range_image_segments(image_id: int, p_m, sigma_m):
    """One range image as range_image_segment payloads: [(seq_flags, payload)]
    of up to RANGE_POINTS_PER_SEGMENT points each (docs/LINK.md,
    "Segmentation"). p_m: (n, 3) points in the structure frame [m], all finite;
    sigma_m: (n,) 1-sigma of each point's deflection [m] (0 = not given)."""
    p_arr = np.asarray(p_m, float)
    s_arr = np.asarray(sigma_m, float)
    n = len(p_arr)
    if p_arr.ndim != 2 or p_arr.shape[1] != 3:
        raise ValueError(f"range image: p_m must be (n, 3), got shape {p_arr.shape}")
    if not 1 <= n <= MAX_RANGE_POINTS_PER_IMAGE or s_arr.shape != (n,):
        raise ValueError(f"range image: {n} points and {s_arr.size} sigmas (1..{MAX_RANGE_POINTS_PER_IMAGE}, equal)")
    bad = np.nonzero(~np.isfinite(p_arr).all(axis=1) | ~(s_arr >= 0))[0]
    if len(bad):
        raise ValueError(
            f"range image: point {bad[0]} is not finite or has a negative sigma "
            f"(p_m {p_arr[bad[0]].tolist()}, sigma_m {s_arr[bad[0]]}); leave missing points out"
        )
    p_m = [tuple(p) for p in p_arr.tolist()]
    sigma_m = s_arr.tolist()
    k = RANGE_POINTS_PER_SEGMENT
    n_seg = (n + k - 1) // k
    out = []
    for s in range(n_seg):
        pts = p_m[s * k : (s + 1) * k]
        sig = sigma_m[s * k : (s + 1) * k]
        vals = []
        for i in range(k):
            vals += [*pts[i], sig[i]] if i < len(pts) else [0.0] * 4
        flags = (
            SequenceFlags.UNSEGMENTED
            if n_seg == 1
            else SequenceFlags.FIRST_SEGMENT
            if s == 0
            else SequenceFlags.LAST_SEGMENT
            if s == n_seg - 1
            else SequenceFlags.CONTINUATION_SEGMENT
        )
        out.append((flags, pack_payload(0x013, image_id, n, s * k, len(pts), 0, *vals)))
    return out


def plan_entry_payloads(plan_id: int, entries) -> list:
    """A valve plan's cmd_plan_entry payloads, one per opening, in order.
    entries: [(valve, t_open_s, t_close_s)] from the plan's start, ordered
    by t_open_s (the flight side refuses them otherwise)."""
    n = len(entries)
    if not 1 <= n <= 0xFFFF:
        raise ValueError(f"a plan holds 1 to 65535 entries on the link, not {n}")
    apid = APID_BY_NAME["cmd_plan_entry"].apid
    return [pack_payload(apid, plan_id, i, n, int(v), float(a), float(b)) for i, (v, a, b) in enumerate(entries)]


def plan_command_payload(action: str, plan_id: int, entry_count: int = 0, duration_s: float = 0.0) -> bytes:
    """cmd_plan: action "load" (with the entry count and the plan's
    duration), "start" (at the packet's time tag) or "abort"."""
    return pack_payload(APID_BY_NAME["cmd_plan"].apid, PLAN_ACTIONS[action], plan_id, entry_count, 0, float(duration_s))


PLAN_STATUS_FIELDS = (
    "plan_id",
    "state",
    "action",
    "verdict",
    "entry_count",
    "entries_received",
    "plans_loaded",
    "commands_refused",
    "duration_s",
    "total_on_time_s",
)


def decode_plan_status(payload: bytes) -> dict:
    """tm_plan_status as named fields, state and verdict by name."""
    d = dict(zip(PLAN_STATUS_FIELDS, unpack_payload(APID_BY_NAME["tm_plan_status"].apid, payload)))
    d["state"] = PLAN_STATES[d["state"]]
    d["verdict"] = PLAN_VERDICTS[d["verdict"]]
    return d


def decode_plan_valves(payload: bytes) -> dict:
    """tm_plan_valves: the plan's valve command for one control interval."""
    v = unpack_payload(APID_BY_NAME["tm_plan_valves"].apid, payload)
    return {
        "plan_id": v[0],
        "valve_mask": v[1],
        "state": PLAN_STATES[v[2]],
        "interval_s": v[4],
        "plan_time_s": v[5],
        "on_time_s": list(v[6:]),
    }


class Sender:
    """Keeps the per-APID 14-bit sequence counts of one direction."""

    def __init__(self) -> None:
        self.next_seq: Dict[int, int] = {}

    def frame(
        self, apid: int, t_s: float, payload: bytes, seq_flags: SequenceFlags = SequenceFlags.UNSEGMENTED
    ) -> bytes:
        seq = self.next_seq.get(apid, 0)
        self.next_seq[apid] = (seq + 1) % SEQ_MODULO
        return build_frame(apid, seq, t_s, payload, seq_flags=seq_flags)


# ----------------------------------------------------------------------------- parse

HOUSEKEEPING_FIELDS = (
    "uptime_s",
    "last_step_cpu_s",
    "max_step_cpu_s",
    "cycle_count",
    "mode",
    "tx_packets",
    "tx_dropped",
)


def decode_housekeeping(payload: bytes) -> dict:
    """tm_housekeeping as named fields; tx_dropped counts the telemetry
    packets the flight side could not queue (its transmit buffer was full:
    the ground was not reading, or a burst outran the port)."""
    return dict(zip(HOUSEKEEPING_FIELDS, unpack_payload(APID_BY_NAME["tm_housekeeping"].apid, payload)))


@dataclass
class Packet:
    header: SpacePacketHeader
    t_s: float
    payload: bytes
    raw: bytes  # header .. payload, without the CRC

    @property
    def apid(self) -> int:
        return self.header.apid

    def values(self) -> tuple:
        return unpack_payload(self.apid, self.payload)


@dataclass
class Rejection:
    reason: str
    apid: Optional[int] = None


def _range_segment_ok(payload: bytes, flags: SequenceFlags) -> bool:
    image_id, total, first, n, _ = struct.unpack_from("<IHHHH", payload, 0)
    if total == 0 or total > 4096 or n > RANGE_POINTS_PER_SEGMENT or first + n > total:
        return False
    starts, ends = first == 0, first + n == total
    ok = {
        SequenceFlags.UNSEGMENTED: starts and ends,
        SequenceFlags.FIRST_SEGMENT: starts and not ends,
        SequenceFlags.CONTINUATION_SEGMENT: not starts and not ends,
        SequenceFlags.LAST_SEGMENT: ends and not starts,
    }[flags]
    sigmas = struct.unpack_from("<" + "d" * 96, payload, 12)[3::4]
    return ok and all(s >= 0.0 for s in sigmas[:n])


_FIELD_CHECKED = frozenset(
    (
        "led_pose",
        "thruster_valves",
        "range_image_segment",
        "cmd_reset",
        "tm_covariance_diag",
        "tm_innovation",
        "tm_modal",
        "tm_plan_status",
        "tm_plan_valves",
    )
)


def _fields_ok(a: ApidDef, flags: SequenceFlags, payload: bytes) -> bool:
    if a.name not in _FIELD_CHECKED:
        return True
    v = struct.unpack(a.fmt, payload) if a.name != "range_image_segment" else None
    if a.name == "led_pose":
        return v[7] >= 0.0 and v[8] >= 0.0
    if a.name == "thruster_valves":
        return v[0] >= 0.0
    if a.name == "range_image_segment":
        return _range_segment_ok(payload, flags)
    if a.name == "cmd_reset":
        return min(v[12:15]) >= 0.0
    if a.name == "tm_covariance_diag":
        return v[0] <= 15
    if a.name == "tm_innovation":
        return v[1] <= 3 and v[3] <= 6
    if a.name == "tm_modal":
        return v[1] <= 3 and v[2] <= 3 and v[4] <= MODAL_TM_MODES
    if a.name == "tm_plan_status":
        return v[1] < len(PLAN_STATES) and v[3] < len(PLAN_VERDICTS)
    if a.name == "tm_plan_valves":
        return v[2] < len(PLAN_STATES)
    return True


class Deframer:
    """Streaming deframer with the same checks in the same order as the flight
    side (docs/LINK.md), for the direction this end receives."""

    def __init__(self, accept: str = FROM_FLIGHT) -> None:
        self.accept = accept
        self._buf = bytearray()
        self._discarding = False
        self.rejected: Dict[str, int] = {r: 0 for r in REJECT_REASONS}
        self.accepted = 0
        self.gaps: Dict[int, int] = {}
        self._last: Dict[int, Tuple[int, float]] = {}

    def feed(self, data: bytes) -> List[Union[Packet, Rejection]]:
        out: List[Union[Packet, Rejection]] = []
        pieces = bytes(data).split(b"\x00")
        for i, piece in enumerate(pieces):
            last = i == len(pieces) - 1  # no 0x00 after it yet
            if not self._discarding:
                room = MAX_FRAME_LEN - len(self._buf)
                if len(piece) > room:
                    self._discarding = True
                    self._buf.clear()
                    out.append(self._reject("frame_too_long"))
                else:
                    self._buf += piece
            if last:
                break
            if self._discarding:
                self._discarding = False
            else:
                out.append(self._frame(bytes(self._buf)))
            self._buf.clear()
        return out

    def reset_time_history(self) -> None:
        """Forgets every APID's last time tag, keeping the sequence counts
        (the flight side does this on a carried-out cmd_reset)."""
        self._last = {a: (seq, -math.inf) for a, (seq, _) in self._last.items()}

    def _reject(self, reason: str, apid: Optional[int] = None) -> Rejection:
        self.rejected[reason] += 1
        return Rejection(reason, apid)

    def _frame(self, enc: bytes) -> Union[Packet, Rejection]:
        if not enc:
            return self._reject("empty_frame")
        try:
            dec = cobs.decode(enc)
        except cobs.DecodeError:
            return self._reject("cobs_error")
        if len(dec) < PACKET_HEADER_SIZE + CRC_SIZE:
            return self._reject("too_short")
        body = dec[:-2]
        if crc16(body) != int.from_bytes(dec[-2:], "big"):
            return self._reject("bad_crc")
        h = SpacePacketHeader.unpack(body)
        want_type = PacketType.TC if self.accept == TO_FLIGHT else PacketType.TM
        if h.ccsds_version != 0:
            return self._reject("wrong_version")
        if h.packet_type != want_type:
            return self._reject("wrong_type")
        if not h.sec_header_flag:
            return self._reject("wrong_secondary_header_flag")
        if h.packet_len > len(body):
            return self._reject("length_field_too_long")
        if h.packet_len < len(body):
            return self._reject("length_field_too_short")
        a = APIDS.get(h.apid)
        if a is None or a.direction != self.accept:
            return self._reject("unknown_apid", h.apid)
        if not a.segmentable and h.seq_flags != SequenceFlags.UNSEGMENTED:
            return self._reject("wrong_sequence_flags", h.apid)
        payload = body[PACKET_HEADER_SIZE:]
        if len(payload) != a.payload_len:
            return self._reject("wrong_payload_length", h.apid)
        (t_s,) = struct.unpack_from("<d", body, PRIMARY_HEADER_SIZE)
        if not math.isfinite(t_s):
            return self._reject("bad_time_tag", h.apid)
        last = self._last.get(h.apid)
        missing = 0  # counted, like the history, only for an accepted packet
        if last is not None:
            delta = (h.seq_count - last[0]) % SEQ_MODULO
            if delta == 0:
                return self._reject("duplicate_sequence", h.apid)
            if t_s < last[1]:
                return self._reject("time_backwards", h.apid)
            if delta >= SEQ_MODULO // 2:
                if not t_s > last[1]:
                    return self._reject("stale_sequence", h.apid)
            else:
                missing = delta - 1
        f64 = struct.unpack_from("<%dd" % a.f64_count, payload, a.f64_offset)
        if not all(math.isfinite(x) for x in f64):
            return self._reject("non_finite_payload", h.apid)
        if a.quat_offset is not None:
            q = struct.unpack_from("<4d", payload, a.quat_offset)
            if not abs(math.sqrt(sum(c * c for c in q)) - 1.0) <= QUAT_NORM_TOL:
                return self._reject("non_unit_quaternion", h.apid)
        if not _fields_ok(a, h.seq_flags, payload):
            return self._reject("invalid_field", h.apid)
        if missing:
            self.gaps[h.apid] = self.gaps.get(h.apid, 0) + missing
        self._last[h.apid] = (h.seq_count, t_s)
        self.accepted += 1
        return Packet(header=h, t_s=t_s, payload=bytes(payload), raw=bytes(body))


def parse_frame(frame_bytes: bytes, accept: str) -> Union[Packet, Rejection]:
    """Parse one complete frame (with or without its trailing 0x00), stateless."""
    d = Deframer(accept)
    data = bytes(frame_bytes)
    if not data.endswith(b"\x00"):
        data += b"\x00"
    res = d.feed(data)
    return res[0] if len(res) == 1 else Rejection("cobs_error")
