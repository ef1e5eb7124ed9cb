// fsw_node: the flight executable. Talks to the world only through a serial
// port: bytes in -> FlightApp -> telemetry frames out. Runs until SIGINT or
// SIGTERM, or until the other end of the port goes away; never because the
// other end stops reading (telemetry is then dropped and counted).
//
//   fsw_node --device /dev/pts/N [--baud 115200] [--quiet]
#include <signal.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "fsw/app/flight_app.hpp"
#include "serial_port.hpp"

namespace {

// Set by the signal handler, read by the loop: a signal handler can only
// reach a global (POSIX), hence the one mutable global of the executable.
volatile sig_atomic_t g_stop = 0;  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables)
void on_signal(int) { g_stop = 1; }

double now_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

int usage(const char* argv0) {
  (void)std::fprintf(stderr, "usage: %s --device PATH [--baud N] [--quiet]\n", argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  const char* device = nullptr;
  int baud = 115200;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--device") && i + 1 < argc) {
      device = argv[++i];
    } else if (!std::strcmp(argv[i], "--baud") && i + 1 < argc) {
      // A rate that is not a whole number is refused (std::atoi would read 0).
      char* end = nullptr;
      const long v = std::strtol(argv[++i], &end, 10);
      if (end == argv[i] || *end != '\0' || v <= 0 || v > 4000000) return usage(argv[0]);
      baud = static_cast<int>(v);
    } else if (!std::strcmp(argv[i], "--quiet")) {
      quiet = true;
    } else {
      return usage(argv[0]);
    }
  }
  if (device == nullptr) return usage(argv[0]);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  (void)sigaction(SIGINT, &sa, nullptr);
  (void)sigaction(SIGTERM, &sa, nullptr);
  (void)signal(SIGPIPE, SIG_IGN);

  fsw::platform::SerialPort port;
  if (!port.open(device, baud)) {
    (void)std::fprintf(stderr, "fsw_node: cannot open %s at %d baud: %s\n", device, baud, port.error());
    return 1;
  }
  // The application is large (history, buffers): one allocation at start-up,
  // none after.
  auto app = std::make_unique<fsw::FlightApp<double>>();
  std::array<std::uint8_t, 4096> rx{};
  std::array<std::uint8_t, 4096> tx{};
  if (!quiet) (void)std::fprintf(stderr, "fsw_node: running on %s at %d baud\n", device, baud);

  // Telemetry goes out as fast as the port takes it and never holds up the
  // loop for long: bytes the port does not take now wait (in tx, then in
  // the app's transmit buffer); once that buffer is full, new telemetry is
  // dropped and counted (tm_housekeeping tx_dropped). A ground station that
  // stops reading costs telemetry, never the flight software. Received
  // bytes are handled kFeedChunk at a time; before each chunk, while less
  // than kChunkReserve of the transmit buffer is free (room for the answers
  // to a chunk of the smallest packets), the port gets up to kDrainWaitMs
  // to take the backlog, so a burst of commands is answered in full when
  // the ground reads, and costs at most kDrainWaitMs per chunk when not.
  constexpr std::size_t kFeedChunk = 512;
  constexpr std::size_t kChunkReserve = 8192;
  constexpr int kDrainWaitMs = 20;
  using App = fsw::FlightApp<double>;
  std::size_t tx_off = 0;
  std::size_t tx_len = 0;
  bool write_error_reported = false;
  auto flush = [&]() {
    for (;;) {
      if (tx_off == tx_len) {
        if (app->tx_pending() == 0) return;
        tx_len = app->take_tx(tx.data(), tx.size());
        tx_off = 0;
      }
      const long w = port.write_some(tx.data() + tx_off, tx_len - tx_off);
      if (w <= 0) {
        if (w < 0 && !write_error_reported && !quiet) {
          (void)std::fprintf(stderr, "fsw_node: write error (%s); telemetry is held, then dropped and counted\n",
                             port.error());
          write_error_reported = true;
        }
        return;  // the port is full (or failing): try again next turn
      }
      tx_off += static_cast<std::size_t>(w);
    }
  };
  while (!g_stop) {
    const bool backlog = tx_off < tx_len || app->tx_pending() > 0;
    const long n = port.read_some(rx.data(), rx.size(), backlog ? 5 : 100);
    if (n < 0) break;  // the other end closed the port
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); i += kFeedChunk) {
      const std::size_t k = std::min(kFeedChunk, static_cast<std::size_t>(n) - i);
      const double give_up = now_s() + 1e-3 * kDrainWaitMs;
      while (app->tx_pending() + kChunkReserve > App::kTxCapacity && !g_stop) {
        const int left_ms = static_cast<int>(1e3 * (give_up - now_s()));
        if (left_ms <= 0 || !port.wait_writable(left_ms)) break;
        flush();
      }
      const double t0 = now_s();
      app->on_bytes(rx.data() + i, k);
      app->note_step_cpu(now_s() - t0);
      flush();
    }
    flush();
  }
  const auto& c = app->counters();
  const auto& l = app->link();
  const auto& m = app->modal().counters();
  if (!quiet) {
    (void)std::fprintf(stderr,
                       "fsw_node: stopped; frames %u, packets accepted %u, rejected %u, imu steps %u, "
                       "pose updates %u (fused %u, deferred %u), learner samples %u, range images %u (fused %u, "
                       "frequency acquisitions %u), resets refused %u, plans loaded %u (plan commands refused %u, "
                       "plan valve commands %u), telemetry packets %u (dropped %u, non-finite values clamped %u)\n",
                       l.frames_total, l.packets_accepted, l.rejected_total(), c.imu_steps, c.pose_updates,
                       c.pose_fused, c.poses_deferred, c.learner_samples, m.images, m.images_fused, m.acquisitions,
                       c.resets_refused, c.plans_loaded, c.plan_commands_refused, c.plan_valve_commands, c.tx_packets,
                       c.tx_dropped, c.tm_values_clamped);
  }
  return 0;
}
