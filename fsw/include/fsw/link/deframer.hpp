// Streaming deframer for the serial link: bytes in (any chunking), and for
// each frame either a packet or a rejection with its reason. Decoding order
// (docs/LINK.md):
//
//   1 split on 0x00            EmptyFrame
//   2 bound the frame length   FrameTooLong (runaway: reported once, resync at next 0x00)
//   3 COBS-decode              CobsError
//   4 minimum length           TooShort
//   5 CRC-16/CCITT-FALSE       BadCrc
//   6 header fields            WrongVersion, WrongType, WrongSecondaryHeaderFlag
//   7 length field vs frame    LengthFieldTooLong, LengthFieldTooShort
//   8 APID and its length      UnknownApid, WrongSequenceFlags, WrongPayloadLength
//   9 sequence and time        BadTimeTag, DuplicateSequence, TimeBackwards, StaleSequence
//                              (gaps counted, packet accepted)
//
// The per-APID history (last sequence count and time tag) and the gap and
// resync counts change only when a packet is accepted (passes step 10).
//  10 payload                  NonFinitePayload, NonUnitQuaternion, InvalidField
//
// No heap, no exceptions; every loop is bounded by the bytes given; every
// rejection increments a fixed counter. A delivered packet has passed its CRC.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "fsw/link/apid.hpp"
#include "fsw/link/cobs.hpp"
#include "fsw/link/space_packet.hpp"

namespace fsw {

// Stable numbering: values index the link-counter telemetry (tm_link_counters)
// and names are the keys of packets_rejected_by_reason. Append only.
enum class RejectReason : std::uint8_t {
  EmptyFrame = 0,
  FrameTooLong = 1,
  CobsError = 2,
  TooShort = 3,
  BadCrc = 4,
  WrongVersion = 5,
  WrongType = 6,
  WrongSecondaryHeaderFlag = 7,
  LengthFieldTooLong = 8,
  LengthFieldTooShort = 9,
  UnknownApid = 10,
  WrongSequenceFlags = 11,
  WrongPayloadLength = 12,
  BadTimeTag = 13,
  DuplicateSequence = 14,
  TimeBackwards = 15,
  StaleSequence = 16,
  NonFinitePayload = 17,
  NonUnitQuaternion = 18,
  InvalidField = 19,
};
constexpr std::size_t kRejectReasonCount = 20;
static_assert(kRejectReasonCount <= kLinkCounterSlots, "tm_link_counters has too few slots");

// snake_case name, e.g. "bad_crc"; "unknown" for a value out of range.
const char* to_string(RejectReason r);

// Smallest and largest frames (encoded bytes, without the 0x00).
constexpr std::size_t kMinPacketWithCrc = kPacketHeaderSize + kCrcSize;
constexpr std::size_t kMaxPacketWithCrc = kMaxPacketLen + kCrcSize;
constexpr std::size_t kMaxFrameLen = cobs_max_encoded_size(kMaxPacketWithCrc);

// A delivered packet. Pointers refer to the deframer's buffer and stay valid
// until the next call to feed() or process_frame().
struct PacketView {
  PrimaryHeader header;
  const ApidInfo* info = nullptr;
  double t_s = 0.0;
  const std::uint8_t* packet = nullptr;  // primary header .. end of payload (no CRC)
  std::uint16_t packet_len = 0;
  const std::uint8_t* payload = nullptr;
  std::uint16_t payload_len = 0;
};

struct DeframeResult {
  enum class Kind : std::uint8_t { Nothing = 0, Packet, Rejected };
  Kind kind = Kind::Nothing;
  RejectReason reason = RejectReason::EmptyFrame;  // meaningful when Rejected
  std::uint16_t apid = 0xFFFF;                     // APID when known at the point of rejection, else 0xFFFF
  PacketView packet;                               // meaningful when Packet
};

struct ApidLinkStats {
  std::uint32_t accepted = 0;
  std::uint32_t rejected = 0;      // rejected after the APID was identified (steps 8-10)
  std::uint32_t gaps = 0;          // packets missing according to the sequence count
  std::uint32_t duplicates = 0;    // same sequence count as the last accepted
  std::uint32_t out_of_order = 0;  // time backwards or stale sequence
  std::uint32_t resyncs = 0;       // sequence jumped back with time moving on (sender restart)
  std::uint16_t last_seq = 0;
  double last_t_s = 0.0;
  bool seen = false;
};

struct LinkCounters {
  std::uint32_t bytes_received = 0;
  std::uint32_t frames_total = 0;  // every 0x00-terminated frame plus every runaway
  std::uint32_t packets_accepted = 0;
  std::array<std::uint32_t, kRejectReasonCount> rejected{};
  std::array<ApidLinkStats, kApidCount> per_apid{};

  std::uint32_t rejected_total() const;
  std::uint32_t gaps_total() const;
  std::uint32_t duplicates_total() const;
};

class Deframer {
 public:
  // accept: the direction this end receives (the flight side receives
  // Direction::ToFlight, the bench side Direction::FromFlight).
  explicit Deframer(Direction accept = Direction::ToFlight) : accept_(accept) {}

  // Consumes bytes from data[0, n) until a frame completes (packet or
  // rejection, reported in out) or the bytes run out (out.kind == Nothing).
  // Returns the number of bytes consumed; call again with the rest.
  std::size_t feed(const std::uint8_t* data, std::size_t n, DeframeResult& out);

  // Steps 3-10 on one complete frame (COBS bytes without the 0x00). Counts
  // like feed() does, except bytes_received.
  DeframeResult process_frame(const std::uint8_t* frame, std::size_t n);

  const LinkCounters& counters() const { return counters_; }
  // Clears the counters (cmd_reset, link bit); keeps sequence and time history.
  void reset_counters();
  // Forgets every APID's last sequence count and time tag (a new session).
  void reset_history();
  // Forgets every APID's last time tag but keeps the sequence counts (a
  // carried-out cmd_reset: a new time base; a repeated packet is still a
  // duplicate).
  void reset_time_history();
  // Drops a partly received frame (e.g. after a serial port reopen).
  void reset_stream() { acc_.reset(); }

  Direction direction() const { return accept_; }

 private:
  DeframeResult reject(RejectReason r, int apid_row = -1, std::uint16_t apid = 0xFFFF);

  Direction accept_;
  CobsAccumulator<kMaxFrameLen> acc_;
  std::array<std::uint8_t, kMaxFrameLen> decoded_{};
  LinkCounters counters_;
};

}  // namespace fsw
