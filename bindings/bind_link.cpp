// The serial-link framing (CRC, COBS, CCSDS packets, deframer) for the
// cross-check tests against the PyPI implementation in hil_sim/packets.py.
// The bench itself never frames through these bindings.
#include <memory>
#include <string>

#include "bind.hpp"
#include "fsw/link/cobs.hpp"
#include "fsw/link/crc16.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "validate.hpp"

namespace {

fsw::Direction direction_of(const std::string& s) {
  if (s == "to_flight") return fsw::Direction::ToFlight;
  if (s == "from_flight") return fsw::Direction::FromFlight;
  throw py::value_error("direction: expected 'to_flight' or 'from_flight', got '" + s + "'");
}

std::string bytes_of(const py::bytes& b) { return std::string(b); }

const std::uint8_t* u8(const std::string& s) { return reinterpret_cast<const std::uint8_t*>(s.data()); }

py::bytes to_bytes(const std::uint8_t* p, std::size_t n) { return py::bytes(reinterpret_cast<const char*>(p), n); }

py::dict link_counters_dict(const fsw::LinkCounters& c) {
  py::dict rejected;
  for (std::size_t i = 0; i < fsw::kRejectReasonCount; ++i) {
    rejected[fsw::to_string(static_cast<fsw::RejectReason>(i))] = c.rejected[i];
  }
  py::dict per_apid;
  for (std::size_t i = 0; i < fsw::kApidCount; ++i) {
    const auto& s = c.per_apid[i];
    py::dict d;
    d["accepted"] = s.accepted;
    d["rejected"] = s.rejected;
    d["gaps"] = s.gaps;
    d["duplicates"] = s.duplicates;
    d["out_of_order"] = s.out_of_order;
    d["resyncs"] = s.resyncs;
    per_apid[py::int_(static_cast<int>(fsw::kApidTable[i].apid))] = d;
  }
  py::dict d;
  d["bytes_received"] = c.bytes_received;
  d["frames_total"] = c.frames_total;
  d["packets_accepted"] = c.packets_accepted;
  d["rejected_by_reason"] = rejected;
  d["rejected_total"] = c.rejected_total();
  d["seq_gaps_total"] = c.gaps_total();
  d["duplicates_total"] = c.duplicates_total();
  d["per_apid"] = per_apid;
  return d;
}

py::dict result_dict(const fsw::DeframeResult& r) {
  py::dict d;
  if (r.kind == fsw::DeframeResult::Kind::Packet) {
    const auto& p = r.packet;
    d["kind"] = "packet";
    d["apid"] = p.header.apid;
    d["packet_type"] = static_cast<int>(p.header.type);
    d["seq_flags"] = static_cast<int>(p.header.seq_flags);
    d["seq_count"] = p.header.seq_count;
    d["t_s"] = p.t_s;
    d["payload"] = to_bytes(p.payload, p.payload_len);
    d["packet"] = to_bytes(p.packet, p.packet_len);
  } else {
    d["kind"] = "rejected";
    d["reason"] = fsw::to_string(r.reason);
    d["apid"] = r.apid == 0xFFFF ? py::object(py::none()) : py::object(py::int_(r.apid));
  }
  return d;
}

// CRC and COBS of any bytes.
void bind_codecs(py::module_& m) {
  m.def(
      "link_crc16",
      [](const py::bytes& b) {
        const std::string s = bytes_of(b);
        return fsw::crc16_ccitt_false(u8(s), s.size());
      },
      py::arg("data"), "CRC-16/CCITT-FALSE of data (check value 0x29B1 over b'123456789').");
  m.def(
      "link_cobs_encode",
      [](const py::bytes& b) {
        const std::string s = bytes_of(b);
        std::string out(fsw::cobs_max_encoded_size(s.size()), '\0');
        const std::size_t n = fsw::cobs_encode(u8(s), s.size(), reinterpret_cast<std::uint8_t*>(&out[0]), out.size());
        return py::bytes(out.data(), n);
      },
      py::arg("data"), "COBS encoding of data (no trailing 0x00).");
}

// The rejection reasons and the APID table, as the flight code has them.
void bind_tables(py::module_& m) {
  m.def(
      "link_reject_reasons",
      []() {
        py::list l;
        for (std::size_t i = 0; i < fsw::kRejectReasonCount; ++i)
          l.append(fsw::to_string(static_cast<fsw::RejectReason>(i)));
        return l;
      },
      "Rejection reason names in the order of their numeric codes.");
  m.def(
      "link_apid_table",
      []() {
        py::list l;
        for (const auto& r : fsw::kApidTable) {
          py::dict d;
          d["apid"] = static_cast<int>(r.apid);
          d["name"] = r.name;
          d["direction"] = r.direction == fsw::Direction::ToFlight ? "to_flight" : "from_flight";
          d["payload_len"] = r.payload_len;
          d["segmentable"] = r.segmentable;
          d["f64_offset"] = r.f64_offset;
          d["f64_count"] = r.f64_count;
          d["quat_offset"] = r.quat_offset < 0 ? py::object(py::none()) : py::object(py::int_(r.quat_offset));
          l.append(d);
        }
        return l;
      },
      "The flight APID table.");
}

// One frame with any header values (the cross-check's malformed packets too).
void bind_build_frame(py::module_& m) {
  m.def(
      "link_build_frame",
      [](int apid, int seq_count, double t_s, const py::bytes& payload, int seq_flags, int packet_type) {
        if (apid < 0 || apid > 0x7FF) throw py::value_error("apid: must be in [0, 2047]");
        if (seq_count < 0 || seq_count >= 16384) throw py::value_error("seq_count: must be in [0, 16383]");
        if (seq_flags < 0 || seq_flags > 3) throw py::value_error("seq_flags: must be in [0, 3]");
        if (packet_type < 0 || packet_type > 1) throw py::value_error("packet_type: 0 (TM) or 1 (TC)");
        const std::string p = bytes_of(payload);
        std::string pkt(fsw::kPacketHeaderSize + p.size() + fsw::kCrcSize, '\0');
        const std::size_t n =
            fsw::build_packet(static_cast<fsw::PacketType>(packet_type), static_cast<std::uint16_t>(apid),
                              static_cast<fsw::SeqFlags>(seq_flags), static_cast<std::uint16_t>(seq_count), t_s, u8(p),
                              p.size(), reinterpret_cast<std::uint8_t*>(&pkt[0]), pkt.size());
        if (n == 0) throw py::value_error("payload: too long for one packet");
        std::string out(fsw::cobs_max_encoded_size(n) + 1, '\0');
        const std::size_t f = fsw::frame_bytes(u8(pkt), n, reinterpret_cast<std::uint8_t*>(&out[0]), out.size());
        return py::bytes(out.data(), f);
      },
      py::arg("apid"), py::arg("seq_count"), py::arg("t_s"), py::arg("payload"), py::arg("seq_flags") = 3,
      py::arg("packet_type") = 1,
      "Frame (COBS bytes and 0x00) of one packet with any header values; t_s [s] is the time tag.");
}

void bind_framer(py::module_& m) {
  py::class_<fsw::Framer>(m, "LinkFramer", "Framer of one direction with per-APID sequence counts.")
      .def(py::init([](const std::string& dir) { return fsw::Framer(direction_of(dir)); }), py::arg("direction"))
      .def(
          "frame",
          [](fsw::Framer& f, int apid, double t_s, const py::bytes& payload, int seq_flags) {
            if (apid < 0 || apid > 0x7FF) throw py::value_error("apid: must be in [0, 2047]");
            if (seq_flags < 0 || seq_flags > 3) throw py::value_error("seq_flags: must be in [0, 3]");
            const std::string p = bytes_of(payload);
            std::string out(fsw::kMaxFrameBytes, '\0');
            const std::size_t n =
                f.frame(static_cast<fsw::Apid>(apid), t_s, u8(p), p.size(), reinterpret_cast<std::uint8_t*>(&out[0]),
                        out.size(), static_cast<fsw::SeqFlags>(seq_flags));
            if (n == 0) throw py::value_error("frame: APID not of this direction, wrong payload length or flags");
            return py::bytes(out.data(), n);
          },
          py::arg("apid"), py::arg("t_s"), py::arg("payload"), py::arg("seq_flags") = 3);
}

void bind_deframer(py::module_& m) {
  py::class_<fsw::Deframer, std::unique_ptr<fsw::Deframer>>(
      m, "LinkDeframer", "Streaming deframer of the flight code; feed() takes any chunk of bytes.")
      .def(py::init([](const std::string& dir) { return std::make_unique<fsw::Deframer>(direction_of(dir)); }),
           py::arg("direction"))
      .def(
          "feed",
          [](fsw::Deframer& d, const py::bytes& data) {
            const std::string s = bytes_of(data);
            const std::uint8_t* p = u8(s);
            std::size_t n = s.size();
            py::list out;
            while (n > 0) {
              fsw::DeframeResult r;
              const std::size_t used = d.feed(p, n, r);
              p += used;
              n -= used;
              if (r.kind != fsw::DeframeResult::Kind::Nothing) out.append(result_dict(r));
            }
            return out;
          },
          py::arg("data"), "Results of the frames completed by these bytes: dicts with kind 'packet' or 'rejected'.")
      .def("counters", [](const fsw::Deframer& d) { return link_counters_dict(d.counters()); })
      .def("reset_history", &fsw::Deframer::reset_history)
      .def("reset_time_history", &fsw::Deframer::reset_time_history);
}

}  // namespace

void bind_link(py::module_& m) {
  bind_codecs(m);
  bind_tables(m);
  bind_build_frame(m);
  bind_framer(m);
  bind_deframer(m);
}
