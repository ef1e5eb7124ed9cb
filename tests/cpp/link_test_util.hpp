// Helpers shared by the link tests: valid payloads for every APID and raw
// packets with arbitrary header fields (for the malformed cases).
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

#include "fsw/link/apid.hpp"
#include "fsw/link/crc16.hpp"
#include "fsw/link/framer.hpp"
#include "fsw/link/space_packet.hpp"

namespace link_test {

using Bytes = std::vector<std::uint8_t>;

// A payload of the table length that passes every check: doubles 0.125*k,
// a unit quaternion where the table has one, valid segment fields.
inline Bytes valid_payload(const fsw::ApidInfo& info) {
  Bytes p(info.payload_len, 0);
  for (std::size_t i = 0; i < info.f64_count; ++i) {
    fsw::put_f64le(p.data() + info.f64_offset + 8 * i, 0.125 * static_cast<double>(i + 1));
  }
  if (info.quat_offset >= 0) {
    const double q[4] = {0.5, 0.5, -0.5, 0.5};
    for (int i = 0; i < 4; ++i) fsw::put_f64le(p.data() + info.quat_offset + 8 * i, q[i]);
  }
  if (info.apid == fsw::Apid::RangeImageSegment) {
    fsw::put_u16le(p.data() + 4, 24);  // points_total
    fsw::put_u16le(p.data() + 6, 0);   // first_point
    fsw::put_u16le(p.data() + 8, 24);  // n_points
  }
  return p;
}

// Packet bytes (with CRC) from explicit header fields; data_length is
// computed unless given.
inline Bytes raw_packet(const fsw::PrimaryHeader& h_in, double t_s, const Bytes& payload, bool fix_length = true) {
  fsw::PrimaryHeader h = h_in;
  Bytes b(fsw::kPacketHeaderSize + payload.size());
  if (fix_length) h.data_length = static_cast<std::uint16_t>(b.size() - fsw::kPrimaryHeaderSize - 1);
  fsw::pack_primary_header(h, b.data());
  fsw::pack_time_tag(t_s, b.data() + fsw::kPrimaryHeaderSize);
  if (!payload.empty()) std::memcpy(b.data() + fsw::kPacketHeaderSize, payload.data(), payload.size());
  const std::uint16_t crc = fsw::crc16_ccitt_false(b.data(), b.size());
  b.push_back(static_cast<std::uint8_t>(crc >> 8));
  b.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  return b;
}

inline Bytes frame_of(const Bytes& packet_with_crc) {
  Bytes f(fsw::cobs_max_encoded_size(packet_with_crc.size()) + 1);
  f.resize(fsw::frame_bytes(packet_with_crc.data(), packet_with_crc.size(), f.data(), f.size()));
  return f;
}

inline fsw::PrimaryHeader header_for(fsw::Apid apid, std::uint16_t seq,
                                     fsw::SeqFlags flags = fsw::SeqFlags::Unsegmented) {
  fsw::PrimaryHeader h;
  const fsw::ApidInfo* info = fsw::apid_info(static_cast<std::uint16_t>(apid));
  h.type = fsw::packet_type_of(info->direction);
  h.apid = static_cast<std::uint16_t>(apid);
  h.seq_flags = flags;
  h.seq_count = seq;
  return h;
}

// A valid frame for a table APID.
inline Bytes valid_frame(fsw::Apid apid, std::uint16_t seq, double t_s) {
  const fsw::ApidInfo* info = fsw::apid_info(static_cast<std::uint16_t>(apid));
  return frame_of(raw_packet(header_for(apid, seq), t_s, valid_payload(*info)));
}

}  // namespace link_test
