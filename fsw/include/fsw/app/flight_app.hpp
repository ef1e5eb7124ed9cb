// The flight application: bytes from the link in, telemetry frames out.
//
// One class used two ways: inside the flight executable behind a
// serial port (fsw/platform/), and in-process through the bindings. Both feed
// the same bytes to on_bytes() and read the same frames from take_tx(), so
// the two paths give identical estimates by construction.
//
// Dispatch by APID, in arrival order, each step at its packet's time tag:
//   cmd_reset (bit 0)   -> NavUkf rebuilt with the commanded settings, init,
//                          then estimate telemetry
//   cmd_reset (bit 1)   -> thruster learner emptied
//   cmd_reset (bit 2)   -> modal estimator rebuilt with the commanded plate
//                          model and priors (ModalTracker)
//   cmd_reset (bit 3)   -> link counters cleared
//   cmd_reset (any)     -> the link's time history cleared (a new time base);
//                          a reset whose bit 0 the filter would refuse is
//                          refused whole: nothing changes, it is counted
//                          (resets_refused) and answered with tm_innovation
//                          (step_kind reset, its status) and the old estimate
//   cmd_config          -> pose noise model (docs/LINK.md, parameter ids)
//   imu_sample          -> NavUkf::predict to the packet time
//   led_pose            -> NavUkf::update_pose at the capture time (may be late);
//                          or NavUkf::reacquire from it when the filter is lost
//                          (see "Re-acquisition" below)
//   thruster_valves     -> held until the IMU sample that ends its interval:
//                          that sample (accelerometer x dt as the body dv, the
//                          gyro's change as dw) enters the thruster learner
//                          (ThrusterBlr, window 30) for that valve mask
//   range_image_segment -> its points into the modal decomposition (plate
//                          mode shapes at each point); the image's last
//                          segment (or the first segment of another image)
//                          closes it: one modal filter step, answered with
//                          tm_modal
//   cmd_plan_entry      -> one valve opening into the valve plan's staging
//                          area (ValvePlan, fsw/app/valve_plan.hpp)
//   cmd_plan            -> load (check the staged plan against the limits
//                          and store it), start (time zero = its time tag)
//                          or abort; answered with tm_plan_status; a
//                          refused command changes nothing and is counted
//                          (plan_commands_refused)
// Valve plan: while a plan runs, every imu_sample (after the learner has
// taken the interval it ends) computes the valve command of the interval
// it opens, [t, t + dt_imu_s), sends it as tm_plan_valves (what the valve
// drivers would be given) and holds it as the learner's next firing
// interval, as a thruster_valves would be (only a command whose open
// valves are open the whole interval: a partial firing is not the mask's
// effect). A thruster_valves that arrives while a plan runs is counted
// and not held: the plan commands the valves. The tick at or after the
// plan's end closes every valve (tm_plan_valves state finished, then
// tm_plan_status); an abort, or a cmd_reset carried out, closes them at
// once (state aborted).
// Re-acquisition: a pose re-initialises position and attitude (velocity and
// biases kept) instead of correcting them when either
//   - the filter is lost: its position or attitude standard deviation is
//     above reacquire_lost_pos_sigma_m / reacquire_lost_att_sigma_rad (an
//     outage: after an hour's coast the attitude variance sits at its
//     ceiling and a pose is no small correction; in float the update would
//     be refused), or
//   - it has rejected reacquire_after_poses poses in a row (gated or not
//     positive definite) that agree with each other (position within
//     4 sigma plus kReacquireMaxSpeed x dt, attitude within 4 sigma plus
//     kReacquireMaxRate x dt): the filter, not the camera, is wrong. A lone
//     outlier, or outliers that do not agree, change nothing.
// That pose's tm_innovation then has step_kind 3 (reacquire), fused 0.
//
// Every imu_sample, led_pose and cmd_reset answers with tm_innovation (the
// step record), tm_estimate and tm_covariance_diag, in that order; an
// imu_sample that fed the learner also with tm_learner (its prediction for
// that mask after the sample); every tenth imu_sample also with
// tm_link_counters and tm_housekeeping.
//
// Real-time core: fixed buffers, no heap, no exceptions, no I/O; a full
// transmit buffer drops telemetry and counts it.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "fsw/app/range_segment.hpp"
#include "fsw/app/valve_plan.hpp"
#include "fsw/link/apid.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"
#include "fsw/modal/modal_tracker.hpp"
#include "fsw/nav/nav_ukf.hpp"
#include "fsw/thrusters/blr.hpp"

namespace fsw {

// Parameter ids of cmd_config.
enum class ConfigParam : std::uint32_t {
  PosePosFraction = 1,    // pose position 1-sigma as a fraction of range (used when r_sigma_m = 0)
  PoseAttSigmaRad = 2,    // pose attitude 1-sigma [rad] (used when att_sigma_rad = 0)
  HousekeepingEvery = 3,  // imu samples between link-counter / housekeeping telemetry
  // Navigation filter settings (NavConfig), applied at the next cmd_reset:
  NavAccelSigma = 4,  // accel_sigma_mps2
  NavGyroSigma = 5,   // gyro_sigma_rps
  NavGateChi2 = 6,    // gate_chi2 (<= 0 disables gating)
  NavMaxDelay = 7,    // max_delay_s
  NavOrbitRate = 8,   // n_radps
  NavDtImu = 9,       // dt_imu_s
  // Re-acquisition (0 disables each rule):
  ReacquireAfterPoses = 10,    // consecutive agreeing rejected poses that re-initialise (integer)
  ReacquireLostPosSigma = 11,  // position 1-sigma above which the filter is lost [m]
  ReacquireLostAttSigma = 12,  // attitude 1-sigma above which the filter is lost [rad]
  // Modal estimator (ModalTrackerConfig), applied at the next cmd_reset with bit 2:
  ModalPlateLx = 13,              // plate side along x [m]
  ModalPlateLy = 14,              // plate side along y [m]
  ModalPeriod1 = 15,              // period of the lowest mode [s]
  ModalPeak1 = 16,                // peak deflection of the lowest mode at coefficient 1 [m]
  ModalPriorOmegaFrac = 17,       // 1-sigma of the a priori frequencies, fraction of the model's
  ModalAcquireAfterPeriods = 18,  // frequency acquisition after this many lowest-mode periods (0: none)
  // Valve plan limits (PlanLimits), applied at the next plan load:
  PlanMinOnTime = 19,       // shortest valve opening [s]
  PlanMaxOnTime = 20,       // longest valve opening [s]
  PlanMaxTotalOnTime = 21,  // the openings of a plan summed [s]
  PlanMaxDuration = 22,     // longest plan [s]
  PlanValves = 23,          // valves of the vehicle (indices 0 .. n - 1; 1 to 8, integer)
};

// What a step did, as reported in tm_innovation.step_kind.
enum class StepKind : std::uint8_t { Predict = 0, PoseUpdate = 1, Reset = 2, Reacquire = 3 };

template <typename S>
class FlightApp {
 public:
  using Nav = NavUkf<S, false>;
  static constexpr int kModalModes = static_cast<int>(kModalTmModes);
  using Modal = ModalTracker<S, kModalModes>;
  static constexpr std::size_t kTxCapacity = 16384;
  // Fastest relative motion two agreeing poses may differ by (the inspector
  // closes at cm/s and turns at a few deg/s; these leave a wide margin).
  static constexpr double kReacquireMaxSpeed = 0.5;  // [m/s]
  static constexpr double kReacquireMaxRate = 0.5;   // [rad/s]

  struct Counters {
    std::uint32_t imu_steps = 0;
    std::uint32_t pose_updates = 0;
    std::uint32_t pose_fused = 0;
    std::uint32_t poses_deferred = 0;  // arrived before their capture tick's IMU sample; fused after it
    std::uint32_t resets = 0;
    std::uint32_t resets_refused = 0;  // cmd_reset the filter would refuse: nothing changed
    std::uint32_t reacquisitions = 0;  // filter re-initialised from a pose (lost, or rejecting agreeing poses)
    std::uint32_t configs_rejected = 0;
    std::uint32_t valves = 0;
    std::uint32_t valves_not_held = 0;  // thruster_valves while a plan commands the valves
    std::uint32_t learner_samples = 0;  // firing intervals entered into the learner
    std::uint32_t unhandled = 0;        // accepted packets this build does not consume
    std::uint32_t plan_entries = 0;     // cmd_plan_entry received
    std::uint32_t plans_loaded = 0;
    std::uint32_t plan_starts = 0;
    std::uint32_t plan_aborts = 0;  // by cmd_plan abort or by a cmd_reset
    std::uint32_t plans_finished = 0;
    std::uint32_t plan_commands_refused = 0;  // cmd_plan refused: nothing changed
    std::uint32_t plan_valve_commands = 0;    // tm_plan_valves produced while running
    std::uint32_t tx_packets = 0;
    std::uint32_t tx_dropped = 0;         // telemetry lost to a full transmit buffer
    std::uint32_t tm_values_clamped = 0;  // non-finite telemetry doubles sent as +-max (see send())
  };

  explicit FlightApp(const NavConfig<S>& nav_cfg = NavConfig<S>())
      : nav_cfg_(nav_cfg), nav_(nav_cfg), deframer_(Direction::ToFlight), framer_(Direction::FromFlight) {}

  // Consumes every byte; dispatches each accepted packet. Bounded by n.
  void on_bytes(const std::uint8_t* data, std::size_t n);

  // Moves up to cap bytes of pending telemetry frames into out.
  std::size_t take_tx(std::uint8_t* out, std::size_t cap);
  std::size_t tx_pending() const { return tx_len_; }

  // The platform reports how long the last on_bytes call took (housekeeping).
  void note_step_cpu(double seconds);

  const Nav& nav() const { return nav_; }
  const ThrusterBlr<S, 30>& learner() const { return learner_; }
  const LinkCounters& link() const { return deframer_.counters(); }
  const Counters& counters() const { return counters_; }
  const Modal& modal() const { return modal_; }
  const ValvePlan& plan() const { return plan_; }
  const PlanLimits& plan_limits() const { return plan_limits_; }

 private:
  void dispatch(const PacketView& p);

  void on_imu(const PacketView& p);

  void on_valves(const PacketView& p);

  // The IMU sample whose interval is the held firing interval teaches the
  // learner that valve mask's effect; the gyro's change across the interval
  // is the dw (the previous sample is kept for it, and must be the one that
  // opened the interval: after a lost sample the dw would span two).
  void learn(double t_s, const ImuSampleMsg<S>& m);

  void on_pose(const PacketView& p);

  // One pose into the filter: a correction, or a re-acquisition when the
  // filter is lost or has rejected enough agreeing poses in a row.
  StepKind apply_pose(double t_s, const Vec3<S>& r, const Quat<S>& q, const typename Nav::MeasCov& R,
                      typename Nav::Record& rec);

  StepKind reacquire(double t_s, const Vec3<S>& r, const Quat<S>& q, const typename Nav::MeasCov& R,
                     typename Nav::Record& rec);

  bool lost() const;

  // A rejected pose extends the run of rejected poses when it agrees with
  // the previous one, else starts a new run.
  void note_rejected(double t_s, const Vec3<S>& r, const Quat<S>& q, const typename Nav::MeasCov& R);

  void on_reset(const PacketView& p);

  void on_config(const PacketView& p);

  // A setting that the filter would reject (checked again at reset) is
  // refused here and counted.
  template <typename T>
  void set_nav(T& field, S value) {
    const T old = field;
    field = static_cast<T>(value);
    if (nav_config_invalid_field(nav_cfg_, Nav::kN, Nav::kHistoryCapacity) != nullptr) {
      field = old;
      ++counters_.configs_rejected;
    }
  }

  void set_modal(double& field, S value);

  void on_range_segment(const PacketView& p);

  void on_plan_entry(const PacketView& p);

  void on_plan(const PacketView& p);

  // The running plan's command for the interval the IMU sample at t_s opens.
  void plan_tick(double t_s);

  // Closes every valve of a running plan at t_s (abort, reset).
  void plan_abort(double t_s);

  void send_plan_valves(const PlanCommand& c, PlanState state, double t_s);

  void send_plan_status(std::uint8_t action, PlanVerdict verdict, double t_s);

  void set_plan_limit(double& field, S value);

  void report_modal(const typename Modal::Report& r);

  // tm_innovation (the step record), then the estimate and the covariance
  // diagonal, all tagged with the filter time t_s (a late pose's capture
  // time would make the telemetry time tags run backwards).
  void report(StepKind kind, const typename Nav::Record& rec, double t_s);

  void housekeeping(double t_s);

  // Telemetry never carries a non-finite number (the bench, like this
  // side's deframer, refuses such a packet whole): each NaN or infinite
  // double of the payload is sent as the largest finite double, with the
  // sign of an infinity (NaN as +max), and counted (tm_values_clamped).
  template <typename Msg>
  void send(Apid apid, const Msg& msg, double t_s) {
    const ApidInfo* info = apid_info(static_cast<std::uint16_t>(apid));
    if (info == nullptr || kTxCapacity - tx_len_ < kMaxFrameBytes) {
      ++counters_.tx_dropped;
      return;
    }
    encode(msg, tm_payload_.data());
    clamp_non_finite(*info);
    const std::size_t n =
        framer_.frame(apid, t_s, tm_payload_.data(), info->payload_len, tx_.data() + tx_len_, kTxCapacity - tx_len_);
    if (n == 0) {
      ++counters_.tx_dropped;
      return;
    }
    tx_len_ += n;
    ++counters_.tx_packets;
  }

  void clamp_non_finite(const ApidInfo& info) {
    constexpr double kMax = std::numeric_limits<double>::max();
    for (std::size_t i = 0; i < info.f64_count; ++i) {
      std::uint8_t* at = tm_payload_.data() + info.f64_offset + 8 * i;
      const double v = get_f64le(at);
      if (std::isfinite(v)) continue;
      put_f64le(at, std::isnan(v) ? kMax : std::copysign(kMax, v));
      ++counters_.tm_values_clamped;
    }
  }

  struct RejectedRun {
    std::uint32_t n = 0;  // consecutive rejected poses that agree with each other
    double t_s = 0.0;     // the last one
    Vec3<S> r = Vec3<S>::Zero();
    Quat<S> q = Quat<S>::Identity();
    S r_var = S(0);
    S a_var = S(0);
  };

  struct PendingPose {
    bool valid = false;
    double t_s = 0.0;
    Vec3<S> r_hill_m = Vec3<S>::Zero();
    Quat<S> q_hb = Quat<S>::Identity();
    typename Nav::MeasCov R = Nav::MeasCov::Identity();
  };

  using Learner = ThrusterBlr<S, 30>;

  NavConfig<S> nav_cfg_;
  Nav nav_;
  PendingPose pending_;
  RejectedRun rejected_;
  std::uint32_t reacquire_after_ = 5;
  S lost_pos_sigma_ = S(10);
  S lost_att_sigma_ = S(0.5);
  Learner learner_;
  ValvePlan plan_;
  PlanLimits plan_limits_;
  ModalTrackerConfig modal_cfg_;
  Modal modal_;
  ThrusterValvesMsg<S> valves_;
  double valves_t_s_ = 0.0;
  bool valves_pending_ = false;
  Vec3<S> prev_gyro_ = Vec3<S>::Zero();
  double prev_gyro_t_s_ = 0.0;
  bool have_prev_gyro_ = false;
  Deframer deframer_;
  Framer framer_;
  Counters counters_;
  std::array<std::uint8_t, kTxCapacity> tx_{};
  std::array<std::uint8_t, kMaxPayloadLen> tm_payload_{};
  std::size_t tx_len_ = 0;
  std::uint32_t step_index_ = 0;
  std::uint32_t hk_every_ = 10;
  S pose_pos_fraction_ = S(0.05);
  S pose_att_sigma_ = S(0.01);
  double last_cpu_s_ = 0.0;
  double max_cpu_s_ = 0.0;
};

template <typename S>
void FlightApp<S>::on_bytes(const std::uint8_t* data, std::size_t n) {
  std::size_t used = 0;
  while (used < n) {
    DeframeResult res;
    const std::size_t k = deframer_.feed(data + used, n - used, res);
    used += k;
    if (res.kind == DeframeResult::Kind::Packet) dispatch(res.packet);
    if (k == 0) break;  // defensive: feed always consumes when bytes remain
  }
}

template <typename S>
std::size_t FlightApp<S>::take_tx(std::uint8_t* out, std::size_t cap) {
  const std::size_t n = tx_len_ < cap ? tx_len_ : cap;
  for (std::size_t i = 0; i < n; ++i) out[i] = tx_[i];
  for (std::size_t i = n; i < tx_len_; ++i) tx_[i - n] = tx_[i];
  tx_len_ -= n;
  return n;
}

template <typename S>
void FlightApp<S>::note_step_cpu(double seconds) {
  last_cpu_s_ = seconds;
  if (seconds > max_cpu_s_) max_cpu_s_ = seconds;
}

template <typename S>
inline void FlightApp<S>::dispatch(const PacketView& p) {
  switch (static_cast<Apid>(p.header.apid)) {
    case Apid::ImuSample: return on_imu(p);
    case Apid::LedPose: return on_pose(p);
    case Apid::CmdReset: return on_reset(p);
    case Apid::CmdConfig: return on_config(p);
    case Apid::ThrusterValves: return on_valves(p);
    case Apid::RangeImageSegment: return on_range_segment(p);
    case Apid::CmdPlanEntry: return on_plan_entry(p);
    case Apid::CmdPlan: return on_plan(p);
    default: ++counters_.unhandled; return;
  }
}

template <typename S>
inline void FlightApp<S>::on_imu(const PacketView& p) {
  ImuSampleMsg<S> m;
  decode(p.payload, p.t_s, m);  // the deframer has checked finiteness
  const typename Nav::Record rec = nav_.predict(p.t_s, m.accel_b_mps2, m.omega_bi_b_rps);
  ++counters_.imu_steps;
  report(StepKind::Predict, rec, p.t_s);
  learn(p.t_s, m);
  plan_tick(p.t_s);
  if (pending_.valid && nav_.initialized() && nav_.t_s() >= pending_.t_s - nav_cfg_.time_tol_s) {
    pending_.valid = false;
    typename Nav::Record prec;
    const StepKind kind = apply_pose(pending_.t_s, pending_.r_hill_m, pending_.q_hb, pending_.R, prec);
    report(kind, prec, nav_.t_s());
  }
  if (hk_every_ > 0 && counters_.imu_steps % hk_every_ == 0) housekeeping(p.t_s);
}

template <typename S>
inline void FlightApp<S>::on_valves(const PacketView& p) {
  ThrusterValvesMsg<S> m;
  decode(p.payload, p.t_s, m);
  ++counters_.valves;
  if (plan_.state() == PlanState::Running) {
    ++counters_.valves_not_held;
    return;
  }
  valves_ = m;
  valves_t_s_ = p.t_s;  // the double time tag (a float t_s loses the tick after hours)
  valves_pending_ = true;
}

template <typename S>
inline void FlightApp<S>::learn(double t_s, const ImuSampleMsg<S>& m) {
  const bool covers = valves_pending_ && valves_.valve_mask != 0 &&
                      std::abs(t_s - valves_t_s_ - double(valves_.interval_s)) <= nav_cfg_.time_tol_s;
  const bool prev_opens = have_prev_gyro_ && std::abs(prev_gyro_t_s_ - valves_t_s_) <= nav_cfg_.time_tol_s;
  if (covers && prev_opens) {
    valves_pending_ = false;
    typename Learner::VecY y;
    y.template head<3>() = m.accel_b_mps2 * valves_.interval_s;
    y.template tail<3>() = m.omega_bi_b_rps - prev_gyro_;
    const auto x = ValveFeatures<S>::from_mask(valves_.valve_mask);
    const auto add = learner_.add(x, y);
    if (add.status == StepStatus::Ok) ++counters_.learner_samples;
    const auto pred = learner_.predict(x);
    TmLearnerMsg<S> tm;
    tm.n_samples = static_cast<std::uint32_t>(pred.count);
    tm.status = static_cast<std::uint32_t>(pred.status);
    tm.dv_b_mps = pred.mean.template head<3>();
    tm.dw_b_rps = pred.mean.template tail<3>();
    tm.variance = pred.variance;
    send(Apid::TmLearner, tm, t_s);
  } else if (valves_pending_ && t_s > valves_t_s_ + double(valves_.interval_s) + nav_cfg_.time_tol_s) {
    valves_pending_ = false;  // its interval's IMU sample never came
  }
  prev_gyro_ = m.omega_bi_b_rps;
  prev_gyro_t_s_ = t_s;
  have_prev_gyro_ = true;
}

template <typename S>
inline void FlightApp<S>::on_pose(const PacketView& p) {
  LedPoseMsg<S> m;
  decode(p.payload, p.t_s, m);
  const S r_sigma = m.r_sigma_m > S(0) ? m.r_sigma_m : pose_pos_fraction_ * m.r_hill_m.norm();
  const S a_sigma = m.att_sigma_rad > S(0) ? m.att_sigma_rad : pose_att_sigma_;
  typename Nav::MeasCov R = Nav::MeasCov::Zero();
  R.diagonal().template head<3>().setConstant(r_sigma * r_sigma);
  R.diagonal().template tail<3>().setConstant(a_sigma * a_sigma);
  typename Nav::Record rec;
  const StepKind kind = apply_pose(p.t_s, m.r_hill_m, m.q_hb, R, rec);
  ++counters_.pose_updates;
  // The pose and IMU streams are independent: a pose may arrive before the
  // IMU sample of its capture tick (or that sample may be lost and bridged
  // by the next one). Such a pose, up to max_dt_s ahead, waits in one slot
  // (a newer one replaces it) and is fused after the predict that reaches
  // its tick; this step answers with the from_future record.
  if (rec.status == StepStatus::BadInput && rec.detail == StepDetail::FromFuture && nav_.initialized() &&
      p.t_s - nav_.t_s() <= nav_cfg_.max_dt_s) {
    pending_.valid = true;
    pending_.t_s = p.t_s;
    pending_.r_hill_m = m.r_hill_m;
    pending_.q_hb = m.q_hb;
    pending_.R = R;
    ++counters_.poses_deferred;
  }
  report(kind, rec, nav_.initialized() ? nav_.t_s() : p.t_s);
}

template <typename S>
inline auto FlightApp<S>::apply_pose(double t_s, const Vec3<S>& r, const Quat<S>& q, const typename Nav::MeasCov& R,
                                     typename Nav::Record& rec) -> StepKind {
  if (nav_.initialized() && lost()) return reacquire(t_s, r, q, R, rec);
  rec = nav_.update_pose(t_s, r, q, R);
  if (rec.fused) {
    ++counters_.pose_fused;
    rejected_.n = 0;
    return StepKind::PoseUpdate;
  }
  if (rec.status == StepStatus::Gated || rec.status == StepStatus::NotPosDef) {
    note_rejected(t_s, r, q, R);
    if (reacquire_after_ > 0 && rejected_.n >= reacquire_after_) return reacquire(t_s, r, q, R, rec);
  }
  return StepKind::PoseUpdate;
}

template <typename S>
inline auto FlightApp<S>::reacquire(double t_s, const Vec3<S>& r, const Quat<S>& q, const typename Nav::MeasCov& R,
                                    typename Nav::Record& rec) -> StepKind {
  rec = nav_.reacquire(t_s, r, q, R);
  if (rec.status == StepStatus::Ok) {
    ++counters_.reacquisitions;
    rejected_.n = 0;
  }
  return StepKind::Reacquire;
}

template <typename S>
inline bool FlightApp<S>::lost() const {
  const auto d = nav_.P().diagonal();
  const S pos_var = d.template segment<3>(0).maxCoeff();
  const S att_var = d.template segment<3>(6).maxCoeff();
  return (lost_pos_sigma_ > S(0) && pos_var > lost_pos_sigma_ * lost_pos_sigma_) ||
         (lost_att_sigma_ > S(0) && att_var > lost_att_sigma_ * lost_att_sigma_);
}

template <typename S>
inline void FlightApp<S>::note_rejected(double t_s, const Vec3<S>& r, const Quat<S>& q,
                                        const typename Nav::MeasCov& R) {
  const S r_var = R.diagonal().template head<3>().maxCoeff();
  const S a_var = R.diagonal().template tail<3>().maxCoeff();
  bool agrees = false;
  if (rejected_.n > 0) {
    const S dt = S(std::abs(t_s - rejected_.t_s));
    const S dr = (r - rejected_.r).norm();
    const S da = boxminus(normalized(q), rejected_.q).norm();
    agrees = dr <= S(4) * std::sqrt(r_var + rejected_.r_var) + S(kReacquireMaxSpeed) * dt &&
             da <= S(4) * std::sqrt(a_var + rejected_.a_var) + S(kReacquireMaxRate) * dt;
  }
  rejected_.n = agrees ? rejected_.n + 1 : 1;
  rejected_.t_s = t_s;
  rejected_.r = r;
  rejected_.q = normalized(q);
  rejected_.r_var = r_var;
  rejected_.a_var = a_var;
}

template <typename S>
inline void FlightApp<S>::on_reset(const PacketView& p) {
  CmdResetMsg<S> m;
  decode(p.payload, p.t_s, m);
  const bool nav_bit = (m.target_mask & 0x1u) != 0;
  typename Nav::State x0;
  typename Nav::Cov P0 = Nav::Cov::Zero();
  if (nav_bit) {
    x0.r_hill_m = m.r_hill_m;
    x0.v_hill_mps = m.v_hill_mps;
    x0.q_hb = m.q_hb;
    P0.diagonal().template segment<3>(0).setConstant(m.pos_sigma_m * m.pos_sigma_m);
    P0.diagonal().template segment<3>(3).setConstant(m.vel_sigma_mps * m.vel_sigma_mps);
    P0.diagonal().template segment<3>(6).setConstant(m.att_sigma_rad * m.att_sigma_rad);
    // All or nothing: a reset the filter would refuse (a sigma whose square
    // overflows, a zero sigma, settings it rejects) changes nothing at all.
    const typename Nav::Record verdict = Nav::check_init(nav_cfg_, p.t_s, x0, P0);
    if (verdict.status != StepStatus::Ok) {
      ++counters_.resets_refused;
      report(StepKind::Reset, verdict, nav_.initialized() ? nav_.t_s() : p.t_s);
      return;
    }
  }
  ++counters_.resets;
  plan_abort(p.t_s);  // a new time base: the running plan's schedule no longer holds
  // A reset starts a new time base: the link's time history is cleared
  // (sequence counts kept), so one command tagged far in the future cannot
  // lock an APID out.
  deframer_.reset_time_history();
  if (m.target_mask & 0x8u) deframer_.reset_counters();
  if (m.target_mask & 0x2u) {
    learner_.reset();
    valves_pending_ = false;
    have_prev_gyro_ = false;
  }
  if (m.target_mask & 0x4u) modal_.configure(modal_cfg_);  // checked when set
  if (!nav_bit) return;
  nav_ = Nav(nav_cfg_);  // fixed-size object: rebuilt in place, no heap
  pending_.valid = false;
  rejected_.n = 0;
  const typename Nav::Record rec = nav_.init(p.t_s, x0, P0);
  report(StepKind::Reset, rec, p.t_s);
}

template <typename S>
inline void FlightApp<S>::on_config(const PacketView& p) {
  CmdConfigMsg<S> m;
  decode(p.payload, p.t_s, m);
  switch (static_cast<ConfigParam>(m.param_id)) {
    case ConfigParam::PosePosFraction:
      if (m.value > S(0)) {
        pose_pos_fraction_ = m.value;
        return;
      }
      break;
    case ConfigParam::PoseAttSigmaRad:
      if (m.value > S(0)) {
        pose_att_sigma_ = m.value;
        return;
      }
      break;
    case ConfigParam::HousekeepingEvery:
      if (m.value >= S(0) && m.value <= S(100000)) {
        hk_every_ = static_cast<std::uint32_t>(m.value);
        return;
      }
      break;
    case ConfigParam::NavAccelSigma: return set_nav(nav_cfg_.accel_sigma_mps2, m.value);
    case ConfigParam::NavGyroSigma: return set_nav(nav_cfg_.gyro_sigma_rps, m.value);
    case ConfigParam::NavGateChi2: nav_cfg_.gate_chi2 = m.value; return;
    case ConfigParam::NavMaxDelay: return set_nav(nav_cfg_.max_delay_s, m.value);
    case ConfigParam::NavOrbitRate: return set_nav(nav_cfg_.n_radps, m.value);
    case ConfigParam::NavDtImu: return set_nav(nav_cfg_.dt_imu_s, m.value);
    case ConfigParam::ReacquireAfterPoses:
      if (m.value >= S(0) && m.value <= S(1000)) {
        reacquire_after_ = static_cast<std::uint32_t>(m.value);
        return;
      }
      break;
    case ConfigParam::ReacquireLostPosSigma:
      if (m.value >= S(0)) {
        lost_pos_sigma_ = m.value;
        return;
      }
      break;
    case ConfigParam::ReacquireLostAttSigma:
      if (m.value >= S(0)) {
        lost_att_sigma_ = m.value;
        return;
      }
      break;
    case ConfigParam::ModalPlateLx: return set_modal(modal_cfg_.plate.lx_m, m.value);
    case ConfigParam::ModalPlateLy: return set_modal(modal_cfg_.plate.ly_m, m.value);
    case ConfigParam::ModalPeriod1: return set_modal(modal_cfg_.plate.period1_s, m.value);
    case ConfigParam::ModalPeak1: return set_modal(modal_cfg_.plate.peak1_m, m.value);
    case ConfigParam::ModalPriorOmegaFrac: return set_modal(modal_cfg_.prior_omega_frac, m.value);
    case ConfigParam::ModalAcquireAfterPeriods: return set_modal(modal_cfg_.acquire_after_periods, m.value);
    case ConfigParam::PlanMinOnTime: return set_plan_limit(plan_limits_.min_on_time_s, m.value);
    case ConfigParam::PlanMaxOnTime: return set_plan_limit(plan_limits_.max_on_time_s, m.value);
    case ConfigParam::PlanMaxTotalOnTime: return set_plan_limit(plan_limits_.max_total_on_time_s, m.value);
    case ConfigParam::PlanMaxDuration: return set_plan_limit(plan_limits_.max_duration_s, m.value);
    case ConfigParam::PlanValves:
      if (m.value >= S(1) && m.value <= S(kPlanValves) && m.value == std::floor(m.value)) {
        plan_limits_.valves = static_cast<std::uint32_t>(m.value);
        return;
      }
      break;
  }
  ++counters_.configs_rejected;
}

template <typename S>
inline void FlightApp<S>::set_modal(double& field, S value) {
  const double old = field;
  field = double(value);
  if (modal_tracker_config_invalid_field(modal_cfg_) != nullptr) {
    field = old;
    ++counters_.configs_rejected;
  }
}

template <typename S>
inline void FlightApp<S>::set_plan_limit(double& field, S value) {
  const double old = field;
  field = double(value);
  if (plan_limits_invalid_field(plan_limits_) != nullptr) {
    field = old;
    ++counters_.configs_rejected;
  }
}

template <typename S>
inline void FlightApp<S>::on_plan_entry(const PacketView& p) {
  CmdPlanEntryMsg m;
  decode(p.payload, p.t_s, m);  // the deframer has checked finiteness
  ++counters_.plan_entries;
  plan_.stage(m);
}

template <typename S>
inline void FlightApp<S>::on_plan(const PacketView& p) {
  CmdPlanMsg m;
  decode(p.payload, p.t_s, m);
  PlanVerdict v = PlanVerdict::UnknownAction;
  switch (static_cast<PlanAction>(m.action)) {
    case PlanAction::Load:
      v = plan_.load(m, plan_limits_);
      if (v == PlanVerdict::Accepted) ++counters_.plans_loaded;
      break;
    case PlanAction::Start:
      v = plan_.start(m.plan_id, p.t_s);
      if (v == PlanVerdict::Accepted) ++counters_.plan_starts;
      break;
    case PlanAction::Abort:
      if (plan_.state() != PlanState::Running) {
        v = PlanVerdict::NotRunning;
        break;
      }
      plan_abort(p.t_s);
      v = PlanVerdict::Accepted;
      break;
  }
  if (v != PlanVerdict::Accepted) ++counters_.plan_commands_refused;
  send_plan_status(static_cast<std::uint8_t>(m.action <= 3 ? m.action : 0), v, p.t_s);
}

template <typename S>
inline void FlightApp<S>::plan_tick(double t_s) {
  PlanCommand c;
  if (!plan_.command(t_s, nav_cfg_.dt_imu_s, nav_cfg_.time_tol_s, c)) return;
  if (c.state == PlanState::Finished) {
    plan_.finish();
    ++counters_.plans_finished;
    send_plan_valves(c, PlanState::Finished, t_s);
    send_plan_status(0, PlanVerdict::Accepted, t_s);
    return;
  }
  ++counters_.plan_valve_commands;
  // The command is the learner's next firing interval, as a thruster_valves.
  valves_.t_s = static_cast<S>(t_s);
  valves_.interval_s = static_cast<S>(nav_cfg_.dt_imu_s);
  valves_.valve_mask = c.valve_mask;
  valves_t_s_ = t_s;
  valves_pending_ = c.full && c.valve_mask != 0;
  send_plan_valves(c, PlanState::Running, t_s);
}

template <typename S>
inline void FlightApp<S>::plan_abort(double t_s) {
  if (plan_.abort() != PlanVerdict::Accepted) return;
  ++counters_.plan_aborts;
  valves_pending_ = false;
  PlanCommand c;
  c.plan_time_s = t_s - plan_.t_start_s();
  send_plan_valves(c, PlanState::Aborted, t_s);
}

template <typename S>
inline void FlightApp<S>::send_plan_valves(const PlanCommand& c, PlanState state, double t_s) {
  TmPlanValvesMsg tm;
  tm.plan_id = plan_.id();
  tm.valve_mask = state == PlanState::Running ? c.valve_mask : 0;
  tm.state = static_cast<std::uint8_t>(state);
  tm.interval_s = nav_cfg_.dt_imu_s;
  tm.plan_time_s = c.plan_time_s;
  if (state == PlanState::Running) tm.on_time_s = c.on_time_s;
  send(Apid::TmPlanValves, tm, t_s);
}

template <typename S>
inline void FlightApp<S>::send_plan_status(std::uint8_t action, PlanVerdict verdict, double t_s) {
  TmPlanStatusMsg tm;
  tm.plan_id = plan_.id();
  tm.state = static_cast<std::uint8_t>(plan_.state());
  tm.action = action;
  tm.verdict = static_cast<std::uint8_t>(verdict);
  tm.entry_count = static_cast<std::uint32_t>(plan_.size());
  tm.entries_received = plan_.entries_received();
  tm.plans_loaded = counters_.plans_loaded;
  tm.commands_refused = counters_.plan_commands_refused;
  tm.duration_s = plan_.duration_s();
  tm.total_on_time_s = plan_.total_on_time_s();
  send(Apid::TmPlanStatus, tm, t_s);
}

template <typename S>
inline void FlightApp<S>::on_range_segment(const PacketView& p) {
  RangeImageSegmentMsg<S> m;
  decode(p.payload, p.t_s, p.header.seq_flags, m);  // the deframer has checked fields and finiteness
  typename Modal::Report rep;
  if (modal_.close_other(m.image_id, rep)) report_modal(rep);
  ModalSegmentPoints<S> points;
  if (modal_.add(modal_segment_of(m, points), p.t_s, rep)) report_modal(rep);
}

template <typename S>
inline void FlightApp<S>::report_modal(const typename Modal::Report& r) {
  TmModalMsg<S> tm;
  tm.image_id = r.image_id;
  tm.status = static_cast<std::uint8_t>(r.step.status);
  tm.decomposition = static_cast<std::uint8_t>(r.decomposition.status);
  tm.fused = r.step.fused ? 1 : 0;
  tm.n_used = static_cast<std::uint32_t>(r.decomposition.n_used);
  tm.n_skipped = static_cast<std::uint32_t>(r.decomposition.n_nonfinite + r.decomposition.n_bad_variance + r.n_outside);
  const S emax = r.decomposition.eig_max, emin = r.decomposition.eig_min;
  tm.rcond = emax > S(0) && emin > S(0) && std::isfinite(emax) ? emin / emax : S(0);
  tm.nis = r.step.nis;
  const auto& filt = modal_.filter();
  if (filt.initialized()) {
    tm.n_modes = static_cast<std::uint8_t>(kModalModes);
    for (int i = 0; i < kModalModes; ++i) {
      const auto x = filt.mode_state(i);
      tm.amplitude(i) = x(0);
      tm.omega_radps(i) = x(2);
      tm.alpha_ps(i) = x(3);
      tm.amplitude_sigma(i) = std::sqrt(filt.mode_cov(i)(0, 0));
    }
  }
  send(Apid::TmModal, tm, r.t_s);
}

template <typename S>
inline void FlightApp<S>::report(StepKind kind, const typename Nav::Record& rec, double t_s) {
  TmInnovationMsg<S> inn;
  inn.step_kind = static_cast<std::uint8_t>(kind);
  inn.status = static_cast<std::uint8_t>(rec.status);
  inn.fused = rec.fused ? 1 : 0;
  inn.meas_dim = kind == StepKind::PoseUpdate ? 6 : 0;
  inn.step_index = ++step_index_;
  inn.innovation = rec.innovation;
  // An overflowed step (a pose 1e308 m away) gives NIS = inf and
  // log-likelihood = -inf, or NaN from inf - inf: NaN is sent as the
  // overflow it is (NIS +max, log-likelihood -max; see send()).
  inn.nis = std::isnan(rec.nis) ? std::numeric_limits<S>::infinity() : rec.nis;
  inn.log_likelihood = std::isnan(rec.log_likelihood) ? -std::numeric_limits<S>::infinity() : rec.log_likelihood;
  send(Apid::TmInnovation, inn, t_s);
  if (!nav_.initialized()) return;
  TmEstimateMsg<S> est;
  est.r_hill_m = nav_.state().r_hill_m;
  est.v_hill_mps = nav_.state().v_hill_mps;
  est.q_hb = nav_.state().q_hb;
  send(Apid::TmEstimate, est, t_s);
  TmCovarianceDiagMsg<S> cov;
  cov.n_valid = Nav::kN;
  cov.p_diag.template head<Nav::kN>() = nav_.P().diagonal();
  send(Apid::TmCovarianceDiag, cov, t_s);
}

template <typename S>
inline void FlightApp<S>::housekeeping(double t_s) {
  const LinkCounters& c = deframer_.counters();
  TmLinkCountersMsg lc;
  lc.packets_accepted = c.packets_accepted;
  lc.frames_total = c.frames_total;
  lc.seq_gaps_total = c.gaps_total();
  lc.duplicates_total = c.duplicates_total();
  for (std::size_t i = 0; i < kRejectReasonCount; ++i) lc.rejected[i] = c.rejected[i];
  send(Apid::TmLinkCounters, lc, t_s);
  TmHousekeepingMsg<S> hk;
  hk.uptime_s = S(t_s);
  hk.last_step_cpu_s = S(last_cpu_s_);
  hk.max_step_cpu_s = S(max_cpu_s_);
  hk.cycle_count = counters_.imu_steps;
  hk.mode = nav_.initialized() ? 1u : 0u;
  hk.tx_packets = counters_.tx_packets;
  hk.tx_dropped = counters_.tx_dropped;
  send(Apid::TmHousekeeping, hk, t_s);
}

// Compiled once, in fsw_core (instantiate_flight_app.cpp); see nav_ukf.hpp.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class FlightApp<double>;
extern template class FlightApp<float>;
#endif

}  // namespace fsw
