// CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740): poly 0x1021, init 0xFFFF, no
// reflection, no final XOR; check value 0x29B1 over "123456789". Table-driven
// with a table computed at compile time. Used as the last two bytes
// (big-endian) of every packet on the serial link (docs/LINK.md).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace fsw {

namespace crc16_detail {
constexpr std::array<std::uint16_t, 256> make_table() {
  std::array<std::uint16_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint16_t c = static_cast<std::uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b) {
      c = static_cast<std::uint16_t>((c & 0x8000u) ? ((c << 1) ^ 0x1021u) : (c << 1));
    }
    t[i] = c;
  }
  return t;
}
inline constexpr std::array<std::uint16_t, 256> kTable = make_table();
}  // namespace crc16_detail

constexpr std::uint16_t kCrc16Init = 0xFFFF;
constexpr std::uint16_t kCrc16Check = 0x29B1;  // over the ASCII bytes "123456789"

// Continue a CRC over n more bytes (start from kCrc16Init).
constexpr std::uint16_t crc16_update(std::uint16_t crc, const std::uint8_t* data, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    crc = static_cast<std::uint16_t>((crc << 8) ^
                                     crc16_detail::kTable[((crc >> 8) ^ data[i]) & 0xFFu]);
  }
  return crc;
}

constexpr std::uint16_t crc16_ccitt_false(const std::uint8_t* data, std::size_t n) {
  return crc16_update(kCrc16Init, data, n);
}

static_assert(crc16_detail::kTable[1] == 0x1021, "CRC table generator");

}  // namespace fsw
