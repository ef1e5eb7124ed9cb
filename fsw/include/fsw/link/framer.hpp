// Framer for the serial link: packet (primary header, time tag, payload) ->
// CRC-16/CCITT-FALSE appended big-endian -> COBS -> 0x00. No heap: the caller
// provides the output buffer (kMaxFrameBytes always suffices).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "fsw/link/apid.hpp"
#include "fsw/link/cobs.hpp"
#include "fsw/link/crc16.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/space_packet.hpp"

namespace fsw {

constexpr std::size_t kMaxFrameBytes = kMaxFrameLen + 1;  // with the trailing 0x00

// Writes primary header, time tag, payload and CRC into out. Returns the
// packet length including the CRC, or 0 if it does not fit cap or cannot be
// described (APID or sequence count out of range, payload too long).
inline std::size_t build_packet(PacketType type, std::uint16_t apid, SeqFlags flags, std::uint16_t seq_count,
                                double t_s, const std::uint8_t* payload, std::size_t payload_len, std::uint8_t* out,
                                std::size_t cap) {
  const std::size_t body = kPacketHeaderSize + payload_len;
  if (apid > kMaxApid || seq_count >= kSeqCountModulo || payload_len > 65536u - kSecondaryHeaderSize) return 0;
  if (body + kCrcSize > cap) return 0;
  PrimaryHeader h;
  h.type = type;
  h.apid = apid;
  h.seq_flags = flags;
  h.seq_count = seq_count;
  if (!data_length_for(body, h.data_length)) return 0;
  pack_primary_header(h, out);
  pack_time_tag(t_s, out + kPrimaryHeaderSize);
  for (std::size_t i = 0; i < payload_len; ++i) out[kPacketHeaderSize + i] = payload[i];
  const std::uint16_t crc = crc16_ccitt_false(out, body);
  out[body] = static_cast<std::uint8_t>(crc >> 8);
  out[body + 1] = static_cast<std::uint8_t>(crc & 0xFF);
  return body + kCrcSize;
}

// COBS-encodes n bytes and appends 0x00. Returns the frame length or 0.
inline std::size_t frame_bytes(const std::uint8_t* in, std::size_t n, std::uint8_t* out, std::size_t cap) {
  if (cap < cobs_max_encoded_size(n) + 1) return 0;
  const std::size_t k = cobs_encode(in, n, out, cap - 1);
  if (k == 0) return 0;
  out[k] = 0;
  return k + 1;
}

// Sends packets of one direction, keeping the per-APID 14-bit sequence count.
class Framer {
 public:
  explicit Framer(Direction send = Direction::FromFlight) : dir_(send) {}

  // Frames one packet of a table APID of this direction with an exact-length
  // payload. Returns the frame length (with 0x00), or 0 on misuse (nothing is
  // counted then). Only segmentable APIDs may use flags other than Unsegmented.
  std::size_t frame(Apid apid, double t_s, const std::uint8_t* payload, std::size_t payload_len, std::uint8_t* out,
                    std::size_t cap, SeqFlags flags = SeqFlags::Unsegmented) {
    const int row = apid_index(static_cast<std::uint16_t>(apid));
    if (row < 0) return 0;
    const ApidInfo& info = kApidTable[static_cast<std::size_t>(row)];
    if (info.direction != dir_ || payload_len != info.payload_len) return 0;
    if (!info.segmentable && flags != SeqFlags::Unsegmented) return 0;
    std::uint16_t& seq = seq_[static_cast<std::size_t>(row)];
    const std::size_t n = build_packet(packet_type_of(dir_), static_cast<std::uint16_t>(apid), flags, seq, t_s, payload,
                                       payload_len, packet_.data(), packet_.size());
    if (n == 0) return 0;
    const std::size_t f = frame_bytes(packet_.data(), n, out, cap);
    if (f == 0) return 0;
    seq = static_cast<std::uint16_t>((seq + 1u) % kSeqCountModulo);
    return f;
  }

  // Encodes a typed message (fsw::encode overloads in apid.hpp) and frames it.
  template <typename Msg>
  std::size_t frame_message(Apid apid, const Msg& msg, double t_s, std::uint8_t* out, std::size_t cap,
                            SeqFlags flags = SeqFlags::Unsegmented) {
    const ApidInfo* info = apid_info(static_cast<std::uint16_t>(apid));
    if (info == nullptr) return 0;
    encode(msg, payload_.data());
    return frame(apid, t_s, payload_.data(), info->payload_len, out, cap, flags);
  }

  std::uint16_t next_seq(Apid apid) const {
    const int row = apid_index(static_cast<std::uint16_t>(apid));
    return row < 0 ? 0 : seq_[static_cast<std::size_t>(row)];
  }
  void set_next_seq(Apid apid, std::uint16_t seq) {
    const int row = apid_index(static_cast<std::uint16_t>(apid));
    if (row >= 0) seq_[static_cast<std::size_t>(row)] = static_cast<std::uint16_t>(seq % kSeqCountModulo);
  }
  Direction direction() const { return dir_; }

 private:
  Direction dir_;
  std::array<std::uint16_t, kApidCount> seq_{};
  std::array<std::uint8_t, kMaxPacketWithCrc> packet_{};
  std::array<std::uint8_t, kMaxPayloadLen> payload_{};
};

}  // namespace fsw
