// CCSDS Space Packet (CCSDS 133.0-B-2) primary header, and the link's
// secondary header (a time tag). The primary header is big-endian as the
// standard says; everything after it (time tag, payload) is little-endian
// (docs/LINK.md).
//
//   bits  0-2   version (0)
//   bit   3     packet type (0 telemetry, 1 telecommand)
//   bit   4     secondary header flag (always 1 on this link)
//   bits  5-15  APID (11 bits)
//   bits 16-17  sequence flags (0b11 unsegmented, 0b01 first, 0b00 continuation, 0b10 last)
//   bits 18-31  sequence count (14 bits, wraps 16383 -> 0)
//   bits 32-47  data length = (bytes after the primary header) - 1
//
// Secondary header: 8 bytes, the time tag t_s as a little-endian IEEE-754
// double, seconds of mission time (for a measurement: its capture time).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace fsw {

constexpr std::size_t kPrimaryHeaderSize = 6;
constexpr std::size_t kSecondaryHeaderSize = 8;
constexpr std::size_t kPacketHeaderSize = kPrimaryHeaderSize + kSecondaryHeaderSize;
constexpr std::uint16_t kMaxApid = 0x7FF;
constexpr std::uint16_t kIdleApid = 0x7FF;  // reserved by CCSDS for idle packets
constexpr std::uint16_t kSeqCountModulo = 1u << 14;

enum class PacketType : std::uint8_t { Telemetry = 0, Telecommand = 1 };

enum class SeqFlags : std::uint8_t {
  Continuation = 0b00,
  First = 0b01,
  Last = 0b10,
  Unsegmented = 0b11,
};

struct PrimaryHeader {
  std::uint8_t version = 0;
  PacketType type = PacketType::Telemetry;
  bool sec_header = true;
  std::uint16_t apid = 0;
  SeqFlags seq_flags = SeqFlags::Unsegmented;
  std::uint16_t seq_count = 0;
  std::uint16_t data_length = 0;  // bytes after the primary header, minus 1
};

// Data-length field for a packet of total_len bytes (>= 7). Computed in 32
// bits by the caller's bound; a packet longer than 65542 bytes cannot be
// described and gives false.
constexpr bool data_length_for(std::size_t total_len, std::uint16_t& field) {
  if (total_len < kPrimaryHeaderSize + 1 || total_len > kPrimaryHeaderSize + 65536u) return false;
  field = static_cast<std::uint16_t>(total_len - kPrimaryHeaderSize - 1);
  return true;
}

// Total packet length announced by a data-length field; 32-bit so that
// 0xFFFF + 1 cannot wrap.
constexpr std::uint32_t packet_length_from_field(std::uint16_t field) {
  return static_cast<std::uint32_t>(field) + 1u + kPrimaryHeaderSize;
}

// Writes 6 bytes. Fields wider than their bit width are masked (callers
// validate first; pack never fails).
inline void pack_primary_header(const PrimaryHeader& h, std::uint8_t* out) {
  const std::uint16_t id =
      static_cast<std::uint16_t>(((h.version & 0x7u) << 13) | ((static_cast<unsigned>(h.type) & 0x1u) << 12) |
                                 ((h.sec_header ? 1u : 0u) << 11) | (h.apid & kMaxApid));
  const std::uint16_t psc = static_cast<std::uint16_t>(((static_cast<unsigned>(h.seq_flags) & 0x3u) << 14) |
                                                       (h.seq_count & (kSeqCountModulo - 1u)));
  out[0] = static_cast<std::uint8_t>(id >> 8);
  out[1] = static_cast<std::uint8_t>(id & 0xFF);
  out[2] = static_cast<std::uint8_t>(psc >> 8);
  out[3] = static_cast<std::uint8_t>(psc & 0xFF);
  out[4] = static_cast<std::uint8_t>(h.data_length >> 8);
  out[5] = static_cast<std::uint8_t>(h.data_length & 0xFF);
}

// Reads 6 bytes; every bit pattern is a valid PrimaryHeader (checks are the
// deframer's job).
inline PrimaryHeader unpack_primary_header(const std::uint8_t* in) {
  PrimaryHeader h;
  const std::uint16_t id = static_cast<std::uint16_t>((in[0] << 8) | in[1]);
  const std::uint16_t psc = static_cast<std::uint16_t>((in[2] << 8) | in[3]);
  h.version = static_cast<std::uint8_t>(id >> 13);
  h.type = static_cast<PacketType>((id >> 12) & 0x1u);
  h.sec_header = ((id >> 11) & 0x1u) != 0;
  h.apid = static_cast<std::uint16_t>(id & kMaxApid);
  h.seq_flags = static_cast<SeqFlags>(psc >> 14);
  h.seq_count = static_cast<std::uint16_t>(psc & (kSeqCountModulo - 1u));
  h.data_length = static_cast<std::uint16_t>((in[4] << 8) | in[5]);
  return h;
}

// Little-endian scalars for the data field (time tag and payloads). memcpy
// plus an explicit byte order keeps this independent of host endianness.
inline void put_u16le(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline void put_u32le(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline void put_u64le(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline std::uint16_t get_u16le(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
inline std::uint32_t get_u32le(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline std::uint64_t get_u64le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline void put_f64le(std::uint8_t* p, double x) {
  static_assert(sizeof(double) == 8, "IEEE-754 binary64 expected");
  std::uint64_t v = 0;
  std::memcpy(&v, &x, 8);
  put_u64le(p, v);
}
inline double get_f64le(const std::uint8_t* p) {
  const std::uint64_t v = get_u64le(p);
  double x = 0.0;
  std::memcpy(&x, &v, 8);
  return x;
}

// Secondary header: the time tag.
inline void pack_time_tag(double t_s, std::uint8_t* out) { put_f64le(out, t_s); }
inline double unpack_time_tag(const std::uint8_t* in) { return get_f64le(in); }

}  // namespace fsw
