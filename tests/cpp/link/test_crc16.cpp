// CRC-16/CCITT-FALSE: check value, against a bitwise reference, and its
// error-detection properties that the link relies on.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "fsw/link/crc16.hpp"

using namespace fsw;

namespace {
// Bit-at-a-time reference, independent of the table.
std::uint16_t crc_bitwise(const std::uint8_t* d, std::size_t n) {
  std::uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= static_cast<std::uint16_t>(d[i] << 8);
    for (int b = 0; b < 8; ++b)
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021) : static_cast<std::uint16_t>(crc << 1);
  }
  return crc;
}
}  // namespace

TEST(Crc16, CheckValue123456789Is29B1) {
  const std::uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(crc16_ccitt_false(s, 9), 0x29B1);
  EXPECT_EQ(kCrc16Check, 0x29B1);
}

TEST(Crc16, CheckValueAtCompileTime) {
  constexpr std::uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  static_assert(crc16_ccitt_false(s, 9) == 0x29B1, "CRC-16/CCITT-FALSE check value");
  SUCCEED();
}

TEST(Crc16, EmptyInputIsInit) { EXPECT_EQ(crc16_ccitt_false(nullptr, 0), 0xFFFF); }

TEST(Crc16, MatchesBitwiseReferenceOnRandomData) {
  std::mt19937 rng(1234);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::uint8_t> d(rng() % 900);
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    EXPECT_EQ(crc16_ccitt_false(d.data(), d.size()), crc_bitwise(d.data(), d.size()));
  }
}

// Slicing-by-8 against byte at a time: every length through three blocks and
// every start offset (the 8-byte blocks fall differently), from any register.
TEST(Crc16, SlicedEqualsBytewiseAtEveryLengthAndOffset) {
  std::mt19937 rng(5);
  std::vector<std::uint8_t> d(40);
  for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  for (std::size_t off = 0; off < 8; ++off) {
    for (std::size_t n = 0; off + n <= d.size(); ++n) {
      const std::uint16_t start = static_cast<std::uint16_t>(rng());
      ASSERT_EQ(crc16_update(start, d.data() + off, n), crc16_update_bytewise(start, d.data() + off, n))
          << "offset " << off << " length " << n;
      ASSERT_EQ(crc16_ccitt_false(d.data() + off, n), crc_bitwise(d.data() + off, n));
    }
  }
}

TEST(Crc16, IncrementalEqualsOneShot) {
  std::mt19937 rng(7);
  std::vector<std::uint8_t> d(500);
  for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  const std::uint16_t a = crc16_update(crc16_update(kCrc16Init, d.data(), 123), d.data() + 123, 377);
  EXPECT_EQ(a, crc16_ccitt_false(d.data(), d.size()));
}

TEST(Crc16, DetectsEverySingleAndDoubleBitErrorInALinkSizedPacket) {
  // 796 bytes = the largest packet with its CRC (6368 bits < 32767: Hamming distance 4).
  std::mt19937 rng(99);
  std::vector<std::uint8_t> d(794);
  for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  const std::uint16_t good = crc16_ccitt_false(d.data(), d.size());
  for (std::size_t bit = 0; bit < d.size() * 8; ++bit) {
    d[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    ASSERT_NE(crc16_ccitt_false(d.data(), d.size()), good) << "bit " << bit;
    d[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
  }
  for (int trial = 0; trial < 2000; ++trial) {
    const std::size_t b1 = rng() % (d.size() * 8), b2 = rng() % (d.size() * 8);
    if (b1 == b2) continue;
    d[b1 / 8] ^= static_cast<std::uint8_t>(1u << (b1 % 8));
    d[b2 / 8] ^= static_cast<std::uint8_t>(1u << (b2 % 8));
    ASSERT_NE(crc16_ccitt_false(d.data(), d.size()), good);
    d[b1 / 8] ^= static_cast<std::uint8_t>(1u << (b1 % 8));
    d[b2 / 8] ^= static_cast<std::uint8_t>(1u << (b2 % 8));
  }
}

TEST(Crc16, AppendingTheCrcBigEndianGivesZeroResidue) {
  // Property of a non-reflected CRC with no final XOR: CRC(data || crc_be) == 0.
  const std::uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9', 0x29, 0xB1};
  EXPECT_EQ(crc16_ccitt_false(s, sizeof s), 0x0000);
}
