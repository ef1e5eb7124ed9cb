// Inspector navigation: multiplicative (error-state) quaternion UKF over
// Clohessy-Wiltshire relative dynamics (section 2 of
// "Online Dynamic Modeling and Localization for Small-Spacecraft
// Proximity Operations" (Rogers-Marcovitz)).
//
// State and covariance layout: nav_state.hpp. Attitude error is body-frame
// (local): q_true = q_est * Exp(dtheta). Sigma points are formed in the
// tangent space (x [+] gamma * column of chol(P), the paper's eqs. 3-4 with the
// local perturbation) and averaged there: the attitude mean is a single
// tangent-space step around the central (propagated) sigma point, and the
// deviations used for the covariance are exact boxminus against that mean.
// Unit norm is restored only in fsw::normalized (through boxplus /
// propagate_attitude).
//
// Predict (IMU, nominally 10 Hz). predict(t, accel, omega) moves the filter
// from its current time to t with the sample (accel = specific force in the
// body frame, omega = omega_BI_B) held constant over that interval:
//   r, v : CW closed form with the exact constant-acceleration term,
//          [r; v] <- Phi [r; v] + Gamma a_hill (cw.hpp); a_hill is the body
//          acceleration rotated with the mid-step attitude (second order in
//          omega dt), so the sigma points carry the attitude-acceleration
//          coupling.
//   q    : propagate_attitude (Hill frame turning at n about z).
// IMU noise (documented equivalent of the paper's augmented state): each
// sample's white noise (1-sigma per axis) is held over its step, so its
// exact effect is additive process noise
//   Q_rv = sigma_a^2 Gamma Gamma^T   (isotropic, so the rotation drops out)
//   Q_th = sigma_g^2 dt^2 I          (dtheta error after one step)
// plus, with the bias option, random walks sigma_w^2 dt I on both biases.
//
// Update (pose, nominally 1 Hz): z = [r_hill_m, q_hb], innovation
// [r_meas - r_pred, q_meas [-] q_pred], R over [position m^2, attitude rad^2].
// Steps 7-14 of the paper's Table 1 with the tangent-space mean, chi-square
// gating on NIS, log p_z = -(NIS + log det(2 pi S)) / 2.
//
// Delayed measurements: a fixed ring buffer holds, per IMU tick, the state,
// covariance and the IMU sample that led to it. A pose captured at t_c (on a
// stored tick, within time_tol_s; capture times between ticks are rejected
// with BadInput/OffTick) is fused into the state at t_c and the stored IMU
// samples are re-applied up to the current time by the same predict code, so
// the result equals the on-time delivery. Capture times older than
// max_delay_s or than the history give BadInput/TooOld; earlier than the
// last fused capture time, BadInput/OutOfSequence. The state is untouched.
//
// UKF parameters (scaled unscented transform): alpha = 1, beta = 2, kappa = 0
// by default: lambda = 0, gamma = sqrt(n) (3 for 9 states, 3.9 for 15),
// mean weights W0 = 0, Wi = 1/(2n) (none negative), covariance weight
// W0c = 2. Small alpha (1e-3) would give W0 ~ -1e6 and lose float precision.
//
// Time is double in both scalar builds (float cannot tell 0.1 s ticks apart
// after a day). Real-time core: fixed-size Eigen, no heap, no exceptions, no
// I/O, bounded loops.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <limits>

#include "fsw/dynamics/cw.hpp"
#include "fsw/dynamics/hill_attitude.hpp"
#include "fsw/math/covariance.hpp"
#include "fsw/math/so3.hpp"
#include "fsw/math/step_status.hpp"
#include "fsw/nav/nav_state.hpp"

namespace fsw {

template <typename S>
struct NavConfig {
  S n_radps = orbit_rate<S>(S(kEarthRadius + 500e3));  // orbit rate [rad/s] (500 km circular)
  double dt_imu_s = 0.1;                               // nominal IMU period [s]
  S accel_sigma_mps2 = S(1.7e-3);                      // accelerometer white noise, 1-sigma per axis [m/s^2]
  S gyro_sigma_rps = S(0.005);                         // gyro white noise, 1-sigma per axis [rad/s]
  // A tick whose IMU sample was lost is bridged by holding the next sample;
  // the specific force and rate during it are unknown to this extent
  // (default: two 20 mN thrusters on 3 kg; their torque over one 0.1 s step).
  S gap_accel_sigma_mps2 = S(1.3e-2);
  S gap_gyro_sigma_rps = S(0.01);
  S gyro_bias_walk = S(1e-5);   // gyro bias random walk [rad/s/sqrt(s)] (15-state only)
  S accel_bias_walk = S(1e-5);  // accel bias random walk [m/s^2/sqrt(s)] (15-state only)
  S gate_chi2 = S(22.46);       // NIS gate (chi2 6 dof, p = 0.999); <= 0 disables gating
  double max_delay_s = 0.5;     // how late a pose may arrive [s]
  double time_tol_s = 1e-3;     // a capture time within this of a tick is on it [s]
  double max_dt_s = 1.0;        // longest accepted off-grid predict step [s]
  double max_gap_s = 60.0;      // longest run of lost IMU ticks coasted through [s]
  S alpha = S(1);               // sigma-point spread
  S beta = S(2);                // prior-distribution term (2: Gaussian)
  S kappa = S(0);               // secondary scaling
  S var_min = S(1e-12);         // floor of every variance (m^2, m^2/s^2, rad^2, ...)
  S pos_var_max_m2 = S(1e8);    // ceilings of the variances per block
  S vel_var_max_m2ps2 = S(1e4);
  S att_var_max_rad2 = S(1.0);
  S gyro_bias_var_max = S(1e-2);
  S accel_bias_var_max = S(1.0);
  S quat_unit_tol = S(1e-3);  // accepted | |q| - 1 | of a measured quaternion
};

// Name of the first invalid configuration field, or nullptr when valid.
// history_capacity: ticks the filter can store.
template <typename S>
inline const char* nav_config_invalid_field(const NavConfig<S>& c, int n_err, int history_capacity) {
  auto pos = [](double x) { return std::isfinite(x) && x > 0.0; };
  auto nonneg = [](double x) { return std::isfinite(x) && x >= 0.0; };
  if (!pos(double(c.n_radps))) return "n_radps";
  if (!pos(c.dt_imu_s)) return "dt_imu_s";
  if (!pos(c.max_gap_s) || c.max_gap_s / c.dt_imu_s > 100000.0) return "max_gap_s";
  if (!nonneg(double(c.accel_sigma_mps2))) return "accel_sigma_mps2";
  if (!nonneg(double(c.gyro_sigma_rps))) return "gyro_sigma_rps";
  if (!nonneg(double(c.gap_accel_sigma_mps2))) return "gap_accel_sigma_mps2";
  if (!nonneg(double(c.gap_gyro_sigma_rps))) return "gap_gyro_sigma_rps";
  if (!nonneg(double(c.gyro_bias_walk))) return "gyro_bias_walk";
  if (!nonneg(double(c.accel_bias_walk))) return "accel_bias_walk";
  if (!std::isfinite(double(c.gate_chi2))) return "gate_chi2";
  if (!nonneg(c.max_delay_s)) return "max_delay_s";
  if (!pos(c.time_tol_s) || c.time_tol_s >= 0.5 * c.dt_imu_s) return "time_tol_s";
  if (!pos(c.max_dt_s)) return "max_dt_s";
  if (!pos(double(c.alpha))) return "alpha";
  if (!nonneg(double(c.beta))) return "beta";
  if (!std::isfinite(double(c.kappa)) || double(c.alpha) * double(c.alpha) * (n_err + double(c.kappa)) <= 0.0)
    return "kappa";
  if (!pos(double(c.var_min))) return "var_min";
  if (!pos(double(c.pos_var_max_m2)) || c.pos_var_max_m2 <= c.var_min) return "pos_var_max_m2";
  if (!pos(double(c.vel_var_max_m2ps2)) || c.vel_var_max_m2ps2 <= c.var_min) return "vel_var_max_m2ps2";
  if (!pos(double(c.att_var_max_rad2)) || c.att_var_max_rad2 <= c.var_min) return "att_var_max_rad2";
  if (!pos(double(c.gyro_bias_var_max)) || c.gyro_bias_var_max <= c.var_min) return "gyro_bias_var_max";
  if (!pos(double(c.accel_bias_var_max)) || c.accel_bias_var_max <= c.var_min) return "accel_bias_var_max";
  if (!pos(double(c.quat_unit_tol))) return "quat_unit_tol";
  // Ticks needed to reach max_delay_s back, plus the tick at the capture time.
  const double ticks = std::ceil((c.max_delay_s + c.time_tol_s) / c.dt_imu_s) + 1.0;
  if (ticks > double(history_capacity)) return "max_delay_s";
  return nullptr;
}

template <typename S, bool kWithBias = false, int kHistory = 16>
class NavUkf {
 public:
  using Layout = NavLayout<kWithBias>;
  static constexpr int kN = Layout::kErrorSize;
  static constexpr int kSigma = 2 * kN + 1;
  static constexpr int kMeas = 6;
  static constexpr int kHistoryCapacity = kHistory;
  static_assert(kHistory >= 2, "history holds at least the current and one earlier tick");

  using State = NavState<S, kWithBias>;
  using ErrVec = Eigen::Matrix<S, kN, 1>;
  using Cov = Eigen::Matrix<S, kN, kN>;
  using MeasVec = Eigen::Matrix<S, kMeas, 1>;
  using MeasCov = Eigen::Matrix<S, kMeas, kMeas>;
  using Record = StepRecord<S, kMeas>;

  explicit NavUkf(const NavConfig<S>& cfg) : cfg_(cfg) {
    bad_field_ = nav_config_invalid_field(cfg_, kN, kHistory);
    if (bad_field_ != nullptr) return;
    const S lambda = cfg_.alpha * cfg_.alpha * (S(kN) + cfg_.kappa) - S(kN);
    gamma_ = std::sqrt(S(kN) + lambda);
    wm0_ = lambda / (S(kN) + lambda);
    wc0_ = wm0_ + S(1) - cfg_.alpha * cfg_.alpha + cfg_.beta;
    wi_ = S(1) / (S(2) * (S(kN) + lambda));
    dt_nom_ = S(cfg_.dt_imu_s);
    prop_nom_ = make_step(dt_nom_);
    variance_bounds(cfg_, var_min_, var_max_);
  }

  bool config_ok() const { return bad_field_ == nullptr; }
  const char* config_invalid_field() const { return bad_field_; }
  const NavConfig<S>& config() const { return cfg_; }

  // Sets the state at t_s. P0 over the error state; it is conditioned and
  // must factor. On failure the filter keeps its previous state.
  Record init(double t_s, const State& x0, const Cov& P0);

  // The record init() would give on a filter built with cfg (status and
  // detail; Ok when it would succeed), computed without building one, so a
  // command can be refused before it changes anything.
  static Record check_init(const NavConfig<S>& cfg, double t_s, const State& x0, const Cov& P0);

  // Re-acquisition from a pose when the filter is lost (an outage left it
  // too uncertain for a pose to be a correction, or it keeps rejecting poses
  // that agree with each other): at the current time, position and attitude
  // become the pose's, with the pose's covariance and no correlation with
  // the rest; velocity and biases keep their coasted values and covariance.
  // The stored history restarts here (nothing before the jump is replayed).
  // The pose may be up to max_delay_s old; it is taken as of now (the motion
  // in that time is far inside a lost filter's error). On failure the filter
  // keeps its state.
  Record reacquire(double t_capture_s, const Vec3<S>& r_hill_m, const Quat<S>& q_hb, const MeasCov& R);

  // IMU sample (specific force in body [m/s^2], omega_BI_B [rad/s]) held
  // over (t_current, t_s]; moves the filter to t_s. A step of m whole IMU
  // periods (samples lost) is taken as m stored ticks.
  Record predict(double t_s, const Vec3<S>& accel_b_mps2, const Vec3<S>& omega_bi_b_rps);

  // Pose captured at t_capture_s: r_hill_m, q_hb, R over [position m^2,
  // attitude rad^2 (body-frame boxminus)]. May be up to max_delay_s late.
  Record update_pose(double t_capture_s, const Vec3<S>& r_hill_m, const Quat<S>& q_hb, const MeasCov& R);

  bool initialized() const { return initialized_; }
  double t_s() const { return hist_[head_].t_s; }
  const State& state() const { return hist_[head_].x; }
  const Cov& P() const { return hist_[head_].P; }
  int history_count() const { return count_; }

 private:
  struct Entry {
    double t_s = 0.0;
    State x;
    Cov P = Cov::Identity();
    Vec3<S> accel_b_mps2 = Vec3<S>::Zero();  // sample that led to this tick
    Vec3<S> omega_bi_b_rps = Vec3<S>::Zero();
    S dt_s = S(0);
    bool bridged = false;  // a lost tick: the sample is the next one, held
  };

  // Per-step constants: CW transition and acceleration response, the Hill
  // frame's rotation over the step, and the IMU process noise.
  struct StepModel {
    Mat6<S> phi;
    Mat63<S> gamma;
    Quat<S> hill_step;
    Cov Q;
  };

  StepModel make_step(S dt) const;

  // One sigma point through the dynamics.
  State dynamics(const State& x, const Vec3<S>& accel_b, const Vec3<S>& omega_b, S dt, const StepModel& m) const;

  // Sigma-point offsets: column i of gamma * L, i in [0, 2n], 0 the centre.
  ErrVec sigma_offset(const Cov& L, int i) const;

  S wm(int i) const { return i == 0 ? wm0_ : wi_; }
  S wc(int i) const { return i == 0 ? wc0_ : wi_; }

  // Weighted tangent-space mean of sigma states (single step around the
  // centre) and deviations from it.
  void sigma_mean(const State* X, State& mean, Eigen::Matrix<S, kN, kSigma>& D) const;

  // Pure predict: no member written. Returns false if P does not factor,
  // even with the jitter of cholesky_lower_repaired.
  // *repaired is set when P factored only with a jitter (cholesky_lower_repaired).
  bool propagate(const State& x, const Cov& P, const Vec3<S>& accel_b, const Vec3<S>& omega_b, S dt, bool bridged,
                 State& x_out, Cov& P_out, bool* repaired = nullptr) const;

  // Pose fusion into (x, P); fills rec. Outputs written only on Ok.
  StepStatus fuse(const State& x, const Cov& P, const Vec3<S>& r_meas, const Quat<S>& q_meas, const MeasCov& R,
                  Record& rec, State& x_out, Cov& P_out) const;

  static StepStatus set(Record& rec, StepStatus s, StepDetail d);
  static Record reject(Record& rec, StepStatus s, StepDetail d);
  static void variance_bounds(const NavConfig<S>& cfg, ErrVec& var_min, ErrVec& var_max);
  // init()'s checks; on success P is P0 conditioned and L its factor.
  static Record init_checks(const NavConfig<S>& cfg, bool config_ok, const ErrVec& var_min, const ErrVec& var_max,
                            double t_s, const State& x0, const Cov& P0, Cov& P, Cov& L);

  // What a pose must be before either use (update or re-acquisition):
  // filter initialised, values finite, unit quaternion, captured neither
  // after the filter time nor more than max_delay_s before it. False with
  // the reason in rec.
  bool pose_input_ok(double t_capture_s, const Vec3<S>& r_hill_m, const Quat<S>& q_hb, const MeasCov& R,
                     Record& rec) const;

  bool quat_unit(const Quat<S>& q) const { return std::abs(q.norm() - S(1)) <= cfg_.quat_unit_tol; }

  // Ring index k ticks back from the newest.
  int index_back(int k) const { return (head_ - k + kHistory) % kHistory; }

  NavConfig<S> cfg_;
  const char* bad_field_ = nullptr;
  S gamma_ = S(1), wm0_ = S(0), wc0_ = S(0), wi_ = S(0);
  S dt_nom_ = S(0.1);
  StepModel prop_nom_;
  ErrVec var_min_ = ErrVec::Zero();
  ErrVec var_max_ = ErrVec::Zero();
  Entry hist_[kHistory];
  Entry scratch_[kHistory];
  int head_ = 0;
  int count_ = 0;
  bool initialized_ = false;
  double last_fused_t_s_ = 0.0;
};

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::init(double t_s, const State& x0, const Cov& P0) -> Record {
  Cov P;
  Cov L;
  Record rec = init_checks(cfg_, config_ok(), var_min_, var_max_, t_s, x0, P0, P, L);
  if (rec.status != StepStatus::Ok) return rec;
  Entry& e = hist_[0];
  e.t_s = t_s;
  e.x = x0;
  e.x.q_hb = normalized(x0.q_hb);
  if constexpr (!kWithBias) {
    e.x.gyro_bias_rps.setZero();
    e.x.accel_bias_mps2.setZero();
  }
  e.P = P;
  e.accel_b_mps2.setZero();
  e.omega_bi_b_rps.setZero();
  e.dt_s = S(0);
  head_ = 0;
  count_ = 1;
  initialized_ = true;
  last_fused_t_s_ = -std::numeric_limits<double>::infinity();
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
void NavUkf<S, kWithBias, kHistory>::variance_bounds(const NavConfig<S>& cfg, ErrVec& var_min, ErrVec& var_max) {
  var_min.setConstant(cfg.var_min);
  var_max.setZero();
  var_max.template segment<3>(Layout::kDPos.index).setConstant(cfg.pos_var_max_m2);
  var_max.template segment<3>(Layout::kDVel.index).setConstant(cfg.vel_var_max_m2ps2);
  var_max.template segment<3>(Layout::kDTheta.index).setConstant(cfg.att_var_max_rad2);
  if constexpr (kWithBias) {
    var_max.template segment<3>(Layout::kDGyroBias.index).setConstant(cfg.gyro_bias_var_max);
    var_max.template segment<3>(Layout::kDAccelBias.index).setConstant(cfg.accel_bias_var_max);
  }
}

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::init_checks(const NavConfig<S>& cfg, bool config_ok, const ErrVec& var_min,
                                                 const ErrVec& var_max, double t_s, const State& x0, const Cov& P0,
                                                 Cov& P, Cov& L) -> Record {
  Record rec;
  rec.t_s = t_s;
  if (!config_ok) return reject(rec, StepStatus::BadInput, StepDetail::BadConfig);
  if (!std::isfinite(t_s) || !x0.all_finite() || !P0.allFinite())
    return reject(rec, StepStatus::BadInput, StepDetail::NonFinite);
  if (!(std::abs(x0.q_hb.norm() - S(1)) <= cfg.quat_unit_tol))
    return reject(rec, StepStatus::BadInput, StepDetail::NonUnitQuaternion);
  P = P0;
  if (!condition_covariance(P, var_min, var_max) || !cholesky_lower(P, L))
    return reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  rec.status = StepStatus::Ok;
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::check_init(const NavConfig<S>& cfg, double t_s, const State& x0, const Cov& P0)
    -> Record {
  const bool config_ok = nav_config_invalid_field(cfg, kN, kHistory) == nullptr;
  ErrVec var_min = ErrVec::Zero();
  ErrVec var_max = ErrVec::Zero();
  if (config_ok) variance_bounds(cfg, var_min, var_max);
  Cov P;
  Cov L;
  return init_checks(cfg, config_ok, var_min, var_max, t_s, x0, P0, P, L);
}

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::reacquire(double t_capture_s, const Vec3<S>& r_hill_m, const Quat<S>& q_hb,
                                               const MeasCov& R) -> Record {
  Record rec;
  rec.t_s = t_capture_s;
  if (!pose_input_ok(t_capture_s, r_hill_m, q_hb, R, rec)) return rec;
  State x = hist_[head_].x;
  x.r_hill_m = r_hill_m;
  x.q_hb = q_hb;
  Cov P = hist_[head_].P;
  constexpr int ip = Layout::kDPos.index, ia = Layout::kDTheta.index;
  P.template middleRows<3>(ip).setZero();
  P.template middleCols<3>(ip).setZero();
  P.template middleRows<3>(ia).setZero();
  P.template middleCols<3>(ia).setZero();
  P.template block<3, 3>(ip, ip) = R.template block<3, 3>(0, 0);
  P.template block<3, 3>(ia, ia) = R.template block<3, 3>(3, 3);
  P.template block<3, 3>(ip, ia) = R.template block<3, 3>(0, 3);
  P.template block<3, 3>(ia, ip) = R.template block<3, 3>(3, 0);
  const Record r = init(hist_[head_].t_s, x, P);  // taken as of now
  rec.status = r.status;
  rec.detail = r.detail;
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::predict(double t_s, const Vec3<S>& accel_b_mps2, const Vec3<S>& omega_bi_b_rps)
    -> Record {
  Record rec;
  rec.t_s = t_s;
  if (!initialized_) return reject(rec, StepStatus::BadInput, StepDetail::NotInitialized);
  if (!std::isfinite(t_s) || !accel_b_mps2.allFinite() || !omega_bi_b_rps.allFinite())
    return reject(rec, StepStatus::BadInput, StepDetail::NonFinite);
  const Entry& cur = hist_[head_];
  const double dt = t_s - cur.t_s;
  if (!(dt > cfg_.time_tol_s)) return reject(rec, StepStatus::BadInput, StepDetail::TimeNotIncreasing);
  // Missed ticks (IMU samples lost on the way): when dt spans m >= 2 whole
  // IMU periods, this sample is held over each of them (with the gap noise)
  // and the last kHistory - 1 ticks are stored, so a pose captured at a
  // missed tick still lands on a stored tick. Earlier ticks of a long gap
  // are coasted through in two temporaries; the stored ones go to scratch_
  // first: a failure leaves everything untouched. Bounded by max_gap_s.
  const long m = std::lround(dt / cfg_.dt_imu_s);
  const bool on_grid = m >= 2 && std::abs(dt - double(m) * cfg_.dt_imu_s) <= cfg_.time_tol_s;
  if (on_grid ? dt > cfg_.max_gap_s : dt > cfg_.max_dt_s)
    return reject(rec, StepStatus::BadInput, StepDetail::StepTooLong);
  const int steps = on_grid ? int(m) : 1;
  const int kept = steps < kHistory - 1 ? steps : kHistory - 1;
  const int coast = steps - kept;
  bool repaired = false;
  Entry coast_a, coast_b;
  const Entry* prev = &cur;
  for (int i = 0; i < steps; ++i) {  // bounded: max_gap_s / dt_imu_s
    Entry& next = i < coast ? ((i % 2) ? coast_b : coast_a) : scratch_[i - coast];
    next.t_s = (i + 1 == steps) ? t_s : cur.t_s + double(i + 1) * cfg_.dt_imu_s;
    next.accel_b_mps2 = accel_b_mps2;
    next.omega_bi_b_rps = omega_bi_b_rps;
    next.dt_s = S(next.t_s - prev->t_s);
    next.bridged = i + 1 < steps;
    if (!propagate(prev->x, prev->P, next.accel_b_mps2, next.omega_bi_b_rps, next.dt_s, next.bridged, next.x, next.P,
                   &repaired))
      return reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
    prev = &next;
  }
  for (int i = 0; i < kept; ++i) {
    head_ = (head_ + 1) % kHistory;
    if (count_ < kHistory) ++count_;
    hist_[head_] = scratch_[i];
  }
  rec.status = StepStatus::Ok;
  if (repaired) rec.detail = StepDetail::CovarianceRepaired;
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
auto NavUkf<S, kWithBias, kHistory>::update_pose(double t_capture_s, const Vec3<S>& r_hill_m, const Quat<S>& q_hb,
                                                 const MeasCov& R) -> Record {
  Record rec;
  rec.t_s = t_capture_s;
  if (!pose_input_ok(t_capture_s, r_hill_m, q_hb, R, rec)) return rec;
  if (t_capture_s < last_fused_t_s_ - cfg_.time_tol_s)
    return reject(rec, StepStatus::BadInput, StepDetail::OutOfSequence);
  // Find the stored tick at the capture time, newest first.
  int back = -1;
  for (int k = 0; k < count_; ++k) {
    const double te = hist_[index_back(k)].t_s;
    if (std::abs(te - t_capture_s) <= cfg_.time_tol_s) {
      back = k;
      break;
    }
    if (te < t_capture_s) break;  // passed it: capture time between two ticks
  }
  if (back < 0) {
    const double t_oldest = hist_[index_back(count_ - 1)].t_s;
    return reject(rec, StepStatus::BadInput, t_capture_s < t_oldest ? StepDetail::TooOld : StepDetail::OffTick);
  }
  const Entry& at = hist_[index_back(back)];
  Entry* out = scratch_;
  out[0] = at;
  const Vec3<S> r_meas = r_hill_m;
  const Quat<S> q_meas = normalized(q_hb);
  const StepStatus st = fuse(at.x, at.P, r_meas, q_meas, R, rec, out[0].x, out[0].P);
  if (st != StepStatus::Ok) return rec;  // state untouched; rec says why
  bool repaired = rec.detail == StepDetail::CovarianceRepaired;
  // Re-apply the stored IMU samples from the capture tick to now.
  for (int k = back - 1, j = 1; k >= 0; --k, ++j) {
    const Entry& src = hist_[index_back(k)];
    out[j].t_s = src.t_s;
    out[j].accel_b_mps2 = src.accel_b_mps2;
    out[j].omega_bi_b_rps = src.omega_bi_b_rps;
    out[j].dt_s = src.dt_s;
    out[j].bridged = src.bridged;
    if (!propagate(out[j - 1].x, out[j - 1].P, src.accel_b_mps2, src.omega_bi_b_rps, src.dt_s, src.bridged, out[j].x,
                   out[j].P, &repaired)) {
      rec.fused = false;
      return reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
    }
  }
  // Commit.
  for (int k = back, j = 0; k >= 0; --k, ++j) hist_[index_back(k)] = out[j];
  last_fused_t_s_ = at.t_s;
  rec.status = StepStatus::Ok;
  rec.fused = true;
  if (repaired) rec.detail = StepDetail::CovarianceRepaired;
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::make_step(S dt) const -> StepModel {
  StepModel m;
  m.phi = cw_stm(cfg_.n_radps, dt);
  m.gamma = cw_accel_response(cfg_.n_radps, dt);
  m.hill_step = hill_frame_step(cfg_.n_radps, dt);
  m.Q.setZero();
  const S sa2 = cfg_.accel_sigma_mps2 * cfg_.accel_sigma_mps2;
  m.Q.template block<6, 6>(0, 0) = sa2 * (m.gamma * m.gamma.transpose());
  const S sg = cfg_.gyro_sigma_rps * dt;
  m.Q.template block<3, 3>(Layout::kDTheta.index, Layout::kDTheta.index) = (sg * sg) * Mat3<S>::Identity();
  if constexpr (kWithBias) {
    const S qg = cfg_.gyro_bias_walk * cfg_.gyro_bias_walk * dt;
    const S qa = cfg_.accel_bias_walk * cfg_.accel_bias_walk * dt;
    m.Q.template block<3, 3>(Layout::kDGyroBias.index, Layout::kDGyroBias.index) = qg * Mat3<S>::Identity();
    m.Q.template block<3, 3>(Layout::kDAccelBias.index, Layout::kDAccelBias.index) = qa * Mat3<S>::Identity();
  }
  return m;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::dynamics(const State& x, const Vec3<S>& accel_b, const Vec3<S>& omega_b,
                                                     S dt, const StepModel& m) const -> State {
  Vec3<S> w = omega_b;
  Vec3<S> a = accel_b;
  if constexpr (kWithBias) {
    w -= x.gyro_bias_rps;
    a -= x.accel_bias_mps2;
  }
  // Body acceleration at mid-step, into the Hill frame at mid-step.
  const Vec3<S> a_mid_b = a + (S(0.5) * dt) * w.cross(a);
  const Vec3<S> v = x.q_hb._transformVector(a_mid_b);
  const S th = S(0.5) * cfg_.n_radps * dt;  // Hill frame turns by -n dt / 2 about z
  const Vec3<S> a_hill(v.x() + th * v.y(), v.y() - th * v.x(), v.z());
  Vec6<S> rv;
  rv << x.r_hill_m, x.v_hill_mps;
  const Vec6<S> rv1 = m.phi * rv + m.gamma * a_hill;
  State out = x;
  out.r_hill_m = rv1.template head<3>();
  out.v_hill_mps = rv1.template tail<3>();
  out.q_hb = propagate_attitude(x.q_hb, w, dt, m.hill_step);
  return out;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::sigma_offset(const Cov& L, int i) const -> ErrVec {
  if (i == 0) return ErrVec::Zero();
  if (i <= kN) return gamma_ * L.col(i - 1);
  return -gamma_ * L.col(i - 1 - kN);
}

template <typename S, bool kWithBias, int kHistory>
inline void NavUkf<S, kWithBias, kHistory>::sigma_mean(const State* X, State& mean,
                                                       Eigen::Matrix<S, kN, kSigma>& D) const {
  const State& c = X[0];
  ErrVec acc = ErrVec::Zero();
  for (int i = 0; i < kSigma; ++i) acc += wm(i) * X[i].minus(c);
  mean = c.plus(acc);
  for (int i = 0; i < kSigma; ++i) D.col(i) = X[i].minus(mean);
}

template <typename S, bool kWithBias, int kHistory>
inline bool NavUkf<S, kWithBias, kHistory>::propagate(const State& x, const Cov& P, const Vec3<S>& accel_b,
                                                      const Vec3<S>& omega_b, S dt, bool bridged, State& x_out,
                                                      Cov& P_out, bool* repaired) const {
  Cov L;
  const int rep = cholesky_lower_repaired(P, L);
  if (rep < 0) return false;
  if (rep > 0 && repaired != nullptr) *repaired = true;
  const bool nominal = std::abs(dt - dt_nom_) <= S(1e-6) * dt_nom_;
  StepModel other;
  if (!nominal) other = make_step(dt);
  const StepModel& m = nominal ? prop_nom_ : other;
  State X[kSigma];
  for (int i = 0; i < kSigma; ++i) X[i] = dynamics(x.plus(sigma_offset(L, i)), accel_b, omega_b, dt, m);
  State mean;
  Eigen::Matrix<S, kN, kSigma> D;
  sigma_mean(X, mean, D);
  Cov Pn = wc0_ * D.col(0) * D.col(0).transpose();
  Pn.noalias() += wi_ * D.template rightCols<kSigma - 1>() * D.template rightCols<kSigma - 1>().transpose();
  Pn += m.Q;
  if (bridged) {  // the held sample stands in for an unknown one
    const S ga = cfg_.gap_accel_sigma_mps2, gg = cfg_.gap_gyro_sigma_rps * dt;
    Pn.template block<6, 6>(0, 0).noalias() += (ga * ga) * (m.gamma * m.gamma.transpose());
    Pn.template block<3, 3>(Layout::kDTheta.index, Layout::kDTheta.index) += (gg * gg) * Mat3<S>::Identity();
  }
  if (!condition_covariance(Pn, var_min_, var_max_)) return false;
  if (!mean.all_finite() || !Pn.allFinite()) return false;
  x_out = mean;
  P_out = Pn;
  return true;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::fuse(const State& x, const Cov& P, const Vec3<S>& r_meas,
                                                 const Quat<S>& q_meas, const MeasCov& R, Record& rec, State& x_out,
                                                 Cov& P_out) const -> StepStatus {
  Cov L;
  const int rep = cholesky_lower_repaired(P, L);
  if (rep < 0) return set(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  Eigen::Matrix<S, kN, kSigma> DX;
  Vec3<S> r_sig[kSigma];
  Quat<S> q_sig[kSigma];
  for (int i = 0; i < kSigma; ++i) {
    DX.col(i) = sigma_offset(L, i);
    r_sig[i] = x.r_hill_m + DX.col(i).template segment<3>(Layout::kDPos.index);
    q_sig[i] = boxplus(x.q_hb, Vec3<S>(DX.col(i).template segment<3>(Layout::kDTheta.index)));
  }
  // Predicted measurement: weighted mean, attitude in the tangent space
  // around the central point.
  Vec3<S> r_hat = Vec3<S>::Zero();
  Vec3<S> dq = Vec3<S>::Zero();
  for (int i = 0; i < kSigma; ++i) {
    r_hat += wm(i) * r_sig[i];
    dq += wm(i) * boxminus(q_sig[i], q_sig[0]);
  }
  const Quat<S> q_hat = boxplus(q_sig[0], dq);
  Eigen::Matrix<S, kMeas, kSigma> DZ;
  for (int i = 0; i < kSigma; ++i) {
    DZ.col(i).template head<3>() = r_sig[i] - r_hat;
    DZ.col(i).template tail<3>() = boxminus(q_sig[i], q_hat);
  }
  MeasCov Szz = wc0_ * DZ.col(0) * DZ.col(0).transpose();
  Szz.noalias() += wi_ * DZ.template rightCols<kSigma - 1>() * DZ.template rightCols<kSigma - 1>().transpose();
  Szz += R;
  symmetrize(Szz);
  Eigen::Matrix<S, kN, kMeas> Pxz = wc0_ * DX.col(0) * DZ.col(0).transpose();
  Pxz.noalias() += wi_ * DX.template rightCols<kSigma - 1>() * DZ.template rightCols<kSigma - 1>().transpose();
  MeasVec y;
  y.template head<3>() = r_meas - r_hat;
  y.template tail<3>() = boxminus(q_meas, q_hat);
  rec.innovation = y;
  rec.innovation_cov = Szz;
  Eigen::LLT<MeasCov> llt;
  if (!factor(Szz, llt)) return set(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  const MeasVec Siy = llt.solve(y);
  rec.nis = y.dot(Siy);
  const S log_2pi = S(1.8378770664093454836);
  rec.log_likelihood = S(-0.5) * (rec.nis + S(kMeas) * log_2pi + log_det(llt));
  if (cfg_.gate_chi2 > S(0) && !(rec.nis <= cfg_.gate_chi2)) return set(rec, StepStatus::Gated, StepDetail::None);
  // K = Pxz S^-1, via S K^T = Pxz^T.
  const Eigen::Matrix<S, kN, kMeas> K = llt.solve(Pxz.transpose()).transpose();
  const ErrVec dx = K * y;
  Cov Pn = P;
  Pn.noalias() -= K * Szz * K.transpose();
  Cov Ln;
  if (!condition_covariance(Pn, var_min_, var_max_))
    return set(rec, StepStatus::NotPosDef, StepDetail::PosteriorCholesky);
  const int rep_n = cholesky_lower_repaired(Pn, Ln);
  if (rep_n < 0) return set(rec, StepStatus::NotPosDef, StepDetail::PosteriorCholesky);
  const State xn = x.plus(dx);
  if (!xn.all_finite()) return set(rec, StepStatus::NotPosDef, StepDetail::PosteriorCholesky);
  x_out = xn;
  P_out = Pn;
  return set(rec, StepStatus::Ok, (rep > 0 || rep_n > 0) ? StepDetail::CovarianceRepaired : StepDetail::None);
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::set(Record& rec, StepStatus s, StepDetail d) -> StepStatus {
  rec.status = s;
  rec.detail = d;
  rec.fused = false;
  return s;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::reject(Record& rec, StepStatus s, StepDetail d) -> Record {
  set(rec, s, d);
  return rec;
}

template <typename S, bool kWithBias, int kHistory>
inline bool NavUkf<S, kWithBias, kHistory>::pose_input_ok(double t_capture_s, const Vec3<S>& r_hill_m,
                                                          const Quat<S>& q_hb, const MeasCov& R, Record& rec) const {
  StepDetail d = StepDetail::None;
  const double t_now = hist_[head_].t_s;
  if (!initialized_)
    d = StepDetail::NotInitialized;
  else if (!std::isfinite(t_capture_s) || !r_hill_m.allFinite() || !q_hb.coeffs().allFinite() || !R.allFinite())
    d = StepDetail::NonFinite;
  else if (!quat_unit(q_hb))
    d = StepDetail::NonUnitQuaternion;
  else if (t_capture_s > t_now + cfg_.time_tol_s)
    d = StepDetail::FromFuture;
  else if (t_now - t_capture_s > cfg_.max_delay_s + cfg_.time_tol_s)
    d = StepDetail::TooOld;
  if (d == StepDetail::None) return true;
  set(rec, StepStatus::BadInput, d);
  return false;
}

// Compiled once, in fsw_core (instantiate_nav.cpp); users link to it instead
// of compiling the filter again. FSW_IMPLICIT_INSTANTIATION (the fuzzer, which
// instruments the code it runs) compiles it in place.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class NavUkf<double, false>;
extern template class NavUkf<float, false>;
extern template class NavUkf<double, true>;
extern template class NavUkf<float, true>;
#endif

}  // namespace fsw
