// COBS encoder, decoder and the streaming accumulator.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "fsw/link/cobs.hpp"

using namespace fsw;
using Bytes = std::vector<std::uint8_t>;

namespace {
Bytes enc(const Bytes& in) {
  Bytes out(cobs_max_encoded_size(in.size()));
  const std::size_t n = cobs_encode(in.data(), in.size(), out.data(), out.size());
  out.resize(n);
  return out;
}
CobsStatus dec(const Bytes& in, Bytes& out) {
  out.assign(in.size() + 1, 0xEE);
  std::size_t n = 0;
  const CobsStatus s = cobs_decode(in.data(), in.size(), out.data(), out.size(), n);
  out.resize(n);
  return s;
}
}  // namespace

// Reference vectors (Wikipedia's COBS examples; the PyPI package agrees).
TEST(Cobs, KnownVectors) {
  EXPECT_EQ(enc({}), (Bytes{0x01}));
  EXPECT_EQ(enc({0x00}), (Bytes{0x01, 0x01}));
  EXPECT_EQ(enc({0x00, 0x00}), (Bytes{0x01, 0x01, 0x01}));
  EXPECT_EQ(enc({0x00, 0x11, 0x00}), (Bytes{0x01, 0x02, 0x11, 0x01}));
  EXPECT_EQ(enc({0x11, 0x22, 0x00, 0x33}), (Bytes{0x03, 0x11, 0x22, 0x02, 0x33}));
  EXPECT_EQ(enc({0x11, 0x22, 0x33, 0x44}), (Bytes{0x05, 0x11, 0x22, 0x33, 0x44}));
  EXPECT_EQ(enc({0x11, 0x00, 0x00, 0x00}), (Bytes{0x02, 0x11, 0x01, 0x01, 0x01}));
}

TEST(Cobs, Run254NonZeroBytesEndsWithoutAnEmptyBlock) {
  // Matches the PyPI package: a full 0xFF block at the end is not followed by 0x01.
  Bytes in(254, 0x01);
  const Bytes e = enc(in);
  ASSERT_EQ(e.size(), 255u);
  EXPECT_EQ(e.front(), 0xFF);
  Bytes d;
  EXPECT_EQ(dec(e, d), CobsStatus::Ok);
  EXPECT_EQ(d, in);
  EXPECT_EQ(enc(Bytes(255, 0x01)).size(), 257u);  // 0xFF block, then a 1-byte block
  EXPECT_EQ(enc(Bytes(508, 0x01)).size(), 510u);
  Bytes with_zero(254, 0x01);
  with_zero.push_back(0);
  EXPECT_EQ(enc(with_zero).size(), 257u);  // 0xFF block, empty block, final empty block
}

TEST(Cobs, DecoderAcceptsTheRedundantTrailingEmptyBlock) {
  Bytes e(1, 0xFF);
  e.insert(e.end(), 254, 0x01);
  e.push_back(0x01);
  Bytes d;
  EXPECT_EQ(dec(e, d), CobsStatus::Ok);
  EXPECT_EQ(d, Bytes(254, 0x01));
}

TEST(Cobs, RoundTripRandomWithNoZeroInOutput) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 500; ++trial) {
    Bytes in(rng() % 1100);
    for (auto& b : in) b = (rng() % 4 == 0) ? 0 : static_cast<std::uint8_t>(rng());
    const Bytes e = enc(in);
    ASSERT_LE(e.size(), cobs_max_encoded_size(in.size()));
    for (auto b : e) ASSERT_NE(b, 0);
    Bytes d;
    ASSERT_EQ(dec(e, d), CobsStatus::Ok);
    ASSERT_EQ(d, in);
  }
}

TEST(Cobs, EncoderRefusesTooSmallBuffer) {
  Bytes in(10, 0x05);
  std::array<std::uint8_t, 10> out{};
  EXPECT_EQ(cobs_encode(in.data(), in.size(), out.data(), out.size()), 0u);
}

TEST(Cobs, DecoderCodePastEnd) {
  Bytes d;
  EXPECT_EQ(dec({0x05, 0x11, 0x22}, d), CobsStatus::CodePastEnd);
  EXPECT_EQ(dec({0xFF}, d), CobsStatus::CodePastEnd);
}

TEST(Cobs, DecoderZeroInFrame) {
  Bytes d;
  EXPECT_EQ(dec({0x03, 0x11, 0x00}, d), CobsStatus::ZeroInFrame);
  EXPECT_EQ(dec({0x00}, d), CobsStatus::ZeroInFrame);
}

TEST(Cobs, DecoderOverflowIsAStatus) {
  const Bytes e = enc(Bytes(50, 0x07));
  std::array<std::uint8_t, 20> out{};
  std::size_t n = 99;
  EXPECT_EQ(cobs_decode(e.data(), e.size(), out.data(), out.size(), n), CobsStatus::Overflow);
  EXPECT_EQ(n, 0u);
}

TEST(CobsAccumulator, FrameEndsAtZero) {
  CobsAccumulator<16> acc;
  EXPECT_EQ(acc.push(0x03), CobsAccumulator<16>::Event::None);
  EXPECT_EQ(acc.push(0x11), CobsAccumulator<16>::Event::None);
  EXPECT_EQ(acc.push(0x22), CobsAccumulator<16>::Event::None);
  ASSERT_EQ(acc.push(0x00), CobsAccumulator<16>::Event::Frame);
  EXPECT_EQ(acc.size(), 3u);
  EXPECT_EQ(acc.frame()[1], 0x11);
}

TEST(CobsAccumulator, EmptyFrame) {
  CobsAccumulator<16> acc;
  EXPECT_EQ(acc.push(0x00), CobsAccumulator<16>::Event::EmptyFrame);
}

TEST(CobsAccumulator, RunawayReportedOnceThenResyncAtZero) {
  CobsAccumulator<8> acc;
  int runaways = 0;
  for (int i = 0; i < 100; ++i) {
    if (acc.push(0x42) == CobsAccumulator<8>::Event::Runaway) ++runaways;
  }
  EXPECT_EQ(runaways, 1);
  EXPECT_TRUE(acc.discarding());
  EXPECT_EQ(acc.push(0x00), CobsAccumulator<8>::Event::None);  // ends the discarded run
  EXPECT_FALSE(acc.discarding());
  acc.push(0x02);
  acc.push(0x09);
  EXPECT_EQ(acc.push(0x00), CobsAccumulator<8>::Event::Frame);
  EXPECT_EQ(acc.size(), 2u);
}

TEST(CobsAccumulator, ExactlyCapacityIsAccepted) {
  CobsAccumulator<8> acc;
  for (int i = 0; i < 8; ++i) ASSERT_EQ(acc.push(0x01), CobsAccumulator<8>::Event::None);
  EXPECT_EQ(acc.push(0x00), CobsAccumulator<8>::Event::Frame);
  EXPECT_EQ(acc.size(), 8u);
}

// push_bytes (runs between zeros, memchr and memcpy) against push byte by
// byte: the same events after the same bytes, the same frames, the same
// state, on random streams with short and over-long frames cut into random
// reads (capacity 8, so runaways and frames of exactly the capacity occur).
TEST(CobsAccumulator, PushBytesMatchesPushByteByByte) {
  using Acc = CobsAccumulator<8>;
  std::mt19937 rng(11);
  int events[4] = {0, 0, 0, 0};
  for (int trial = 0; trial < 300; ++trial) {
    Bytes stream(1 + rng() % 200);
    for (auto& b : stream) b = (rng() % 6 == 0) ? 0 : static_cast<std::uint8_t>(1 + rng() % 255);
    Acc bytewise, bulk;
    std::size_t pos = 0;
    while (pos < stream.size()) {
      const std::size_t n = std::min<std::size_t>(1 + rng() % 24, stream.size() - pos);
      Acc::Event ev;
      const std::size_t used = bulk.push_bytes(stream.data() + pos, n, ev);
      ASSERT_GE(used, 1u);
      ASSERT_LE(used, n);
      // The reference: byte by byte until the first event or the end of the read.
      Acc::Event ref = Acc::Event::None;
      std::size_t k = 0;
      while (k < n && ref == Acc::Event::None) ref = bytewise.push(stream[pos + k++]);
      ASSERT_EQ(ev, ref) << "trial " << trial << " at byte " << pos;
      ASSERT_EQ(used, k) << "trial " << trial << " at byte " << pos;
      ++events[static_cast<int>(ev)];
      if (ev == Acc::Event::Frame) {
        ASSERT_EQ(bulk.size(), bytewise.size());
        ASSERT_TRUE(std::equal(bulk.frame(), bulk.frame() + bulk.size(), bytewise.frame()));
      }
      ASSERT_EQ(bulk.pending(), bytewise.pending());
      ASSERT_EQ(bulk.discarding(), bytewise.discarding());
      pos += used;
    }
  }
  // Every kind of event was exercised.
  for (int e = 0; e < 4; ++e) EXPECT_GT(events[e], 10) << "event " << e;
}
