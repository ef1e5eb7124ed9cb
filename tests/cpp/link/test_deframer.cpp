// The streaming deframer: one named test per malformed case of the
// decoding order (docs/LINK.md, deframer.hpp), plus sequence, time and segmentation behaviour.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "link_test_util.hpp"

using namespace fsw;
using namespace link_test;
using Kind = DeframeResult::Kind;

namespace {

struct Outcome {
  std::vector<Bytes> packets;  // delivered packets (header .. payload, no CRC)
  std::vector<RejectReason> rejections;
};

// Feeds a byte stream in chunks of the given size (0 = all at once).
Outcome run(Deframer& d, const Bytes& stream, std::size_t chunk = 0) {
  Outcome o;
  std::size_t pos = 0;
  while (pos < stream.size()) {
    std::size_t n = chunk == 0 ? stream.size() - pos : std::min(chunk, stream.size() - pos);
    const std::uint8_t* p = stream.data() + pos;
    pos += n;
    while (n > 0) {
      DeframeResult r;
      const std::size_t used = d.feed(p, n, r);
      p += used;
      n -= used;
      if (r.kind == Kind::Packet) {
        o.packets.emplace_back(r.packet.packet, r.packet.packet + r.packet.packet_len);
      } else if (r.kind == Kind::Rejected) {
        o.rejections.push_back(r.reason);
      }
    }
  }
  return o;
}

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

Bytes strip_crc(const Bytes& pkt) { return Bytes(pkt.begin(), pkt.end() - 2); }

// One malformed packet, expected to be rejected with one reason.
void expect_single_rejection(const Bytes& stream, RejectReason why, Direction dir = Direction::ToFlight) {
  Deframer d(dir);
  const Outcome o = run(d, stream);
  EXPECT_TRUE(o.packets.empty());
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], why) << "got " << to_string(o.rejections[0]);
  EXPECT_EQ(d.counters().rejected[static_cast<std::size_t>(why)], 1u);
  EXPECT_EQ(d.counters().rejected_total(), 1u);
  EXPECT_EQ(d.counters().packets_accepted, 0u);
}

Bytes imu_payload() { return valid_payload(*apid_info(0x010)); }

}  // namespace

// ---------------------------------------------------------------- framing

TEST(Deframer, ValidFrameDelivered) {
  Deframer d;
  const Bytes pkt = raw_packet(header_for(Apid::ImuSample, 7), 1.5, imu_payload());
  const Outcome o = run(d, frame_of(pkt));
  ASSERT_EQ(o.packets.size(), 1u);
  EXPECT_EQ(o.packets[0], strip_crc(pkt));
  EXPECT_TRUE(o.rejections.empty());
  EXPECT_EQ(d.counters().packets_accepted, 1u);
}

TEST(Deframer, DeliveredViewCarriesHeaderTimeAndPayload) {
  Deframer d;
  const Bytes f = valid_frame(Apid::LedPose, 42, 17.25);
  DeframeResult r;
  ASSERT_EQ(d.feed(f.data(), f.size(), r), f.size());
  ASSERT_EQ(r.kind, Kind::Packet);
  EXPECT_EQ(r.packet.header.apid, 0x011);
  EXPECT_EQ(r.packet.header.seq_count, 42);
  EXPECT_EQ(r.packet.t_s, 17.25);
  EXPECT_EQ(r.packet.payload_len, 72);
  EXPECT_EQ(r.packet.info->apid, Apid::LedPose);
  LedPoseMsg<double> m;
  ASSERT_TRUE(decode(r.packet.payload, r.packet.t_s, m));
  EXPECT_DOUBLE_EQ(m.q_hb.w(), 0.5);
}

TEST(Deframer, EmptyFrame) { expect_single_rejection(Bytes{0x00}, RejectReason::EmptyFrame); }

TEST(Deframer, GarbageBeforeFirstZero) {
  // Opening the port mid-frame: the tail of a frame, its 0x00, then frames.
  Deframer d;
  std::mt19937 rng(3);
  Bytes garbage(37);
  for (auto& b : garbage) b = static_cast<std::uint8_t>(1 + rng() % 255);
  garbage.push_back(0x00);
  const Outcome o = run(d, cat({garbage, valid_frame(Apid::ImuSample, 0, 1.0)}));
  EXPECT_EQ(o.rejections.size(), 1u);
  ASSERT_EQ(o.packets.size(), 1u);
  EXPECT_EQ(d.counters().rejected_total(), 1u);
}

TEST(Deframer, GarbageWithoutZeroCostsOnlyTheFirstFrame) {
  Deframer d;
  const Bytes garbage = {0x13, 0x37, 0xAB};
  const Outcome o = run(d, cat({garbage, valid_frame(Apid::ImuSample, 0, 1.0), valid_frame(Apid::ImuSample, 1, 1.1)}));
  EXPECT_EQ(o.rejections.size(), 1u);
  ASSERT_EQ(o.packets.size(), 1u);
  EXPECT_EQ(unpack_primary_header(o.packets[0].data()).seq_count, 1);
}

TEST(Deframer, CobsCodePastEnd) { expect_single_rejection(Bytes{0x05, 0x11, 0x22, 0x00}, RejectReason::CobsError); }

TEST(Deframer, RunawayFrameWithoutZero) {
  Deframer d;
  Bytes noise(5 * kMaxFrameLen, 0x5A);
  Outcome o = run(d, noise, 64);
  EXPECT_TRUE(o.packets.empty());
  ASSERT_EQ(o.rejections.size(), 1u);  // reported once, not once per byte
  EXPECT_EQ(o.rejections[0], RejectReason::FrameTooLong);
  // The next 0x00 resynchronises without a second rejection.
  o = run(d, cat({Bytes{0x00}, valid_frame(Apid::ImuSample, 0, 1.0)}));
  EXPECT_TRUE(o.rejections.empty());
  EXPECT_EQ(o.packets.size(), 1u);
}

TEST(Deframer, LongestValidFrameIsWithinTheBound) {
  const Bytes f = valid_frame(Apid::RangeImageSegment, 0, 1.0);
  EXPECT_LE(f.size(), kMaxFrameBytes);
  Deframer d;
  EXPECT_EQ(run(d, f).packets.size(), 1u);
}

TEST(Deframer, ProcessFrameRefusesOversizedFrame) {
  Deframer d;
  Bytes big(kMaxFrameLen + 1, 0x01);
  EXPECT_EQ(d.process_frame(big.data(), big.size()).reason, RejectReason::FrameTooLong);
}

TEST(Deframer, FrameSplitOverManyReads) {
  const Bytes stream = cat({valid_frame(Apid::RangeImageSegment, 0, 1.0), valid_frame(Apid::ImuSample, 0, 1.0),
                            valid_frame(Apid::LedPose, 0, 1.0)});
  for (std::size_t chunk : {1u, 2u, 3u, 7u, 64u, 255u}) {
    Deframer d;
    const Outcome o = run(d, stream, chunk);
    EXPECT_EQ(o.packets.size(), 3u) << "chunk " << chunk;
    EXPECT_TRUE(o.rejections.empty());
  }
}

TEST(Deframer, SeveralFramesInOneRead) {
  Bytes stream;
  for (std::uint16_t k = 0; k < 20; ++k) {
    const Bytes f = valid_frame(Apid::ImuSample, k, 0.1 * k);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  Deframer d;
  const Outcome o = run(d, stream);
  ASSERT_EQ(o.packets.size(), 20u);
  for (std::uint16_t k = 0; k < 20; ++k) EXPECT_EQ(unpack_primary_header(o.packets[k].data()).seq_count, k);
  EXPECT_EQ(d.counters().gaps_total(), 0u);
}

// ---------------------------------------------------------------- packet

TEST(Deframer, TooShort) {
  // 15 bytes with a valid CRC: one short of headers + CRC.
  Bytes body(13, 0x01);
  const std::uint16_t crc = crc16_ccitt_false(body.data(), body.size());
  body.push_back(static_cast<std::uint8_t>(crc >> 8));
  body.push_back(static_cast<std::uint8_t>(crc));
  ASSERT_EQ(body.size(), kMinPacketWithCrc - 1);
  expect_single_rejection(frame_of(body), RejectReason::TooShort);
}

TEST(Deframer, BadCrc) {
  Bytes pkt = raw_packet(header_for(Apid::ImuSample, 0), 1.0, imu_payload());
  pkt.back() ^= 0x01;
  expect_single_rejection(frame_of(pkt), RejectReason::BadCrc);
}

TEST(Deframer, LengthFieldTooLong) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.data_length = static_cast<std::uint16_t>(8 + 48 - 1 + 1);
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload(), false)), RejectReason::LengthFieldTooLong);
}

TEST(Deframer, LengthFieldTooShort) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.data_length = static_cast<std::uint16_t>(8 + 48 - 1 - 1);
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload(), false)), RejectReason::LengthFieldTooShort);
}

TEST(Deframer, LengthFieldFFFF) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.data_length = 0xFFFF;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload(), false)), RejectReason::LengthFieldTooLong);
}

TEST(Deframer, LengthFieldZero) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.data_length = 0;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload(), false)), RejectReason::LengthFieldTooShort);
}

TEST(Deframer, WrongVersion) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.version = 1;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload())), RejectReason::WrongVersion);
}

TEST(Deframer, WrongType) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.type = PacketType::Telemetry;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload())), RejectReason::WrongType);
}

TEST(Deframer, WrongSecondaryHeaderFlag) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.sec_header = false;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload())), RejectReason::WrongSecondaryHeaderFlag);
}

TEST(Deframer, WrongSequenceFlags) {
  for (SeqFlags f : {SeqFlags::First, SeqFlags::Continuation, SeqFlags::Last}) {
    expect_single_rejection(frame_of(raw_packet(header_for(Apid::ImuSample, 0, f), 1.0, imu_payload())),
                            RejectReason::WrongSequenceFlags);
  }
}

TEST(Deframer, UnknownApid) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.apid = 0x123;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload())), RejectReason::UnknownApid);
}

TEST(Deframer, IdleApidIsUnknown) {
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.apid = kIdleApid;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, imu_payload())), RejectReason::UnknownApid);
}

TEST(Deframer, TelemetryApidSentToFlightIsUnknown) {
  // Right type bit for the flight side, but an APID that only flows the other way.
  PrimaryHeader h = header_for(Apid::TmEstimate, 0);
  h.type = PacketType::Telecommand;
  expect_single_rejection(frame_of(raw_packet(h, 1.0, valid_payload(*apid_info(0x040)))), RejectReason::UnknownApid);
}

TEST(Deframer, WrongPayloadLength) {
  Bytes p = imu_payload();
  p.push_back(0);
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::ImuSample, 0), 1.0, p)),
                          RejectReason::WrongPayloadLength);
}

TEST(Deframer, EverySingleBitFlipRejected) {
  // Every bit of the encoded frame, its 0x00 included, for the smallest and
  // the largest packet. Each corrupted frame is followed by a good one: the
  // corrupted frame must never deliver, and the good one must come through
  // unless the flip removed the delimiter (the two frames then merge).
  for (Apid apid : {Apid::ImuSample, Apid::RangeImageSegment}) {
    Deframer d;
    const Bytes frame = valid_frame(apid, 0, 1.0);
    std::uint16_t seq = 1;
    std::size_t delivered_corrupt = 0;
    for (std::size_t bit = 0; bit < frame.size() * 8; ++bit) {
      Bytes bad = frame;
      bad[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
      const Bytes good_pkt =
          raw_packet(header_for(apid, seq), 1.0 + seq, valid_payload(*apid_info(static_cast<std::uint16_t>(apid))));
      ++seq;
      const Outcome o = run(d, cat({bad, frame_of(good_pkt)}));
      for (const auto& p : o.packets) {
        if (p != strip_crc(good_pkt)) ++delivered_corrupt;
      }
      const bool delimiter = bit / 8 == frame.size() - 1;
      ASSERT_EQ(o.packets.size(), delimiter ? 0u : 1u) << "bit " << bit;
      ASSERT_GE(o.rejections.size(), 1u) << "bit " << bit;
    }
    EXPECT_EQ(delivered_corrupt, 0u);
    EXPECT_EQ(d.counters().rejected[static_cast<std::size_t>(RejectReason::DuplicateSequence)], 0u);
  }
}

// ---------------------------------------------------------------- payload

TEST(Deframer, NanPayload) {
  Bytes p = imu_payload();
  put_f64le(p.data() + 16, std::numeric_limits<double>::quiet_NaN());
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::ImuSample, 0), 1.0, p)), RejectReason::NonFinitePayload);
}

TEST(Deframer, InfPayload) {
  for (double inf : {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
    Bytes p = imu_payload();
    put_f64le(p.data() + 40, inf);
    expect_single_rejection(frame_of(raw_packet(header_for(Apid::ImuSample, 0), 1.0, p)),
                            RejectReason::NonFinitePayload);
  }
}

TEST(Deframer, NanInLastRangePointRejected) {
  Bytes p = valid_payload(*apid_info(0x013));
  put_f64le(p.data() + 780 - 8, std::numeric_limits<double>::quiet_NaN());
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::RangeImageSegment, 0), 1.0, p)),
                          RejectReason::NonFinitePayload);
}

TEST(Deframer, NonUnitQuaternion) {
  Bytes p = valid_payload(*apid_info(0x011));
  put_f64le(p.data() + 24, 0.5 * 1.001);
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::LedPose, 0), 1.0, p)), RejectReason::NonUnitQuaternion);
}

TEST(Deframer, ZeroQuaternionRejected) {
  Bytes p = valid_payload(*apid_info(0x020));
  for (int i = 0; i < 4; ++i) put_f64le(p.data() + 56 + 8 * i, 0.0);
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::CmdReset, 0), 1.0, p)), RejectReason::NonUnitQuaternion);
}

TEST(Deframer, QuaternionWithinToleranceAccepted) {
  Bytes p = valid_payload(*apid_info(0x011));
  const double s = 1.0 + 0.5 * kQuatNormTol;
  for (int i = 0; i < 4; ++i) put_f64le(p.data() + 24 + 8 * i, get_f64le(p.data() + 24 + 8 * i) * s);
  Deframer d;
  EXPECT_EQ(run(d, frame_of(raw_packet(header_for(Apid::LedPose, 0), 1.0, p))).packets.size(), 1u);
}

TEST(Deframer, InvalidSegmentFields) {
  Bytes p = valid_payload(*apid_info(0x013));
  put_u16le(p.data() + 8, 25);  // more points than a segment holds
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::RangeImageSegment, 0), 1.0, p)),
                          RejectReason::InvalidField);
}

TEST(Deframer, NegativeSigmaIsInvalidField) {
  Bytes p = valid_payload(*apid_info(0x011));
  put_f64le(p.data() + 56, -0.1);
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::LedPose, 0), 1.0, p)), RejectReason::InvalidField);
}

// ---------------------------------------------------------------- sequence and time

TEST(Deframer, BadTimeTag) {
  expect_single_rejection(
      frame_of(raw_packet(header_for(Apid::ImuSample, 0), std::numeric_limits<double>::quiet_NaN(), imu_payload())),
      RejectReason::BadTimeTag);
}

TEST(Deframer, TimeGoingBackwards) {
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 0, 2.0), valid_frame(Apid::ImuSample, 1, 1.9)}));
  EXPECT_EQ(o.packets.size(), 1u);
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::TimeBackwards);
  EXPECT_EQ(d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))].out_of_order, 1u);
}

TEST(Deframer, TimeIsPerApid) {
  // A late pose (capture time earlier than the last IMU sample) is not "backwards".
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 0, 10.0), valid_frame(Apid::LedPose, 0, 9.5)}));
  EXPECT_EQ(o.packets.size(), 2u);
}

TEST(Deframer, EqualTimeTagsAccepted) {
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 0, 2.0), valid_frame(Apid::ImuSample, 1, 2.0)}));
  EXPECT_EQ(o.packets.size(), 2u);
}

TEST(Deframer, SequenceWrap16383To0) {
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 16382, 1.0), valid_frame(Apid::ImuSample, 16383, 1.1),
                                valid_frame(Apid::ImuSample, 0, 1.2), valid_frame(Apid::ImuSample, 1, 1.3)}));
  EXPECT_EQ(o.packets.size(), 4u);
  EXPECT_EQ(d.counters().gaps_total(), 0u);
  EXPECT_EQ(d.counters().duplicates_total(), 0u);
}

TEST(Deframer, SequenceGapCountedAcrossWrap) {
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 16380, 1.0), valid_frame(Apid::ImuSample, 2, 1.1)}));
  EXPECT_EQ(o.packets.size(), 2u);
  EXPECT_EQ(d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))].gaps, 5u);  // 16381..1
}

TEST(Deframer, SequenceGapsArePerApid) {
  Deframer d;
  run(d, cat({valid_frame(Apid::ImuSample, 0, 1.0), valid_frame(Apid::LedPose, 5, 1.0),
              valid_frame(Apid::ImuSample, 1, 1.1), valid_frame(Apid::LedPose, 9, 2.0)}));
  EXPECT_EQ(d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))].gaps, 0u);
  EXPECT_EQ(d.counters().per_apid[static_cast<std::size_t>(apid_index(0x011))].gaps, 3u);
}

TEST(Deframer, DuplicateSequenceRejectedAndCounted) {
  Deframer d;
  const Bytes f = valid_frame(Apid::ImuSample, 4, 1.0);
  const Outcome o = run(d, cat({f, f}));
  EXPECT_EQ(o.packets.size(), 1u);
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::DuplicateSequence);
  EXPECT_EQ(d.counters().duplicates_total(), 1u);
}

TEST(Deframer, ReorderedSegmentsWithEqualTimeAreStale) {
  Deframer d;
  const Outcome o =
      run(d, cat({valid_frame(Apid::RangeImageSegment, 1, 5.0), valid_frame(Apid::RangeImageSegment, 0, 5.0)}));
  EXPECT_EQ(o.packets.size(), 1u);
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::StaleSequence);
}

TEST(Deframer, SenderRestartResyncs) {
  // The count jumps back but time moves on: accepted, counted as a resync.
  Deframer d;
  const Outcome o = run(d, cat({valid_frame(Apid::ImuSample, 100, 1.0), valid_frame(Apid::ImuSample, 0, 1.1),
                                valid_frame(Apid::ImuSample, 1, 1.2)}));
  EXPECT_EQ(o.packets.size(), 3u);
  const auto& st = d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))];
  EXPECT_EQ(st.resyncs, 1u);
  EXPECT_EQ(st.gaps, 0u);
}

TEST(Deframer, RefusedPayloadLeavesTheHistory) {
  // A packet refused for its payload changes neither the sequence nor the
  // time history: a NaN sample tagged far in the future does not block the
  // normal samples after it; the next accepted one counts it as a gap.
  Deframer d;
  Bytes p = imu_payload();
  put_f64le(p.data(), std::numeric_limits<double>::quiet_NaN());
  const Outcome o =
      run(d, cat({valid_frame(Apid::ImuSample, 0, 1.0), frame_of(raw_packet(header_for(Apid::ImuSample, 1), 1e12, p)),
                  valid_frame(Apid::ImuSample, 2, 1.2), valid_frame(Apid::ImuSample, 3, 1.3)}));
  EXPECT_EQ(o.packets.size(), 3u);
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::NonFinitePayload);
  const auto& st = d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))];
  EXPECT_EQ(st.last_t_s, 1.3);
  EXPECT_EQ(st.last_seq, 3u);
  EXPECT_EQ(st.gaps, 1u);
  EXPECT_EQ(st.out_of_order, 0u);
}

TEST(Deframer, RefusedPayloadDoesNotCountAResync) {
  // A refused packet far behind in count but later in time is not a resync:
  // the next in-sequence packet is accepted without a gap.
  Deframer d;
  Bytes p = imu_payload();
  put_f64le(p.data(), std::numeric_limits<double>::infinity());
  const Outcome o =
      run(d, cat({valid_frame(Apid::ImuSample, 100, 1.0), frame_of(raw_packet(header_for(Apid::ImuSample, 5), 2.0, p)),
                  valid_frame(Apid::ImuSample, 101, 1.1)}));
  EXPECT_EQ(o.packets.size(), 2u);
  const auto& st = d.counters().per_apid[static_cast<std::size_t>(apid_index(0x010))];
  EXPECT_EQ(st.resyncs, 0u);
  EXPECT_EQ(st.gaps, 0u);
}

TEST(Deframer, ResetTimeHistoryKeepsSequenceCounts) {
  // After a far-future packet, time_backwards until the time history is
  // cleared; a repeated count is still a duplicate afterwards.
  Deframer d;
  run(d, valid_frame(Apid::CmdReset, 0, 1e300));
  Outcome o = run(d, valid_frame(Apid::CmdReset, 1, 5.0));
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::TimeBackwards);
  d.reset_time_history();
  o = run(d, cat({valid_frame(Apid::CmdReset, 1, 5.0), valid_frame(Apid::CmdReset, 1, 6.0)}));
  EXPECT_EQ(o.packets.size(), 1u);
  ASSERT_EQ(o.rejections.size(), 1u);
  EXPECT_EQ(o.rejections[0], RejectReason::DuplicateSequence);
}

TEST(Deframer, SegmentedRangeImageAccepted) {
  // 50 points: first (0..23), continuation (24..47), last (48..49).
  Deframer d;
  Bytes stream;
  const std::uint16_t firsts[3] = {0, 24, 48};
  const std::uint16_t counts[3] = {24, 24, 2};
  const SeqFlags flags[3] = {SeqFlags::First, SeqFlags::Continuation, SeqFlags::Last};
  for (int s = 0; s < 3; ++s) {
    Bytes p = valid_payload(*apid_info(0x013));
    put_u16le(p.data() + 4, 50);
    put_u16le(p.data() + 6, firsts[s]);
    put_u16le(p.data() + 8, counts[s]);
    const Bytes f =
        frame_of(raw_packet(header_for(Apid::RangeImageSegment, static_cast<std::uint16_t>(s), flags[s]), 60.0, p));
    stream.insert(stream.end(), f.begin(), f.end());
  }
  const Outcome o = run(d, stream);
  EXPECT_EQ(o.packets.size(), 3u);
  EXPECT_TRUE(o.rejections.empty());
}

TEST(Deframer, SegmentFlagsMustMatchPosition) {
  Bytes p = valid_payload(*apid_info(0x013));  // 24 of 24 points: a whole image
  expect_single_rejection(frame_of(raw_packet(header_for(Apid::RangeImageSegment, 0, SeqFlags::First), 1.0, p)),
                          RejectReason::InvalidField);
}

// ---------------------------------------------------------------- framer and counters

TEST(Deframer, EveryApidRoundTripsThroughTheFramer) {
  for (Direction dir : {Direction::ToFlight, Direction::FromFlight}) {
    Framer fr(dir);
    Deframer d(dir);
    std::size_t expected = 0;
    for (const auto& info : kApidTable) {
      if (info.direction != dir) {
        Bytes out(kMaxFrameBytes);
        const Bytes p = valid_payload(info);
        EXPECT_EQ(fr.frame(info.apid, 1.0, p.data(), p.size(), out.data(), out.size()), 0u);
        continue;
      }
      const Bytes p = valid_payload(info);
      Bytes out(kMaxFrameBytes);
      out.resize(fr.frame(info.apid, 1.0, p.data(), p.size(), out.data(), out.size()));
      ASSERT_GT(out.size(), 0u) << info.name;
      const Outcome o = run(d, out);
      ASSERT_EQ(o.packets.size(), 1u) << info.name;
      EXPECT_TRUE(std::equal(p.begin(), p.end(), o.packets[0].begin() + kPacketHeaderSize)) << info.name;
      ++expected;
    }
    EXPECT_EQ(d.counters().packets_accepted, expected);
  }
}

TEST(Deframer, FramerCountsAndWrapsSequence) {
  Framer fr(Direction::ToFlight);
  fr.set_next_seq(Apid::ImuSample, 16383);
  Deframer d;
  const Bytes p = imu_payload();
  for (int k = 0; k < 3; ++k) {
    Bytes out(kMaxFrameBytes);
    out.resize(fr.frame(Apid::ImuSample, 1.0 + k, p.data(), p.size(), out.data(), out.size()));
    run(d, out);
  }
  EXPECT_EQ(fr.next_seq(Apid::ImuSample), 2);
  EXPECT_EQ(d.counters().packets_accepted, 3u);
  EXPECT_EQ(d.counters().gaps_total(), 0u);
}

TEST(Deframer, FramerRefusesMisuse) {
  Framer fr(Direction::ToFlight);
  Bytes out(kMaxFrameBytes);
  const Bytes p = imu_payload();
  EXPECT_EQ(fr.frame(Apid::ImuSample, 1.0, p.data(), p.size() - 1, out.data(), out.size()), 0u);
  EXPECT_EQ(fr.frame(Apid::ImuSample, 1.0, p.data(), p.size(), out.data(), 10), 0u);
  EXPECT_EQ(fr.frame(Apid::ImuSample, 1.0, p.data(), p.size(), out.data(), out.size(), SeqFlags::First), 0u);
  EXPECT_EQ(fr.next_seq(Apid::ImuSample), 0);  // nothing sent, nothing counted
}

TEST(Deframer, FramerTypedMessage) {
  Framer fr(Direction::FromFlight);
  TmEstimateMsg<float> m;
  m.r_hill_m << 1.f, 2.f, 3.f;
  Bytes out(kMaxFrameBytes);
  out.resize(fr.frame_message(Apid::TmEstimate, m, 4.0, out.data(), out.size()));
  Deframer d(Direction::FromFlight);
  DeframeResult r;
  d.feed(out.data(), out.size(), r);
  ASSERT_EQ(r.kind, Kind::Packet);
  TmEstimateMsg<double> u;
  ASSERT_TRUE(decode(r.packet.payload, r.packet.t_s, u));
  EXPECT_EQ(u.r_hill_m(2), 3.0);
}

TEST(Deframer, CountersPerReasonAreExact) {
  Deframer d;
  PrimaryHeader h = header_for(Apid::ImuSample, 0);
  h.version = 2;
  Bytes bad_crc = raw_packet(header_for(Apid::ImuSample, 0), 1.0, imu_payload());
  bad_crc[10] ^= 0x40;
  run(d, cat({Bytes{0x00}, Bytes{0x00}, frame_of(raw_packet(h, 1.0, imu_payload())), frame_of(bad_crc),
              valid_frame(Apid::ImuSample, 0, 1.0), Bytes{0x00}}));
  const auto& c = d.counters();
  EXPECT_EQ(c.rejected[static_cast<std::size_t>(RejectReason::EmptyFrame)], 3u);
  EXPECT_EQ(c.rejected[static_cast<std::size_t>(RejectReason::WrongVersion)], 1u);
  EXPECT_EQ(c.rejected[static_cast<std::size_t>(RejectReason::BadCrc)], 1u);
  EXPECT_EQ(c.rejected_total(), 5u);
  EXPECT_EQ(c.packets_accepted, 1u);
  EXPECT_EQ(c.frames_total, 6u);
  d.reset_counters();
  EXPECT_EQ(d.counters().rejected_total(), 0u);
}

TEST(Deframer, ResetHistoryForgetsSequenceAndTime) {
  Deframer d;
  run(d, valid_frame(Apid::ImuSample, 5, 100.0));
  d.reset_history();
  const Outcome o = run(d, valid_frame(Apid::ImuSample, 5, 0.0));
  EXPECT_EQ(o.packets.size(), 1u);
}

TEST(RejectReasonNames, StableAndDistinct) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < kRejectReasonCount; ++i) {
    const std::string s = to_string(static_cast<RejectReason>(i));
    EXPECT_NE(s, "unknown");
    names.insert(s);
  }
  EXPECT_EQ(names.size(), kRejectReasonCount);
  EXPECT_STREQ(to_string(RejectReason::BadCrc), "bad_crc");
  EXPECT_STREQ(to_string(RejectReason::EmptyFrame), "empty_frame");
  EXPECT_STREQ(to_string(RejectReason::InvalidField), "invalid_field");
  EXPECT_STREQ(to_string(static_cast<RejectReason>(200)), "unknown");
}
