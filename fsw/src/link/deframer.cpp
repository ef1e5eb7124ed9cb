// Streaming deframer: the checks in the order documented in deframer.hpp.
#include "fsw/link/deframer.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

#include "fsw/link/crc16.hpp"

namespace fsw {

namespace {
inline void bump(std::uint32_t& c) {
  if (c != UINT32_MAX) ++c;  // saturate rather than wrap
}
constexpr std::uint16_t kHalfSeq = kSeqCountModulo / 2;
}  // namespace

const char* to_string(RejectReason r) {
  switch (r) {
    case RejectReason::EmptyFrame: return "empty_frame";
    case RejectReason::FrameTooLong: return "frame_too_long";
    case RejectReason::CobsError: return "cobs_error";
    case RejectReason::TooShort: return "too_short";
    case RejectReason::BadCrc: return "bad_crc";
    case RejectReason::WrongVersion: return "wrong_version";
    case RejectReason::WrongType: return "wrong_type";
    case RejectReason::WrongSecondaryHeaderFlag: return "wrong_secondary_header_flag";
    case RejectReason::LengthFieldTooLong: return "length_field_too_long";
    case RejectReason::LengthFieldTooShort: return "length_field_too_short";
    case RejectReason::UnknownApid: return "unknown_apid";
    case RejectReason::WrongSequenceFlags: return "wrong_sequence_flags";
    case RejectReason::WrongPayloadLength: return "wrong_payload_length";
    case RejectReason::BadTimeTag: return "bad_time_tag";
    case RejectReason::DuplicateSequence: return "duplicate_sequence";
    case RejectReason::TimeBackwards: return "time_backwards";
    case RejectReason::StaleSequence: return "stale_sequence";
    case RejectReason::NonFinitePayload: return "non_finite_payload";
    case RejectReason::NonUnitQuaternion: return "non_unit_quaternion";
    case RejectReason::InvalidField: return "invalid_field";
  }
  return "unknown";
}

std::uint32_t LinkCounters::rejected_total() const {
  std::uint64_t s = 0;
  for (auto c : rejected) s += c;
  return s > UINT32_MAX ? UINT32_MAX : static_cast<std::uint32_t>(s);
}
std::uint32_t LinkCounters::gaps_total() const {
  std::uint64_t s = 0;
  for (const auto& a : per_apid) s += a.gaps;
  return s > UINT32_MAX ? UINT32_MAX : static_cast<std::uint32_t>(s);
}
std::uint32_t LinkCounters::duplicates_total() const {
  std::uint64_t s = 0;
  for (const auto& a : per_apid) s += a.duplicates;
  return s > UINT32_MAX ? UINT32_MAX : static_cast<std::uint32_t>(s);
}

void Deframer::reset_counters() {
  counters_.bytes_received = 0;
  counters_.frames_total = 0;
  counters_.packets_accepted = 0;
  counters_.rejected.fill(0);
  for (auto& a : counters_.per_apid) {
    a.accepted = a.rejected = a.gaps = a.duplicates = a.out_of_order = a.resyncs = 0;
  }
}

void Deframer::reset_history() {
  for (auto& a : counters_.per_apid) {
    a.seen = false;
    a.last_seq = 0;
    a.last_t_s = 0.0;
  }
}

void Deframer::reset_time_history() {
  for (auto& a : counters_.per_apid) a.last_t_s = -std::numeric_limits<double>::infinity();
}

DeframeResult Deframer::reject(RejectReason r, int apid_row, std::uint16_t apid) {
  bump(counters_.rejected[static_cast<std::size_t>(r)]);
  if (apid_row >= 0) bump(counters_.per_apid[static_cast<std::size_t>(apid_row)].rejected);
  DeframeResult out;
  out.kind = DeframeResult::Kind::Rejected;
  out.reason = r;
  out.apid = apid;
  return out;
}

std::size_t Deframer::feed(const std::uint8_t* data, std::size_t n, DeframeResult& out) {
  out = DeframeResult{};
  CobsAccumulator<kMaxFrameLen>::Event ev{};
  const std::size_t used = acc_.push_bytes(data, n, ev);
  const std::uint32_t room = UINT32_MAX - counters_.bytes_received;  // saturate rather than wrap
  counters_.bytes_received += used < room ? static_cast<std::uint32_t>(used) : room;
  switch (ev) {
    case CobsAccumulator<kMaxFrameLen>::Event::None: break;
    case CobsAccumulator<kMaxFrameLen>::Event::EmptyFrame:
      bump(counters_.frames_total);
      out = reject(RejectReason::EmptyFrame);
      break;
    case CobsAccumulator<kMaxFrameLen>::Event::Runaway:
      bump(counters_.frames_total);
      out = reject(RejectReason::FrameTooLong);
      break;
    case CobsAccumulator<kMaxFrameLen>::Event::Frame: out = process_frame(acc_.frame(), acc_.size()); break;
  }
  return used;
}

DeframeResult Deframer::process_frame(const std::uint8_t* frame, std::size_t n) {
  bump(counters_.frames_total);
  // 1-2: split and bound (feed() has done both; repeated for direct callers).
  if (n == 0) return reject(RejectReason::EmptyFrame);
  if (n > kMaxFrameLen) return reject(RejectReason::FrameTooLong);

  // 3: COBS.
  std::size_t len = 0;
  if (cobs_decode(frame, n, decoded_.data(), decoded_.size(), len) != CobsStatus::Ok) {
    return reject(RejectReason::CobsError);
  }
  const std::uint8_t* p = decoded_.data();

  // 4: minimum length (headers and CRC).
  if (len < kMinPacketWithCrc) return reject(RejectReason::TooShort);

  // 5: CRC over everything before the last two bytes, stored big-endian.
  const std::size_t body_len = len - kCrcSize;
  const std::uint16_t crc_rx = static_cast<std::uint16_t>((p[body_len] << 8) | p[body_len + 1]);
  if (crc16_ccitt_false(p, body_len) != crc_rx) return reject(RejectReason::BadCrc);

  // 6: header fields.
  const PrimaryHeader h = unpack_primary_header(p);
  if (h.version != 0) return reject(RejectReason::WrongVersion);
  if (h.type != packet_type_of(accept_)) return reject(RejectReason::WrongType);
  if (!h.sec_header) return reject(RejectReason::WrongSecondaryHeaderFlag);

  // 7: length field against the frame, in 32 bits (0xFFFF + 7 does not wrap).
  const std::uint32_t announced = packet_length_from_field(h.data_length);
  if (announced > body_len) return reject(RejectReason::LengthFieldTooLong);
  if (announced < body_len) return reject(RejectReason::LengthFieldTooShort);

  // 8: APID known for this direction, its sequence flags allowed, its length exact.
  const int row = apid_index(h.apid);
  if (row < 0) return reject(RejectReason::UnknownApid, -1, h.apid);
  const ApidInfo& info = kApidTable[static_cast<std::size_t>(row)];
  if (info.direction != accept_) return reject(RejectReason::UnknownApid, -1, h.apid);
  if (!info.segmentable && h.seq_flags != SeqFlags::Unsegmented) {
    return reject(RejectReason::WrongSequenceFlags, row, h.apid);
  }
  const std::size_t payload_len = body_len - kPacketHeaderSize;
  if (payload_len != info.payload_len) return reject(RejectReason::WrongPayloadLength, row, h.apid);
  const std::uint8_t* payload = p + kPacketHeaderSize;

  // 9: time tag, sequence count and time order. The history is updated only
  // for a packet that passes step 10 too: a refused packet changes nothing,
  // so a bad one (a far-future time tag on a NaN payload) cannot lock the
  // APID out. The next accepted packet counts a refused one as a gap.
  ApidLinkStats& st = counters_.per_apid[static_cast<std::size_t>(row)];
  const double t_s = unpack_time_tag(p + kPrimaryHeaderSize);
  if (!std::isfinite(t_s)) return reject(RejectReason::BadTimeTag, row, h.apid);
  std::uint32_t missing = 0;  // committed only if the packet is accepted
  bool resync = false;
  if (st.seen) {
    const std::uint16_t delta =
        static_cast<std::uint16_t>((h.seq_count + kSeqCountModulo - st.last_seq) % kSeqCountModulo);
    if (delta == 0) {
      bump(st.duplicates);
      return reject(RejectReason::DuplicateSequence, row, h.apid);
    }
    if (t_s < st.last_t_s) {
      bump(st.out_of_order);
      return reject(RejectReason::TimeBackwards, row, h.apid);
    }
    if (delta >= kHalfSeq) {
      // Behind: a reordered or replayed packet unless time moved on (the
      // sender restarted its counts, or an outage longer than half the count).
      if (!(t_s > st.last_t_s)) {
        bump(st.out_of_order);
        return reject(RejectReason::StaleSequence, row, h.apid);
      }
      resync = true;
    } else {
      missing = delta - 1u;
    }
  }

  // 10: payload values.
  for (std::size_t i = 0; i < info.f64_count; ++i) {
    if (!std::isfinite(get_f64le(payload + info.f64_offset + 8 * i))) {
      return reject(RejectReason::NonFinitePayload, row, h.apid);
    }
  }
  if (info.quat_offset >= 0) {
    double n2 = 0.0;
    for (std::size_t i = 0; i < 4; ++i) {
      const double c = get_f64le(payload + info.quat_offset + 8 * i);
      n2 += c * c;
    }
    if (!(std::fabs(std::sqrt(n2) - 1.0) <= kQuatNormTol)) {
      return reject(RejectReason::NonUnitQuaternion, row, h.apid);
    }
  }
  if (!payload_fields_valid(info.apid, h.seq_flags, payload)) {
    return reject(RejectReason::InvalidField, row, h.apid);
  }

  if (resync) bump(st.resyncs);
  st.gaps = (UINT32_MAX - st.gaps < missing) ? UINT32_MAX : st.gaps + missing;
  st.seen = true;
  st.last_seq = h.seq_count;
  st.last_t_s = t_s;
  bump(st.accepted);
  bump(counters_.packets_accepted);
  DeframeResult out;
  out.kind = DeframeResult::Kind::Packet;
  out.apid = h.apid;
  out.packet.header = h;
  out.packet.info = &info;
  out.packet.t_s = t_s;
  out.packet.packet = p;
  out.packet.packet_len = static_cast<std::uint16_t>(body_len);
  out.packet.payload = payload;
  out.packet.payload_len = static_cast<std::uint16_t>(payload_len);
  return out;
}

}  // namespace fsw
