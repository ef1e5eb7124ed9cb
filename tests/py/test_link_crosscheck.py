"""Cross-check of the flight framing (C++, through the bindings) against the
independent bench implementation (hil_sim.packets: spacepackets, cobs, crc)."""

import math
import random
import struct

import pytest
from cobs import cobs
from crc import Calculator, Crc16
from spacepackets.ccsds.spacepacket import PacketType, SequenceFlags, SpacePacketHeader

from hil_sim import packets as P

fb = pytest.importorskip("fsw_bindings")
if not hasattr(fb, "LinkDeframer"):
    pytest.skip("fsw_bindings built without the link bindings", allow_module_level=True)


def valid_payload(a: P.ApidDef, rng: random.Random, first=0, n=None, total=None) -> bytes:
    """A random payload of APID a that passes every check."""
    buf = bytearray(a.payload_len)
    for i in range(a.f64_count):
        struct.pack_into("<d", buf, a.f64_offset + 8 * i, rng.gauss(0.0, 10.0))
    if a.quat_offset is not None:
        q = [rng.gauss(0, 1) for _ in range(4)]
        nq = math.sqrt(sum(c * c for c in q))
        struct.pack_into("<4d", buf, a.quat_offset, *[c / nq for c in q])
    if a.name == "led_pose":
        struct.pack_into("<2d", buf, 56, abs(rng.gauss(0, 0.1)), abs(rng.gauss(0, 0.01)))
    elif a.name == "thruster_valves":
        struct.pack_into("<dB", buf, 0, rng.uniform(0, 1), rng.randrange(256))
    elif a.name == "range_image_segment":
        n = P.RANGE_POINTS_PER_SEGMENT if n is None else n
        total = n if total is None else total
        struct.pack_into("<IHHH", buf, 0, rng.randrange(2**32), total, first, n)
        for i in range(P.RANGE_POINTS_PER_SEGMENT):
            struct.pack_into("<d", buf, 12 + 32 * i + 24, abs(rng.gauss(0, 0.05)))
    elif a.name == "cmd_reset":
        struct.pack_into("<II", buf, 0, rng.randrange(16), 0)
        struct.pack_into("<3d", buf, 88, 0.1, 0.01, 0.05)
    elif a.name == "cmd_config":
        struct.pack_into("<I", buf, 0, rng.randrange(8))
    elif a.name == "tm_covariance_diag":
        struct.pack_into("<I", buf, 0, rng.choice([9, 15]))
    elif a.name == "tm_innovation":
        struct.pack_into(
            "<BBBBI", buf, 0, rng.randrange(2), rng.randrange(4), rng.randrange(2), 6, rng.randrange(2**32)
        )
    elif a.name == "tm_modal":
        struct.pack_into(
            "<IBBBBII",
            buf,
            0,
            rng.randrange(2**32),
            rng.randrange(4),
            rng.randrange(4),
            rng.randrange(2),
            rng.choice([0, 10]),
            rng.randrange(2**32),
            rng.randrange(2**32),
        )
    elif a.name == "cmd_plan_entry":
        struct.pack_into("<IHHB", buf, 0, rng.randrange(2**32), 3, 7, rng.randrange(8))
    elif a.name == "cmd_plan":
        struct.pack_into("<III", buf, 0, rng.randrange(1, 4), rng.randrange(2**32), rng.randrange(129))
    elif a.name == "tm_plan_status":
        struct.pack_into("<IBBB", buf, 0, rng.randrange(2**32), rng.randrange(5), rng.randrange(4), rng.randrange(14))
    elif a.name == "tm_plan_valves":
        struct.pack_into("<IBB", buf, 0, rng.randrange(2**32), rng.randrange(256), rng.randrange(5))
    elif a.name in ("tm_learner", "tm_housekeeping"):
        pass
    elif a.name == "tm_link_counters":
        struct.pack_into("<32I", buf, 0, *[rng.randrange(2**32) for _ in range(32)])
    return bytes(buf)


# ----------------------------------------------------------------------------- CRC and COBS


def test_crc_check_value_python_side():
    assert P.crc16(b"123456789") == 0x29B1 == P.CRC16_CHECK
    assert P.crc16_reference(b"123456789") == 0x29B1
    # The explicit configuration is the catalogue's CRC-16/IBM-3740 (alias CCITT-FALSE).
    assert Calculator(Crc16.IBM_3740).checksum(b"123456789") == 0x29B1


def test_crc_check_value_cpp_side():
    assert fb.link_crc16(b"123456789") == 0x29B1


def test_crc_agrees_on_random_data():
    rng = random.Random(11)
    for _ in range(200):
        d = bytes(rng.randrange(256) for _ in range(rng.randrange(900)))
        assert fb.link_crc16(d) == P.crc16(d) == P.crc16_reference(d)


def test_cobs_encoding_identical_to_pypi():
    rng = random.Random(12)
    cases = [b"", b"\x00", b"\x01" * 254, b"\x01" * 255, b"\x01" * 508, b"\x01" * 254 + b"\x00", b"\x00" * 300]
    cases += [bytes(rng.choice([0, rng.randrange(256)]) for _ in range(rng.randrange(1200))) for _ in range(200)]
    for d in cases:
        assert fb.link_cobs_encode(d) == cobs.encode(d)


# ----------------------------------------------------------------------------- tables


def test_apid_tables_agree():
    cpp = {r["apid"]: r for r in fb.link_apid_table()}
    assert set(cpp) == set(P.APIDS)
    for apid, a in P.APIDS.items():
        r = cpp[apid]
        assert (r["name"], r["direction"], r["payload_len"], r["segmentable"]) == (
            a.name,
            a.direction,
            a.payload_len,
            a.segmentable,
        ), a.name
        assert (r["f64_offset"], r["f64_count"], r["quat_offset"]) == (a.f64_offset, a.f64_count, a.quat_offset)


def test_reject_reason_names_agree():
    assert tuple(fb.link_reject_reasons()) == P.REJECT_REASONS


# ----------------------------------------------------------------------------- both ways, every APID


@pytest.mark.parametrize("apid", sorted(P.APIDS))
def test_cpp_built_packet_parses_with_pypi_packages(apid):
    a = P.APIDS[apid]
    rng = random.Random(apid)
    framer = fb.LinkFramer(a.direction)
    for k in range(3):
        payload = valid_payload(a, rng)
        t_s = rng.uniform(0, 1e5)
        f = framer.frame(apid, t_s, payload)
        assert f.endswith(b"\x00") and b"\x00" not in f[:-1]
        dec = cobs.decode(f[:-1])
        body, crc_rx = dec[:-2], int.from_bytes(dec[-2:], "big")
        assert Calculator(P.CRC16_CCITT_FALSE).checksum(body) == crc_rx
        h = SpacePacketHeader.unpack(body)
        assert h.ccsds_version == 0
        assert h.packet_type == (PacketType.TC if a.direction == P.TO_FLIGHT else PacketType.TM)
        assert h.sec_header_flag
        assert h.apid == apid
        assert h.seq_flags == SequenceFlags.UNSEGMENTED
        assert h.seq_count == k
        assert h.packet_len == len(body)
        assert struct.unpack_from("<d", body, 6)[0] == t_s
        assert body[14:] == payload
        got = P.parse_frame(f, a.direction)
        assert isinstance(got, P.Packet), got


@pytest.mark.parametrize("apid", sorted(P.APIDS))
def test_pypi_built_packet_accepted_by_cpp(apid):
    a = P.APIDS[apid]
    rng = random.Random(1000 + apid)
    sender = P.Sender()
    d = fb.LinkDeframer(a.direction)
    for k in range(3):
        payload = valid_payload(a, rng)
        t_s = 10.0 + k
        res = d.feed(sender.frame(apid, t_s, payload))
        assert len(res) == 1 and res[0]["kind"] == "packet", res
        r = res[0]
        assert (r["apid"], r["seq_count"], r["t_s"], r["payload"]) == (apid, k, t_s, payload)
    assert d.counters()["rejected_total"] == 0


@pytest.mark.parametrize("apid", sorted(P.APIDS))
def test_frames_byte_identical_both_sides(apid):
    a = P.APIDS[apid]
    rng = random.Random(2000 + apid)
    ptype = 1 if a.direction == P.TO_FLIGHT else 0
    for seq in (0, 1, 16383):
        payload = valid_payload(a, rng)
        t_s = rng.uniform(-1e3, 1e6)
        assert fb.link_build_frame(apid, seq, t_s, payload, 3, ptype) == P.build_frame(apid, seq, t_s, payload)


def test_segmented_range_image_both_ways():
    a = P.APID_BY_NAME["range_image_segment"]
    rng = random.Random(5)
    sender = P.Sender()
    segs = [
        (0, 24, SequenceFlags.FIRST_SEGMENT),
        (24, 24, SequenceFlags.CONTINUATION_SEGMENT),
        (48, 5, SequenceFlags.LAST_SEGMENT),
    ]
    d = fb.LinkDeframer("to_flight")
    for first, n, flags in segs:
        payload = valid_payload(a, rng, first=first, n=n, total=53)
        res = d.feed(sender.frame(a.apid, 60.0, payload, seq_flags=flags))
        assert res[0]["kind"] == "packet" and res[0]["seq_flags"] == int(flags)
    cpp = fb.LinkFramer("to_flight")
    payload = valid_payload(a, rng, first=0, n=24, total=53)
    f = cpp.frame(a.apid, 61.0, payload, int(SequenceFlags.FIRST_SEGMENT))
    h = SpacePacketHeader.unpack(cobs.decode(f[:-1]))
    assert h.seq_flags == SequenceFlags.FIRST_SEGMENT
    assert isinstance(P.parse_frame(f, "to_flight"), P.Packet)


# ----------------------------------------------------------------------------- malformed: same verdict


def _malformed_cases():
    a = P.APID_BY_NAME["imu_sample"]
    good = valid_payload(a, random.Random(1))
    pkt = P.build_packet(a.apid, 0, 1.0, good)
    body = bytearray(pkt[:-2])

    def recrc(b):
        return bytes(b) + P.crc16(bytes(b)).to_bytes(2, "big")

    def with_len(v):
        b = bytearray(body)
        b[4:6] = v.to_bytes(2, "big")
        return recrc(b)

    nan = bytearray(body)
    struct.pack_into("<d", nan, 14, float("nan"))
    yield "empty_frame", b"\x00"
    yield "cobs_error", b"\x05\x11\x22\x00"
    yield "too_short", P.frame(recrc(body[:13]))
    yield "bad_crc", P.frame(pkt[:-1] + bytes([pkt[-1] ^ 1]))
    yield "length_field_too_long", P.frame(with_len(0xFFFF))
    yield "length_field_too_short", P.frame(with_len(10))
    yield "wrong_version", P.frame(recrc(bytes([body[0] | 0x20]) + body[1:]))
    yield "wrong_type", P.frame(P.build_packet(a.apid, 0, 1.0, good, packet_type=PacketType.TM))
    yield "wrong_secondary_header_flag", P.frame(recrc(bytes([body[0] & ~0x08]) + body[1:]))
    yield "unknown_apid", P.build_frame(0x123, 0, 1.0, good, packet_type=PacketType.TC)
    yield "wrong_sequence_flags", P.build_frame(a.apid, 0, 1.0, good, seq_flags=SequenceFlags.FIRST_SEGMENT)
    yield "wrong_payload_length", P.build_frame(a.apid, 0, 1.0, good + b"\x00")
    yield "bad_time_tag", P.build_frame(a.apid, 0, float("inf"), good)
    yield "non_finite_payload", P.frame(recrc(nan))
    lp = P.APID_BY_NAME["led_pose"]
    yield (
        "non_unit_quaternion",
        P.build_frame(lp.apid, 0, 1.0, P.pack_payload(lp.apid, 0, 0, 0, 1.01, 0, 0, 0, 0.1, 0.1)),
    )
    yield "invalid_field", P.build_frame(lp.apid, 0, 1.0, P.pack_payload(lp.apid, 0, 0, 0, 1, 0, 0, 0, -0.1, 0.1))


@pytest.mark.parametrize("reason,frame", list(_malformed_cases()), ids=[c[0] for c in _malformed_cases()])
def test_malformed_frames_get_the_same_reason_on_both_sides(reason, frame):
    cpp = fb.LinkDeframer("to_flight").feed(frame)
    py = P.Deframer(P.TO_FLIGHT).feed(frame)
    assert [r["reason"] for r in cpp] == [reason]
    assert [r.reason for r in py] == [reason]


# ----------------------------------------------------------------------------- corruption campaign


def _corrupt(stream: bytes, rng: random.Random, ber: float, drop: float) -> bytes:
    out = bytearray()
    for b in stream:
        if rng.random() < drop:
            continue
        for bit in range(8):
            if rng.random() < ber:
                b ^= 1 << bit
        out.append(b)
    return bytes(out)


def test_seeded_corruption_campaign_never_delivers_a_corrupted_packet():
    """Bit errors (BER 1e-3, ten times the faulty-link soak's 1e-4), 1% dropped bytes,
    duplicated and reordered packets, fed in random chunk sizes: every packet
    the C++ delivers is byte-identical to one the bench sent, and the C++ and
    the PyPI deframers agree on every verdict."""
    rng = random.Random(20240601)
    sender = P.Sender()
    frames, sent = [], set()
    to_flight = [a for a in P.APIDS.values() if a.direction == P.TO_FLIGHT]
    t = 0.0
    for _k in range(1500):
        a = rng.choice(to_flight)
        t += 0.01
        payload = valid_payload(a, rng)
        f = sender.frame(a.apid, t, payload)
        sent.add(cobs.decode(f[:-1])[:-2])
        frames.append(f)
        if rng.random() < 0.02:
            frames.append(f)  # duplicated
        if rng.random() < 0.02 and len(frames) > 2:
            frames[-1], frames[-2] = frames[-2], frames[-1]  # reordered
    stream = _corrupt(b"".join(frames), rng, ber=1e-3, drop=0.01)

    cpp = fb.LinkDeframer("to_flight")
    cpp_results = []
    pos = 0
    while pos < len(stream):
        n = rng.randrange(1, 600)
        cpp_results += cpp.feed(stream[pos : pos + n])
        pos += n
    py_results = P.Deframer(P.TO_FLIGHT).feed(stream)

    delivered = [r for r in cpp_results if r["kind"] == "packet"]
    bad = [r for r in delivered if r["packet"] not in sent]
    assert bad == []
    # Range segments (800 bytes) rarely survive BER 1e-3 and 1% drops; the
    # small packets mostly do. A deframer that lost sync would deliver few.
    assert len(delivered) > 300
    c = cpp.counters()
    assert c["rejected_by_reason"]["bad_crc"] > 0
    assert c["rejected_total"] == len(cpp_results) - len(delivered)
    assert c["packets_accepted"] == len(delivered)
    # Same verdicts, in the same order, from the independent implementation.
    assert [r["reason"] if r["kind"] == "rejected" else "packet" for r in cpp_results] == [
        r.reason if isinstance(r, P.Rejection) else "packet" for r in py_results
    ]


def test_housekeeping_carries_the_telemetry_drop_count():
    """A burst of 200 IMU samples in one call overflows the flight app's
    transmit buffer; the drops are counted, and the next tm_housekeeping,
    decoded on the bench side, carries the same count."""
    app = fb.FlightApp(fb.NavConfig())
    s = P.Sender()
    reset, imu = P.APID_BY_NAME["cmd_reset"].apid, P.APID_BY_NAME["imu_sample"].apid
    data = s.frame(
        reset, 0.0, P.pack_payload(reset, 1, 0, 0.0, -0.7, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.05, 0.01, 0.05)
    )
    data += b"".join(s.frame(imu, 0.1 * k, P.pack_payload(imu, *[0.0] * 6)) for k in range(1, 201))
    app.on_bytes(data)
    dropped = app.counters()["tx_dropped"]
    assert dropped > 0
    out = app.on_bytes(b"".join(s.frame(imu, 0.1 * k, P.pack_payload(imu, *[0.0] * 6)) for k in range(201, 211)))
    hk = [
        P.decode_housekeeping(p.payload)
        for p in P.Deframer(P.FROM_FLIGHT).feed(out)
        if isinstance(p, P.Packet) and p.apid == P.APID_BY_NAME["tm_housekeeping"].apid
    ]
    assert len(hk) == 1
    assert hk[0]["tx_dropped"] == dropped and hk[0]["cycle_count"] == 210


def _plan_telemetry(out: bytes) -> tuple:
    """(tm_plan_status list, tm_plan_valves list) decoded on the bench side."""
    status, valves = [], []
    for p in P.Deframer(P.FROM_FLIGHT).feed(out):
        if isinstance(p, P.Packet) and p.apid == P.APID_BY_NAME["tm_plan_status"].apid:
            status.append(P.decode_plan_status(p.payload))
        elif isinstance(p, P.Packet) and p.apid == P.APID_BY_NAME["tm_plan_valves"].apid:
            valves.append({**P.decode_plan_valves(p.payload), "t_s": p.t_s})
    return status, valves


def test_valve_plan_from_the_bench_runs_in_the_flight_app():
    """A plan built by the bench side (hil_sim.packets) is uplinked entry by
    entry, a refused load (two openings of valve 1 overlapping) changes
    nothing, the good plan loads and runs: the valve commands the flight
    app sends, decoded by the bench side, are the plan's, interval by
    interval; an abort closes the valves."""
    app = fb.FlightApp(fb.NavConfig())
    s = P.Sender()
    entry, cmd, imu = (P.APID_BY_NAME[n].apid for n in ("cmd_plan_entry", "cmd_plan", "imu_sample"))
    bad = [(1, 0.0, 0.5), (1, 0.3, 0.8)]
    data = b"".join(s.frame(entry, 0.0, pl) for pl in P.plan_entry_payloads(4, bad))
    data += s.frame(cmd, 0.0, P.plan_command_payload("load", 4, len(bad), 2.0))
    status, _ = _plan_telemetry(app.on_bytes(data))
    assert [(x["verdict"], x["state"], x["commands_refused"]) for x in status] == [("overlap", "empty", 1)]
    good = [(0, 0.2, 0.5), (6, 0.3, 0.4), (0, 1.0, 1.2)]
    data = b"".join(s.frame(entry, 0.0, pl) for pl in P.plan_entry_payloads(5, good))
    data += s.frame(cmd, 0.0, P.plan_command_payload("load", 5, len(good), 1.5))
    data += s.frame(cmd, 1.0, P.plan_command_payload("start", 5))
    data += b"".join(s.frame(imu, 0.1 * k, P.pack_payload(imu, *[0.0] * 6)) for k in range(10, 27))
    status, valves = _plan_telemetry(app.on_bytes(data))
    assert [(x["verdict"], x["state"]) for x in status] == [
        ("accepted", "loaded"),
        ("accepted", "running"),
        ("accepted", "finished"),
    ]
    assert status[0]["entry_count"] == 3 and status[0]["total_on_time_s"] == pytest.approx(0.6)
    running = [v for v in valves if v["state"] == "running"]
    assert len(running) == 15 and valves[-1]["state"] == "finished" and valves[-1]["valve_mask"] == 0
    for k, v in enumerate(running):
        tau = 0.1 * k
        want = sum(1 << valve for valve, a, b in good if a - 1e-9 <= tau < b - 1e-9)
        assert v["valve_mask"] == want, (k, v)
        assert v["t_s"] == pytest.approx(1.0 + tau) and v["plan_time_s"] == pytest.approx(tau)
        assert v["on_time_s"][0] == pytest.approx(0.1 if want & 1 else 0.0)
    c = app.counters()
    assert (c["plans_loaded"], c["plan_commands_refused"], c["plans_finished"]) == (1, 1, 1)
    data = s.frame(cmd, 3.0, P.plan_command_payload("start", 5))
    data += s.frame(imu, 3.0, P.pack_payload(imu, *[0.0] * 6))
    data += s.frame(cmd, 3.05, P.plan_command_payload("abort", 5))
    status, valves = _plan_telemetry(app.on_bytes(data))
    assert [v["state"] for v in valves] == ["running", "aborted"] and valves[-1]["valve_mask"] == 0
    assert status[-1]["state"] == "aborted" and app.counters()["plan_aborts"] == 1


@pytest.mark.parametrize("name,offset", [("tm_plan_status", 4), ("tm_plan_status", 6), ("tm_plan_valves", 5)])
def test_plan_telemetry_state_and_verdict_out_of_range_refused_on_both_sides(name, offset):
    a = P.APID_BY_NAME[name]
    payload = bytearray(valid_payload(a, random.Random(3)))
    payload[offset] = 14 if offset == 6 else 5  # one past the last verdict / state
    frame = P.build_frame(a.apid, 0, 1.0, bytes(payload))
    cpp = fb.LinkDeframer("from_flight").feed(frame)
    py = P.Deframer(P.FROM_FLIGHT).feed(frame)
    assert cpp[0]["kind"] == "rejected" and cpp[0]["reason"] == "invalid_field"
    assert isinstance(py[0], P.Rejection) and py[0].reason == "invalid_field"
