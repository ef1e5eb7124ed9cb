// CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740): poly 0x1021, init 0xFFFF, no
// reflection, no final XOR; check value 0x29B1 over "123456789". Used as the
// last two bytes (big-endian) of every packet on the serial link
// (docs/LINK.md). Slicing-by-8 (eight 256-entry tables, 4 KB, computed at
// compile time): eight independent lookups per 8 bytes instead of a chain of
// eight dependent ones, so a range-image packet is checked about five times
// faster than byte at a time (docs/PERFORMANCE.md, serial link).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace fsw {

namespace crc16_detail {
using Table = std::array<std::uint16_t, 256>;

// kSlices[0][b]: the CRC register after byte b enters an all-zero register
// (the classic table); kSlices[k][b]: the same after k further zero bytes.
constexpr std::array<Table, 8> make_slices() {
  std::array<Table, 8> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint16_t c = static_cast<std::uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b) {
      c = static_cast<std::uint16_t>((c & 0x8000u) ? ((c << 1) ^ 0x1021u) : (c << 1));
    }
    t[0][i] = c;
  }
  for (std::size_t k = 1; k < 8; ++k) {
    for (std::size_t i = 0; i < 256; ++i) {
      const std::uint16_t c = t[k - 1][i];
      t[k][i] = static_cast<std::uint16_t>((c << 8) ^ t[0][c >> 8]);
    }
  }
  return t;
}
inline constexpr std::array<Table, 8> kSlices = make_slices();
}  // namespace crc16_detail

constexpr std::uint16_t kCrc16Init = 0xFFFF;
constexpr std::uint16_t kCrc16Check = 0x29B1;  // over the ASCII bytes "123456789"

// Continue a CRC over n more bytes, one byte at a time (the reference the
// sliced form is checked against, and its tail).
constexpr std::uint16_t crc16_update_bytewise(std::uint16_t crc, const std::uint8_t* data, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    crc = static_cast<std::uint16_t>((crc << 8) ^ crc16_detail::kSlices[0][((crc >> 8) ^ data[i]) & 0xFFu]);
  }
  return crc;
}

// Continue a CRC over n more bytes (start from kCrc16Init). Each block of 8:
// the register's two bytes fold into the first two data bytes, and byte j of
// the block reaches the end through 7 - j more bytes, i.e. table 7 - j.
constexpr std::uint16_t crc16_update(std::uint16_t crc, const std::uint8_t* data, std::size_t n) {
  const auto& T = crc16_detail::kSlices;
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const std::uint8_t* d = data + i;
    crc = static_cast<std::uint16_t>(T[7][(crc >> 8) ^ d[0]] ^ T[6][(crc & 0xFFu) ^ d[1]] ^ T[5][d[2]] ^ T[4][d[3]] ^
                                     T[3][d[4]] ^ T[2][d[5]] ^ T[1][d[6]] ^ T[0][d[7]]);
  }
  return crc16_update_bytewise(crc, data + i, n - i);
}

constexpr std::uint16_t crc16_ccitt_false(const std::uint8_t* data, std::size_t n) {
  return crc16_update(kCrc16Init, data, n);
}

static_assert(crc16_detail::kSlices[0][1] == 0x1021, "CRC table generator");

}  // namespace fsw
