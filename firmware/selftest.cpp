// The firmware self-test driver (selftest.hpp). Target-independent: no heap,
// no stdio; the flight objects live in one static arena, the application
// first and then the components, so the image needs RAM for the larger of
// the two only.
#include "selftest.hpp"

#include <new>

#include "fsw/app/flight_app.hpp"
#include "fsw/app/range_segment.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "fsw/modal/modal_tracker.hpp"
#include "fsw/nav/nav_ukf.hpp"
#include "fsw/thrusters/blr.hpp"

namespace fwtest {
namespace {

using S = float;
using App = fsw::FlightApp<S>;
using Nav = App::Nav;
using Learner = fsw::ThrusterBlr<S, 30>;
using Modal = App::Modal;

// The components measured one call at a time.
struct Components {
  fsw::Deframer deframer{fsw::Direction::ToFlight};
  fsw::Framer framer{fsw::Direction::FromFlight};
  Nav nav{fsw::NavConfig<S>()};
  Learner learner;
  Modal modal;
};

constexpr std::size_t kArenaSize = sizeof(App) > sizeof(Components) ? sizeof(App) : sizeof(Components);
constexpr std::size_t kArenaAlign = alignof(App) > alignof(Components) ? alignof(App) : alignof(Components);
alignas(kArenaAlign) unsigned char g_arena[kArenaSize];

class Lines {
 public:
  explicit Lines(Output& out) : out_(out) {}
  ~Lines() { flush(); }
  Lines& str(const char* s) {
    while (*s) put(*s++);
    return *this;
  }
  Lines& num(long long v) {
    char tmp[24];
    int k = 0;
    unsigned long long u = v < 0 ? 0ull - static_cast<unsigned long long>(v) : static_cast<unsigned long long>(v);
    do {
      tmp[k++] = static_cast<char>('0' + u % 10);
      u /= 10;
    } while (u != 0 && k < 24);
    if (v < 0) put('-');
    while (k > 0) put(tmp[--k]);
    return *this;
  }
  Lines& hex(const std::uint8_t* p, std::size_t n) {
    static const char kDigits[] = "0123456789abcdef";
    for (std::size_t i = 0; i < n; ++i) {
      put(kDigits[p[i] >> 4]);
      put(kDigits[p[i] & 0xF]);
    }
    return *this;
  }
  Lines& sp() { return put(' '); }
  Lines& end() {
    put('\n');
    return *this;
  }
  void flush() {
    if (len_ > 0) out_.write(buf_, len_);
    len_ = 0;
  }

 private:
  Lines& put(char c) {
    if (len_ == sizeof(buf_)) flush();
    buf_[len_++] = c;
    return *this;
  }
  Output& out_;
  char buf_[1024];
  std::size_t len_ = 0;
};

class Meter {
 public:
  explicit Meter(Counter c) : counter_(c) {
    if (counter_ == nullptr) return;
    // The counter's own cost (two reads), taken off every measurement.
    std::uint32_t best = UINT32_MAX;
    for (int i = 0; i < 8; ++i) {
      const std::uint32_t a = counter_();
      const std::uint32_t b = counter_();
      if (b - a < best) best = b - a;
    }
    overhead_ = best;
  }
  void start() {
    if (counter_ != nullptr) t0_ = counter_();
  }
  long long stop() const {
    if (counter_ == nullptr) return -1;
    const std::uint32_t t1 = counter_();
    return static_cast<long long>(t1 - t0_) - static_cast<long long>(overhead_);
  }

 private:
  Counter counter_;
  std::uint32_t overhead_ = 0;
  std::uint32_t t0_ = 0;
};

// The next frame of the input: [p, end) up to and including its 0x00.
std::size_t next_frame(const std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (p[i] == 0) return i + 1;
  return n;
}

// The APID of a frame (COBS-decoded header), or -1.
int frame_apid(const std::uint8_t* f, std::size_t n) {
  std::uint8_t dec[fsw::kPrimaryHeaderSize + 8];
  if (n < 2) return -1;
  // COBS: the first code byte says how many data bytes follow before a zero.
  std::size_t k = 0;
  std::size_t i = 0;
  while (k < sizeof(dec) && i < n - 1) {
    const std::uint8_t code = f[i++];
    if (code == 0) return -1;
    for (std::uint8_t j = 1; j < code && k < sizeof(dec) && i < n - 1; ++j) dec[k++] = f[i++];
    if (code < 0xFF && k < sizeof(dec)) dec[k++] = 0;
  }
  if (k < fsw::kPrimaryHeaderSize) return -1;
  return static_cast<int>(fsw::unpack_primary_header(dec).apid);
}

int run_app(const std::uint8_t* input, std::size_t n, Lines& out, Meter& meter) {
  App* app = new (g_arena) App(fsw::NavConfig<S>());
  static std::uint8_t tx[App::kTxCapacity];
  std::size_t off = 0;
  long long index = 0;
  while (off < n) {
    const std::size_t k = next_frame(input + off, n - off);
    meter.start();
    app->on_bytes(input + off, k);
    const long long used = meter.stop();
    out.str("F ").num(index).sp().num(frame_apid(input + off, k)).sp().num(used).end();
    const std::size_t m = app->take_tx(tx, sizeof(tx));
    if (m > 0) out.str("T ").hex(tx, m).end();
    off += k;
    ++index;
  }
  const App::Counters& c = app->counters();
  const auto& mc = app->modal().counters();
  out.str("A imu_steps ").num(c.imu_steps).end();
  out.str("A pose_fused ").num(c.pose_fused).end();
  out.str("A learner_samples ").num(c.learner_samples).end();
  out.str("A resets ").num(c.resets).end();
  out.str("A tx_dropped ").num(c.tx_dropped).end();
  out.str("A images_fused ").num(mc.images_fused).end();
  out.str("A acquisitions ").num(mc.acquisitions).end();
  out.str("A plans_loaded ").num(c.plans_loaded).end();
  out.str("A plan_commands_refused ").num(c.plan_commands_refused).end();
  out.str("A plan_valve_commands ").num(c.plan_valve_commands).end();
  out.str("A plans_finished ").num(c.plans_finished).end();
  out.str("A plan_aborts ").num(c.plan_aborts).end();
  out.str("A packets_accepted ").num(app->link().packets_accepted).end();
  out.str("A rejected_total ").num(app->link().rejected_total()).end();
  const int status = (c.tx_dropped == 0 && app->link().rejected_total() == 0) ? 0 : 1;
  app->~App();
  return status;
}

int run_components(const std::uint8_t* input, std::size_t n, Lines& out, Meter& meter) {
  Components* c = new (g_arena) Components();
  int status = 0;
  std::size_t off = 0;
  while (off < n) {
    const std::size_t k = next_frame(input + off, n - off);
    fsw::DeframeResult res;
    meter.start();
    c->deframer.feed(input + off, k, res);
    long long used = meter.stop();
    off += k;
    if (res.kind != fsw::DeframeResult::Kind::Packet) {
      status = 1;
      continue;
    }
    const fsw::PacketView& p = res.packet;
    out.str("C deframe ").num(used).end();
    switch (static_cast<fsw::Apid>(p.header.apid)) {
      case fsw::Apid::CmdReset: {
        fsw::CmdResetMsg<S> m;
        fsw::decode(p.payload, p.t_s, m);
        if (!(m.target_mask & 0x1u)) break;
        Nav::State x0;
        x0.r_hill_m = m.r_hill_m;
        x0.v_hill_mps = m.v_hill_mps;
        x0.q_hb = m.q_hb;
        Nav::Cov P0 = Nav::Cov::Zero();
        P0.diagonal().segment<3>(0).setConstant(m.pos_sigma_m * m.pos_sigma_m);
        P0.diagonal().segment<3>(3).setConstant(m.vel_sigma_mps * m.vel_sigma_mps);
        P0.diagonal().segment<3>(6).setConstant(m.att_sigma_rad * m.att_sigma_rad);
        c->nav.init(p.t_s, x0, P0);
        break;
      }
      case fsw::Apid::ImuSample: {
        fsw::ImuSampleMsg<S> m;
        fsw::decode(p.payload, p.t_s, m);
        meter.start();
        const Nav::Record rec = c->nav.predict(p.t_s, m.accel_b_mps2, m.omega_bi_b_rps);
        used = meter.stop();
        out.str("C nav_predict ").num(used).end();
        if (rec.status != fsw::StepStatus::Ok) status = 1;
        // One telemetry packet framed, as the app answers every step.
        fsw::TmEstimateMsg<S> est;
        est.r_hill_m = c->nav.state().r_hill_m;
        est.v_hill_mps = c->nav.state().v_hill_mps;
        est.q_hb = c->nav.state().q_hb;
        std::uint8_t frame[fsw::kMaxFrameBytes];
        meter.start();
        const std::size_t f = c->framer.frame_message(fsw::Apid::TmEstimate, est, p.t_s, frame, sizeof(frame));
        used = meter.stop();
        out.str("C frame_tm_estimate ").num(used).end();
        if (f == 0) status = 1;
        break;
      }
      case fsw::Apid::LedPose: {
        fsw::LedPoseMsg<S> m;
        fsw::decode(p.payload, p.t_s, m);
        Nav::MeasCov R = Nav::MeasCov::Zero();
        R.diagonal().head<3>().setConstant(m.r_sigma_m * m.r_sigma_m);
        R.diagonal().tail<3>().setConstant(m.att_sigma_rad * m.att_sigma_rad);
        meter.start();
        const Nav::Record rec = c->nav.update_pose(p.t_s, m.r_hill_m, m.q_hb, R);
        used = meter.stop();
        out.str(rec.fused ? "C nav_update " : "C nav_update_not_fused ").num(used).end();
        break;
      }
      case fsw::Apid::RangeImageSegment: {
        fsw::RangeImageSegmentMsg<S> m;
        fsw::decode(p.payload, p.t_s, p.header.seq_flags, m);
        fsw::ModalSegmentPoints<S> points;
        const fsw::ModalSegment<S> segment = fsw::modal_segment_of(m, points);
        Modal::Report rep;
        meter.start();
        const bool other = c->modal.close_other(m.image_id, rep);
        const bool closed = c->modal.add(segment, p.t_s, rep);
        used = meter.stop();
        if (other) status = 1;  // the recording loses no segment
        out.str(!closed        ? "C modal_segment "
                : rep.acquired ? "C modal_image_acquisition "
                               : "C modal_image ")
            .num(used)
            .end();
        if (closed && !rep.step.fused) status = 1;
        break;
      }
      default: break;
    }
  }
  // The thruster learner on its own: a window of 30 filled and run over by
  // adds (each past the 30th evicts the oldest), then emptied by removals.
  for (int i = 0; i < 75; ++i) {
    const std::uint8_t mask = static_cast<std::uint8_t>(1u << (i % 8) | 1u << ((3 * i + 1) % 8));
    const Learner::VecX x = fsw::ValveFeatures<S>::from_mask(mask);
    Learner::VecY y;
    for (int j = 0; j < 6; ++j) y(j) = S(0.001) * S((i * 7 + j * 3) % 11 - 5) + S(0.01) * x(j);
    meter.start();
    const Learner::AddRecord a = c->learner.add(x, y);
    const long long used = meter.stop();
    out.str(a.evicted ? "C learner_add_evict " : "C learner_add ").num(used).end();
    if (a.status != fsw::StepStatus::Ok) status = 1;
    if (i % 5 == 4) {
      meter.start();
      const Learner::Prediction pr = c->learner.predict(x);
      const long long pused = meter.stop();
      out.str("C learner_predict ").num(pused).end();
      if (pr.status != fsw::StepStatus::Ok) status = 1;
    }
  }
  for (int i = 0; i < 30; ++i) {
    meter.start();
    const fsw::StepStatus s = c->learner.remove_oldest();
    const long long used = meter.stop();
    out.str("C learner_remove ").num(used).end();
    if (s != fsw::StepStatus::Ok) status = 1;
  }
  c->~Components();
  return status;
}

}  // namespace

int run(const std::uint8_t* input, std::size_t n, Output& output, Counter counter) {
  Lines out(output);
  Meter meter(counter);
  out.str("# proxops firmware self-test: ").num(static_cast<long long>(n)).str(" input bytes").end();
  const int app_status = run_app(input, n, out, meter);
  const int comp_status = run_components(input, n, out, meter);
  const int status = app_status | (comp_status << 1);
  out.str("E ").num(status).end();
  out.flush();
  return status;
}

}  // namespace fwtest
