// The link code allocates nothing: framing, deframing (valid and malformed
// input) and the typed payload codecs in float and double, inside a guard
// that counts every operator new and forbids Eigen allocation.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <limits>

#include "fsw/link/apid.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

namespace {
// A valid payload for one table row, written into a fixed buffer.
void fill_valid(const ApidInfo& info, std::uint8_t* p) {
  for (std::size_t i = 0; i < info.payload_len; ++i) p[i] = 0;
  for (std::size_t i = 0; i < info.f64_count; ++i) put_f64le(p + info.f64_offset + 8 * i, 0.5);
  if (info.quat_offset >= 0) {
    put_f64le(p + info.quat_offset, 1.0);
    for (int i = 1; i < 4; ++i) put_f64le(p + info.quat_offset + 8 * i, 0.0);
  }
  if (info.apid == Apid::RangeImageSegment) {
    put_u16le(p + 4, 24);
    put_u16le(p + 8, 24);
  }
}
}  // namespace

TEST(NoHeapLink, FrameAndDeframeEveryApidBothDirections) {
  static Framer to_flight(Direction::ToFlight);
  static Framer from_flight(Direction::FromFlight);
  static Deframer flight_side(Direction::ToFlight);
  static Deframer bench_side(Direction::FromFlight);
  static std::array<std::uint8_t, kMaxPayloadLen> payload{};
  static std::array<std::uint8_t, kMaxFrameBytes> frame{};
  std::size_t delivered = 0;
  NoHeapGuard guard;
  for (int round = 0; round < 50; ++round) {
    for (const auto& info : kApidTable) {
      fill_valid(info, payload.data());
      Framer& fr = info.direction == Direction::ToFlight ? to_flight : from_flight;
      Deframer& d = info.direction == Direction::ToFlight ? flight_side : bench_side;
      const std::size_t n =
          fr.frame(info.apid, 1.0 + round, payload.data(), info.payload_len, frame.data(), frame.size());
      ASSERT_GT(n, 0u);
      // Corrupt every third frame so that the rejection paths run too.
      if (round % 3 == 1) frame[n / 2] ^= 0x10;
      DeframeResult r;
      std::size_t pos = 0;
      while (pos < n) {
        pos += d.feed(frame.data() + pos, n - pos, r);
        if (r.kind == DeframeResult::Kind::Packet) ++delivered;
      }
    }
  }
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_GT(delivered, 0u);
  EXPECT_GT(flight_side.counters().rejected_total(), 0u);
}

TEST(NoHeapLink, RunawayAndGarbage) {
  static Deframer d;
  static std::array<std::uint8_t, 4096> noise{};
  for (std::size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<std::uint8_t>(i * 37 + 1);
  NoHeapGuard guard;
  DeframeResult r;
  std::size_t pos = 0;
  while (pos < noise.size()) pos += d.feed(noise.data() + pos, noise.size() - pos, r);
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_EQ(d.counters().packets_accepted, 0u);
}

template <typename S>
class NoHeapLinkCodec : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(NoHeapLinkCodec, Scalars);

TYPED_TEST(NoHeapLinkCodec, EncodeDecodeEveryMessage) {
  using S = TypeParam;
  static std::array<std::uint8_t, kMaxPayloadLen> p{};
  static ImuSampleMsg<S> imu;
  static LedPoseMsg<S> pose;
  static ThrusterValvesMsg<S> valves;
  static RangeImageSegmentMsg<S> seg;
  static CmdResetMsg<S> reset;
  static CmdConfigMsg<S> config;
  static TmEstimateMsg<S> est;
  static TmCovarianceDiagMsg<S> cov;
  static TmInnovationMsg<S> inn;
  static TmLearnerMsg<S> learn;
  static TmLinkCountersMsg link;
  static TmHousekeepingMsg<S> hk;
  NoHeapGuard guard;
  bool ok = true;
  encode(imu, p.data());
  ok &= decode(p.data(), 1.0, imu);
  encode(pose, p.data());
  ok &= decode(p.data(), 1.0, pose);
  encode(valves, p.data());
  ok &= decode(p.data(), 1.0, valves);
  encode(seg, p.data());
  ok &= decode(p.data(), 1.0, SeqFlags::Unsegmented, seg);
  encode(reset, p.data());
  ok &= decode(p.data(), 1.0, reset);
  encode(config, p.data());
  ok &= decode(p.data(), 1.0, config);
  encode(est, p.data());
  ok &= decode(p.data(), 1.0, est);
  encode(cov, p.data());
  ok &= decode(p.data(), 1.0, cov);
  encode(inn, p.data());
  ok &= decode(p.data(), 1.0, inn);
  encode(learn, p.data());
  ok &= decode(p.data(), 1.0, learn);
  encode(link, p.data());
  ok &= decode(p.data(), 1.0, link);
  encode(hk, p.data());
  ok &= decode(p.data(), 1.0, hk);
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_TRUE(ok);
}
