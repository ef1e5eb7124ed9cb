// Deterministic, seeded mutation fuzzer for the deframer over the committed
// seed corpus (tests/fuzz/corpus/deframer). Mutations: bit flips, random
// bytes, inserted and deleted bytes, inserted 0x00, truncation, splices of two
// corpus entries, duplicated runs, and edits inside a decoded packet with
// the CRC recomputed (to reach the checks behind the CRC). Asserts: no crash, progress on every call
// (no hang), no allocation (mutator and deframer both run inside the guard),
// every delivered packet carries a correct CRC and satisfies the table, and
// every frame has exactly one outcome.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fsw/link/apid.hpp"
#include "fsw/link/cobs.hpp"
#include "fsw/link/crc16.hpp"
#include "fsw/link/deframer.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

namespace {

constexpr std::size_t kMaxInput = 8192;
constexpr std::size_t kMaxSeeds = 64;

struct Corpus {
  std::array<std::array<std::uint8_t, kMaxInput>, kMaxSeeds> data{};
  std::array<std::size_t, kMaxSeeds> len{};
  std::size_t count = 0;
};

// xorshift64*: allocation-free and identical on every platform.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    return s * 0x2545F4914F6CDD1DULL;
  }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(next() % n); }
};

void load(Corpus& c) {
  const std::filesystem::path dir = PROXOPS_DEFRAMER_CORPUS;
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    if (c.count == kMaxSeeds) break;
    std::ifstream in(f, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t n = std::min(bytes.size(), kMaxInput);
    for (std::size_t i = 0; i < n; ++i) c.data[c.count][i] = static_cast<std::uint8_t>(bytes[i]);
    c.len[c.count++] = n;
  }
}

// Structure-aware mutation: decode the first frame of a seed, change header
// or payload bytes, recompute the CRC (usually) and re-encode, so that the
// checks behind the CRC (header, length, APID, sequence, payload) are reached.
std::size_t mutate_inside(const Corpus& c, Rng& rng, std::uint8_t* buf) {
  static std::array<std::uint8_t, kMaxInput> pkt{};
  const std::size_t a = rng.below(c.count);
  std::size_t end = 0;
  while (end < c.len[a] && c.data[a][end] != 0) ++end;
  std::size_t n = 0;
  if (cobs_decode(c.data[a].data(), end, pkt.data(), pkt.size(), n) != CobsStatus::Ok || n < 3) return 0;
  std::size_t body = n - 2;
  const std::size_t edits = 1 + rng.below(3);
  for (std::size_t e = 0; e < edits; ++e) {
    switch (rng.below(4)) {
      case 0:  // any header byte (primary and time tag)
        pkt[rng.below(std::min<std::size_t>(body, kPacketHeaderSize))] = static_cast<std::uint8_t>(rng.next());
        break;
      case 1:  // one header bit
        pkt[rng.below(std::min<std::size_t>(body, kPacketHeaderSize))] ^= static_cast<std::uint8_t>(1u << rng.below(8));
        break;
      case 2:  // a payload byte (0xFF bytes make NaN and Inf likely)
        pkt[rng.below(body)] = rng.below(2) ? 0xFF : static_cast<std::uint8_t>(rng.next());
        break;
      default:  // shorten or lengthen the body
        body = rng.below(2) ? rng.below(body + 1) : std::min<std::size_t>(body + rng.below(16), kMaxInput / 2);
        break;
    }
  }
  if (rng.below(8) != 0) {
    const std::uint16_t crc = crc16_ccitt_false(pkt.data(), body);
    pkt[body] = static_cast<std::uint8_t>(crc >> 8);
    pkt[body + 1] = static_cast<std::uint8_t>(crc);
  }
  const std::size_t k = cobs_encode(pkt.data(), body + 2, buf, kMaxInput - 1);
  if (k == 0) return 0;
  buf[k] = 0;
  return k + 1;
}

std::size_t mutate(const Corpus& c, Rng& rng, std::uint8_t* buf) {
  if (rng.below(2) == 0) return mutate_inside(c, rng, buf);
  const std::size_t a = rng.below(c.count);
  std::size_t n = c.len[a];
  for (std::size_t i = 0; i < n; ++i) buf[i] = c.data[a][i];
  const std::size_t rounds = 1 + rng.below(8);
  for (std::size_t r = 0; r < rounds; ++r) {
    switch (rng.below(8)) {
      case 0:  // flip one bit
        if (n) buf[rng.below(n)] ^= static_cast<std::uint8_t>(1u << rng.below(8));
        break;
      case 1:  // random byte
        if (n) buf[rng.below(n)] = static_cast<std::uint8_t>(rng.next());
        break;
      case 2:  // insert a byte (often 0x00)
        if (n < kMaxInput) {
          const std::size_t at = rng.below(n + 1);
          for (std::size_t i = n; i > at; --i) buf[i] = buf[i - 1];
          buf[at] = rng.below(3) == 0 ? 0 : static_cast<std::uint8_t>(rng.next());
          ++n;
        }
        break;
      case 3:  // delete a byte
        if (n) {
          const std::size_t at = rng.below(n);
          for (std::size_t i = at; i + 1 < n; ++i) buf[i] = buf[i + 1];
          --n;
        }
        break;
      case 4:  // truncate
        n = rng.below(n + 1);
        break;
      case 5: {  // splice the tail of another seed
        const std::size_t b = rng.below(c.count);
        const std::size_t from = rng.below(c.len[b] + 1);
        const std::size_t at = rng.below(n + 1);
        std::size_t k = 0;
        for (std::size_t i = from; i < c.len[b] && at + k < kMaxInput; ++i, ++k) buf[at + k] = c.data[b][i];
        n = at + k;
        break;
      }
      case 6: {  // duplicate a run
        if (!n) break;
        const std::size_t from = rng.below(n);
        const std::size_t len = std::min<std::size_t>(1 + rng.below(64), n - from);
        for (std::size_t i = 0; i < len && n < kMaxInput; ++i) buf[n++] = buf[from + i];
        break;
      }
      default:  // overwrite a 16-bit field with an interesting value
        if (n >= 2) {
          static constexpr std::uint16_t kVals[] = {0x0000, 0x0001, 0x00FF, 0x7FFF, 0xFFFF, 0x3FFF, 0xC000};
          const std::size_t at = rng.below(n - 1);
          const std::uint16_t v = kVals[rng.below(7)];
          buf[at] = static_cast<std::uint8_t>(v >> 8);
          buf[at + 1] = static_cast<std::uint8_t>(v);
        }
        break;
    }
  }
  return n;
}

bool packet_is_sound(const PacketView& p) {
  if (p.info == nullptr || p.payload_len != p.info->payload_len) return false;
  if (p.packet_len != kPacketHeaderSize + p.payload_len) return false;
  const std::uint16_t crc = static_cast<std::uint16_t>((p.packet[p.packet_len] << 8) | p.packet[p.packet_len + 1]);
  if (crc16_ccitt_false(p.packet, p.packet_len) != crc) return false;
  if (p.header.version != 0 || !p.header.sec_header || !std::isfinite(p.t_s)) return false;
  for (std::size_t i = 0; i < p.info->f64_count; ++i) {
    if (!std::isfinite(get_f64le(p.payload + p.info->f64_offset + 8 * i))) return false;
  }
  return true;
}

}  // namespace

TEST(FuzzDeframer, SeededMutationsNoCrashNoHangNoAllocationNoBadPacket) {
  static Corpus corpus;
  load(corpus);
  ASSERT_GE(corpus.count, 5u) << "seed corpus missing";
  static Deframer d(Direction::ToFlight);
  static std::array<std::uint8_t, kMaxInput> buf{};
  Rng rng{0x9E3779B97F4A7C15ULL};
  std::size_t delivered = 0, unsound = 0, stalls = 0;
  constexpr int kInputs = 200000;

  NoHeapGuard guard;
  for (int it = 0; it < kInputs; ++it) {
    const std::size_t n = mutate(corpus, rng, buf.data());
    std::size_t pos = 0;
    while (pos < n) {
      const std::size_t chunk = 1 + rng.below(n - pos);
      std::size_t left = chunk;
      while (left > 0) {
        DeframeResult r;
        const std::size_t used = d.feed(buf.data() + pos, left, r);
        if (used == 0) {
          ++stalls;
          left = 0;
          pos = n;
          break;
        }
        pos += used;
        left -= used;
        if (r.kind == DeframeResult::Kind::Packet) {
          ++delivered;
          if (!packet_is_sound(r.packet)) ++unsound;
        }
      }
    }
    // End every input with a delimiter so that the next starts in sync half of the time.
    if (rng.below(2) == 0) {
      const std::uint8_t z = 0;
      DeframeResult r;
      d.feed(&z, 1, r);
      if (r.kind == DeframeResult::Kind::Packet) {
        ++delivered;
        if (!packet_is_sound(r.packet)) ++unsound;
      }
    }
    if (rng.below(50) == 0) d.reset_history();
  }
  const long allocations = guard.allocations();

  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(stalls, 0u);
  EXPECT_EQ(unsound, 0u);
  EXPECT_GT(delivered, 1000u);  // the mutator keeps enough valid frames to reach the deep checks
  const LinkCounters& c = d.counters();
  EXPECT_EQ(static_cast<std::uint64_t>(c.packets_accepted) + c.rejected_total(), c.frames_total);
  // Every rejection reason has been reached.
  for (std::size_t i = 0; i < kRejectReasonCount; ++i) {
    const auto r = static_cast<RejectReason>(i);
    EXPECT_GT(c.rejected[static_cast<std::size_t>(r)], 0u) << to_string(r);
  }
}
