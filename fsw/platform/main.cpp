// fsw_node: the flight executable. Talks to the world only through a serial
// port: bytes in -> FlightApp -> telemetry frames out. Runs until SIGINT or
// SIGTERM, or until the other end of the port goes away.
//
//   fsw_node --device /dev/pts/N [--baud 115200] [--quiet]
#include <signal.h>
#include <time.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "fsw/flight_app.hpp"
#include "serial_port.hpp"

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

double now_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

int usage(const char* argv0) {
  std::fprintf(stderr, "usage: %s --device PATH [--baud N] [--quiet]\n", argv0);
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
      baud = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--quiet")) {
      quiet = true;
    } else {
      return usage(argv[0]);
    }
  }
  if (device == nullptr) return usage(argv[0]);

  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  fsw::platform::SerialPort port;
  if (!port.open(device, baud)) {
    std::fprintf(stderr, "fsw_node: cannot open %s at %d baud: %s\n", device, baud, port.error());
    return 1;
  }
  // The application is large (history, buffers): one allocation at start-up,
  // none after.
  auto app = std::make_unique<fsw::FlightApp<double>>();
  std::array<std::uint8_t, 4096> rx{};
  std::array<std::uint8_t, 4096> tx{};
  int exit_code = 0;
  if (!quiet) std::fprintf(stderr, "fsw_node: running on %s at %d baud\n", device, baud);
  while (!g_stop) {
    const long n = port.read_some(rx.data(), rx.size(), 100);
    if (n < 0) break;  // the other end closed the port
    if (n == 0) continue;
    const double t0 = now_s();
    app->on_bytes(rx.data(), static_cast<std::size_t>(n));
    app->note_step_cpu(now_s() - t0);
    while (app->tx_pending() > 0) {
      const std::size_t k = app->take_tx(tx.data(), tx.size());
      if (!port.write_all(tx.data(), k, 1000)) {
        if (!g_stop) std::fprintf(stderr, "fsw_node: write failed\n");
        g_stop = 1;
        exit_code = 1;
        break;
      }
    }
  }
  const auto& c = app->counters();
  const auto& l = app->link();
  const auto& m = app->modal().counters();
  if (!quiet) {
    std::fprintf(stderr,
                 "fsw_node: stopped; frames %u, packets accepted %u, rejected %u, imu steps %u, "
                 "pose updates %u (fused %u, deferred %u), learner samples %u, range images %u (fused %u, "
                 "frequency acquisitions %u), telemetry packets %u (dropped %u)\n",
                 l.frames_total, l.packets_accepted, l.rejected_total(), c.imu_steps, c.pose_updates,
                 c.pose_fused, c.poses_deferred, c.learner_samples, m.images, m.images_fused, m.acquisitions,
                 c.tx_packets, c.tx_dropped);
  }
  return exit_code;
}
