// Coverage-guided fuzzer (libFuzzer) for the flight side of the serial link:
// arbitrary bytes, split into arbitrary chunks, go through FlightApp::on_bytes
// (deframer, dispatch, navigation filter, modal estimator on range-image
// segments, telemetry framing). Built with clang
// and -fsanitize=fuzzer,address,undefined (CMake target fuzz_flight_link).
//
// Fails (abort, reported by libFuzzer with the input saved) when:
//   - the app allocates while it processes bytes (malloc hook),
//   - a frame has no outcome or two (accepted + rejected != frames),
//   - the outcome depends on how the stream was split into reads,
//   - a telemetry frame the app sends is not accepted by a bench-direction
//     deframer, or the app's state stops being finite,
//   - ASan or UBSan report anything, or one input takes longer than -timeout.
#include <sanitizer/allocator_interface.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <new>

#include "fsw/app/flight_app.hpp"
#include "fsw/link/deframer.hpp"

namespace {

// Armed per thread: the hook runs in the allocating thread, and libFuzzer's
// own threads (the RSS monitor) may allocate while this one is armed.
thread_local bool g_armed = false;
long g_allocations = 0;

void on_malloc(const volatile void*, std::size_t) {
  if (g_armed) ++g_allocations;
}
void on_free(const volatile void*) {}

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "fuzz_flight_link: %s\n", what);
  std::abort();
}

using App = fsw::FlightApp<double>;

// Static storage: the app is rebuilt in place for every input, so each input
// starts from power-on state and a crash reproduces from its file alone.
alignas(App) unsigned char g_app_storage[2][sizeof(App)];
std::uint8_t g_tx[1 << 16];

// Feeds the stream in chunks of `chunk` bytes (0: all at once), checking every
// telemetry frame on the way. Returns the app, left in g_app_storage[slot].
App* run(const std::uint8_t* data, std::size_t size, std::size_t chunk, int slot) {
  App* app = new (g_app_storage[slot]) App();
  fsw::Deframer bench_side(fsw::Direction::FromFlight);
  std::size_t used = 0;
  while (used < size) {
    const std::size_t n = (chunk == 0 || size - used < chunk) ? size - used : chunk;
    g_armed = true;
    app->on_bytes(data + used, n);
    const std::size_t tx = app->take_tx(g_tx, sizeof(g_tx));
    g_armed = false;
    used += n;

    // Everything the flight side sends must be a valid frame.
    std::size_t off = 0;
    while (off < tx) {
      fsw::DeframeResult res;
      const std::size_t k = bench_side.feed(g_tx + off, tx - off, res);
      if (k == 0) fail("bench deframer made no progress on telemetry");
      off += k;
      if (res.kind == fsw::DeframeResult::Kind::Rejected && res.reason != fsw::RejectReason::TimeBackwards &&
          res.reason != fsw::RejectReason::DuplicateSequence && res.reason != fsw::RejectReason::StaleSequence) {
        // Time tags come from the fuzzed input (a reset may rewind them);
        // anything else means the flight side built a bad frame.
        std::fprintf(stderr, "telemetry rejected: %s\n", fsw::to_string(res.reason));
        fail("flight side sent a malformed frame");
      }
    }
  }
  if (g_allocations != 0) fail("heap allocation while processing link bytes");

  const fsw::LinkCounters& c = app->link();
  if (app->counters().resets == 0 &&
      static_cast<std::uint64_t>(c.packets_accepted) + c.rejected_total() != c.frames_total) {
    // (a reset with the link bit clears the counters mid-stream, hence the guard)
    fail("a frame without exactly one outcome");
  }
  if (app->nav().initialized()) {
    const auto& x = app->nav().state();
    if (!x.r_hill_m.allFinite() || !x.v_hill_mps.allFinite() || !x.q_hb.coeffs().allFinite())
      fail("navigation state is not finite");
    if (!app->nav().P().allFinite()) fail("covariance is not finite");
  }
  const auto& filt = app->modal().filter();
  if (filt.initialized()) {
    for (int i = 0; i < App::kModalModes; ++i)
      if (!filt.mode_state(i).allFinite() || !filt.mode_cov(i).allFinite()) fail("modal state is not finite");
  }
  return app;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The same stream must give the same outcome however the serial driver
  // splits it: once whole, once in small chunks whose size the input picks.
  const std::size_t chunk = 1 + (size == 0 ? 0 : data[size / 2] % 16);
  App* whole = run(data, size, 0, 0);
  App* split = run(data, size, chunk, 1);

  const fsw::LinkCounters& a = whole->link();
  const fsw::LinkCounters& b = split->link();
  if (a.frames_total != b.frames_total || a.packets_accepted != b.packets_accepted || a.rejected != b.rejected)
    fail("link counters depend on how the bytes were chunked");
  if (whole->nav().initialized() != split->nav().initialized()) fail("nav init depends on chunking");
  if (whole->nav().initialized()) {
    const auto& x = whole->nav().state();
    const auto& y = split->nav().state();
    if (x.r_hill_m != y.r_hill_m || x.v_hill_mps != y.v_hill_mps || x.q_hb.coeffs() != y.q_hb.coeffs())
      fail("navigation estimate depends on chunking");
  }
  const auto& ma = whole->modal().counters();
  const auto& mb = split->modal().counters();
  if (ma.segments != mb.segments || ma.images != mb.images || ma.images_fused != mb.images_fused ||
      ma.points_outside != mb.points_outside)
    fail("modal counters depend on chunking");
  if (whole->modal().filter().initialized()) {
    for (int i = 0; i < App::kModalModes; ++i)
      if (whole->modal().filter().mode_state(i) != split->modal().filter().mode_state(i))
        fail("modal estimate depends on chunking");
  }
  whole->~App();
  split->~App();
  return 0;
}
