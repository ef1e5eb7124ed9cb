// Serial-link throughput: CRC, COBS, framing and deframing of the smallest
// (imu_sample, 48-byte payload) and largest (range_image_segment, 780) packets.
#include <benchmark/benchmark.h>

#include <array>
#include <cstdint>
#include <vector>

#include "fsw/link/cobs.hpp"
#include "fsw/link/crc16.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"

using namespace fsw;

namespace {
std::vector<std::uint8_t> payload_for(Apid apid) {
  const ApidInfo* info = apid_info(static_cast<std::uint16_t>(apid));
  std::vector<std::uint8_t> p(info->payload_len, 0);
  for (std::size_t i = 0; i < info->f64_count; ++i) put_f64le(p.data() + info->f64_offset + 8 * i, 0.1 * i);
  if (info->quat_offset >= 0) put_f64le(p.data() + info->quat_offset, 1.0);
  if (apid == Apid::RangeImageSegment) {
    put_u16le(p.data() + 4, 24);
    put_u16le(p.data() + 8, 24);
  }
  return p;
}
}  // namespace

static void BM_Crc16(benchmark::State& st) {
  std::vector<std::uint8_t> d(static_cast<std::size_t>(st.range(0)), 0xA5);
  for (auto _ : st) benchmark::DoNotOptimize(crc16_ccitt_false(d.data(), d.size()));
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_Crc16)->Arg(64)->Arg(794);

// The same CRC one byte at a time (the classic 256-entry table), side by side.
static void BM_Crc16Bytewise(benchmark::State& st) {
  std::vector<std::uint8_t> d(static_cast<std::size_t>(st.range(0)), 0xA5);
  for (auto _ : st) benchmark::DoNotOptimize(crc16_update_bytewise(kCrc16Init, d.data(), d.size()));
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_Crc16Bytewise)->Arg(64)->Arg(794);

static void BM_CobsEncode(benchmark::State& st) {
  std::vector<std::uint8_t> d(static_cast<std::size_t>(st.range(0)));
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = static_cast<std::uint8_t>(i % 7 == 0 ? 0 : i);
  std::vector<std::uint8_t> out(cobs_max_encoded_size(d.size()));
  for (auto _ : st) benchmark::DoNotOptimize(cobs_encode(d.data(), d.size(), out.data(), out.size()));
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations()) * st.range(0));
}
BENCHMARK(BM_CobsEncode)->Arg(64)->Arg(796);

static void BM_FrameEncode(benchmark::State& st) {
  const Apid apid = st.range(0) ? Apid::RangeImageSegment : Apid::ImuSample;
  const auto p = payload_for(apid);
  Framer fr(Direction::ToFlight);
  std::array<std::uint8_t, kMaxFrameBytes> out{};
  double t = 0.0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(fr.frame(apid, t, p.data(), p.size(), out.data(), out.size()));
    t += 0.1;
  }
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations() * p.size()));
  st.SetLabel(st.range(0) ? "range_image_segment" : "imu_sample");
}
BENCHMARK(BM_FrameEncode)->Arg(0)->Arg(1);

// Decoding a long stream of valid frames, fed in 64-byte reads like a serial port.
static void BM_FrameDecode(benchmark::State& st) {
  const Apid apid = st.range(0) ? Apid::RangeImageSegment : Apid::ImuSample;
  const auto p = payload_for(apid);
  Framer fr(Direction::ToFlight);
  std::vector<std::uint8_t> stream;
  constexpr int kFrames = 256;
  std::array<std::uint8_t, kMaxFrameBytes> out{};
  for (int k = 0; k < kFrames; ++k) {
    const std::size_t n = fr.frame(apid, 0.1 * k, p.data(), p.size(), out.data(), out.size());
    stream.insert(stream.end(), out.begin(), out.begin() + static_cast<long>(n));
  }
  std::size_t packets = 0;
  for (auto _ : st) {
    Deframer d(Direction::ToFlight);
    std::size_t pos = 0;
    while (pos < stream.size()) {
      DeframeResult r;
      const std::size_t chunk = std::min<std::size_t>(64, stream.size() - pos);
      std::size_t used = 0;
      while (used < chunk) {
        used += d.feed(stream.data() + pos + used, chunk - used, r);
        if (r.kind == DeframeResult::Kind::Packet) ++packets;
      }
      pos += chunk;
    }
    benchmark::DoNotOptimize(packets);
  }
  st.SetBytesProcessed(static_cast<std::int64_t>(st.iterations() * stream.size()));
  st.SetItemsProcessed(static_cast<std::int64_t>(st.iterations()) * kFrames);
  st.SetLabel(st.range(0) ? "range_image_segment" : "imu_sample");
}
BENCHMARK(BM_FrameDecode)->Arg(0)->Arg(1);
