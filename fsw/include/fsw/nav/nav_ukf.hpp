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
// Only where the model is nonlinear are sigma points propagated. The square
// root of P is taken with the nonlinear states first (attitude, and the
// biases with the bias option) and r, v last: L = chol(Pi P Pi^T). Its last
// six columns then move r and v only, along which the step is linear
// (Phi), so their 12 sigma points are known without propagating them: they
// add nothing to the mean (they cancel in pairs) and exactly
// (2 Wi gamma^2 = 1) Phi L_rv L_rv^T Phi^T plus 12 Wi d0 d0^T (d0: the centre's
// deviation from the mean) to the covariance. The 2 m + 1 others (m = 3, or
// 9 with biases) go through the dynamics. The result is the 2n + 1 point
// transform with this square root, to rounding. Without the bias option
// the sample's turn Exp(omega dt) and mid-step acceleration do not depend on
// the state and are computed once per step; each pair x [+] d, x [+] -d
// shares Exp(d_theta).
// The pose measurement [r, q] is linear in the tangent space: with the
// sigma points x [+] d_i, the predicted mean is the centre and the
// deviations are H d_i (H selects dr and dtheta; boxminus(q [+] d, q) = d),
// so the transform's S = H P H^T + R and P_xz = P H^T exactly; the update
// computes them so, without sigma points.
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
  static constexpr int kLin = 6;         // r, v: the step is linear in them
  static constexpr int kNl = kN - kLin;  // attitude (and biases): propagated by sigma points
  static constexpr int kSigmaNl = 2 * kNl + 1;
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

  // What the IMU sample does over a step, from the (bias-corrected) sample:
  // the body acceleration at mid-step and the body's turn Exp(omega dt).
  struct StepInput {
    Vec3<S> a_mid_b;
    Quat<S> turn;
    S dt{0};
  };
  static StepInput step_input(const Vec3<S>& accel_b, const Vec3<S>& omega_b, S dt);
  // The sample as the state sees it: without the bias option the same for
  // every sigma point (computed once), else corrected by its biases.
  StepInput input_for(const State& x, const Vec3<S>& accel_b, const Vec3<S>& omega_b, S dt,
                      const StepInput& shared) const;

  // One sigma point through the dynamics.
  State dynamics(const State& x, const StepInput& in, const StepModel& m) const;

  // P with the nonlinear states first (file comment), and back.
  static void nonlinear_first(const Cov& P, Cov& Pp);
  // Column j of a square root in that order, as an error-state vector.
  static ErrVec column_in_state_order(const Cov& L, int j);

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
  const Quat<S> q_meas = normalized(q_hb);
  const StepStatus st = fuse(at.x, at.P, r_hill_m, q_meas, R, rec, out[0].x, out[0].P);
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
inline auto NavUkf<S, kWithBias, kHistory>::step_input(const Vec3<S>& a, const Vec3<S>& w, S dt) -> StepInput {
  StepInput in;
  in.a_mid_b = a + (S(0.5) * dt) * w.cross(a);  // body acceleration at mid-step
  in.turn = exp(Vec3<S>(w * dt));
  in.dt = dt;
  return in;
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::input_for(const State& x, const Vec3<S>& accel_b, const Vec3<S>& omega_b,
                                                      S dt, const StepInput& shared) const -> StepInput {
  if constexpr (kWithBias) {
    return step_input(accel_b - x.accel_bias_mps2, omega_b - x.gyro_bias_rps, dt);
  } else {
    (void)x;
    (void)accel_b;
    (void)omega_b;
    (void)dt;
    return shared;
  }
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::dynamics(const State& x, const StepInput& in, const StepModel& m) const
    -> State {
  // Body acceleration at mid-step, into the Hill frame at mid-step.
  const Vec3<S> v = x.q_hb._transformVector(in.a_mid_b);
  const S th = S(0.5) * cfg_.n_radps * in.dt;  // Hill frame turns by -n dt / 2 about z
  const Vec3<S> a_hill(v.x() + th * v.y(), v.y() - th * v.x(), v.z());
  Vec6<S> rv;
  rv << x.r_hill_m, x.v_hill_mps;
  const Vec6<S> rv1 = m.phi * rv + m.gamma * a_hill;
  State out = x;
  out.r_hill_m = rv1.template head<3>();
  out.v_hill_mps = rv1.template tail<3>();
  out.q_hb = normalized(Quat<S>(m.hill_step * x.q_hb * in.turn));  // propagate_attitude, the turn computed once
  return out;
}

template <typename S, bool kWithBias, int kHistory>
inline void NavUkf<S, kWithBias, kHistory>::nonlinear_first(const Cov& P, Cov& Pp) {
  Pp.template topLeftCorner<kNl, kNl>() = P.template bottomRightCorner<kNl, kNl>();
  Pp.template topRightCorner<kNl, kLin>() = P.template bottomLeftCorner<kNl, kLin>();
  Pp.template bottomLeftCorner<kLin, kNl>() = P.template topRightCorner<kLin, kNl>();
  Pp.template bottomRightCorner<kLin, kLin>() = P.template topLeftCorner<kLin, kLin>();
}

template <typename S, bool kWithBias, int kHistory>
inline auto NavUkf<S, kWithBias, kHistory>::column_in_state_order(const Cov& L, int j) -> ErrVec {
  ErrVec d;
  d.template head<kLin>() = L.col(j).template tail<kLin>();
  d.template tail<kNl>() = L.col(j).template head<kNl>();
  return d;
}

template <typename S, bool kWithBias, int kHistory>
inline bool NavUkf<S, kWithBias, kHistory>::propagate(const State& x, const Cov& P, const Vec3<S>& accel_b,
                                                      const Vec3<S>& omega_b, S dt, bool bridged, State& x_out,
                                                      Cov& P_out, bool* repaired) const {
  Cov Pp;
  nonlinear_first(P, Pp);
  Cov L;
  const int rep = cholesky_lower_repaired(Pp, L);
  if (rep < 0) return false;
  if (rep > 0 && repaired != nullptr) *repaired = true;
  const bool nominal = std::abs(dt - dt_nom_) <= S(1e-6) * dt_nom_;
  StepModel other;
  if (!nominal) other = make_step(dt);
  const StepModel& m = nominal ? prop_nom_ : other;
  // The centre and the 2 kNl points along the nonlinear columns: x [+] d and
  // x [+] -d share Exp(d_theta) (Exp(-v) = Exp(v)^-1).
  const StepInput shared = step_input(accel_b, omega_b, dt);
  State X[kSigmaNl];
  X[0] = dynamics(x, input_for(x, accel_b, omega_b, dt, shared), m);
  for (int j = 0; j < kNl; ++j) {
    const ErrVec d = gamma_ * column_in_state_order(L, j);
    const Quat<S> e = exp(Vec3<S>(d.template segment<3>(Layout::kDTheta.index)));
    State xp = x.plus_vectors(d), xm = x.plus_vectors(-d);
    xp.q_hb = normalized(Quat<S>(x.q_hb * e));  // boxplus(q, d_theta)
    xm.q_hb = normalized(Quat<S>(x.q_hb * e.conjugate()));
    X[1 + j] = dynamics(xp, input_for(xp, accel_b, omega_b, dt, shared), m);
    X[1 + kNl + j] = dynamics(xm, input_for(xm, accel_b, omega_b, dt, shared), m);
  }
  // Tangent-space mean around the centre; the linear columns' points cancel in pairs.
  ErrVec acc = ErrVec::Zero();
  for (int i = 1; i < kSigmaNl; ++i) acc += X[i].minus(X[0]);
  const State mean = X[0].plus(wi_ * acc);
  const ErrVec d0 = X[0].minus(mean);
  Eigen::Matrix<S, kN, kSigmaNl - 1> D;
  for (int i = 1; i < kSigmaNl; ++i) D.col(i - 1) = X[i].minus(mean);
  Cov Pn = (wc0_ + S(2 * kLin) * wi_) * d0 * d0.transpose();
  Pn.noalias() += wi_ * D * D.transpose();
  // The linear columns: Phi L_rv L_rv^T Phi^T on r, v.
  const Mat6<S> PhiL = (S(2) * wi_ * gamma_ * gamma_) * m.phi *
                       L.template bottomRightCorner<kLin, kLin>().template triangularView<Eigen::Lower>();
  Pn.template topLeftCorner<kLin, kLin>().noalias() += PhiL * PhiL.transpose();
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
  // The transform's covariance is L L^T: P itself unless the factor needed a jitter.
  Cov Pj;
  if (rep > 0) Pj.noalias() = L * L.transpose();
  const Cov& Pt = rep > 0 ? Pj : P;
  constexpr int ip = Layout::kDPos.index, ia = Layout::kDTheta.index;
  Eigen::Matrix<S, kN, kMeas> Pxz;  // P H^T
  Pxz.template leftCols<3>() = Pt.template middleCols<3>(ip);
  Pxz.template rightCols<3>() = Pt.template middleCols<3>(ia);
  MeasCov Szz;
  Szz.template topRows<3>() = Pxz.template middleRows<3>(ip);
  Szz.template bottomRows<3>() = Pxz.template middleRows<3>(ia);
  Szz += R;
  symmetrize(Szz);
  MeasVec y;
  y.template head<3>() = r_meas - x.r_hill_m;
  y.template tail<3>() = boxminus(q_meas, x.q_hb);
  rec.innovation = y;
  rec.innovation_cov = Szz;
  Eigen::LLT<MeasCov> llt;
  if (!factor(Szz, llt)) return set(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  const MeasVec Siy = llt.solve(y);
  rec.nis = y.dot(Siy);
  const S log_2pi = S(1.8378770664093454836);
  rec.log_likelihood = S(-0.5) * (rec.nis + S(kMeas) * log_2pi + log_det(llt));
  if (cfg_.gate_chi2 > S(0) && !(rec.nis <= cfg_.gate_chi2)) return set(rec, StepStatus::Gated, StepDetail::None);
  // K = Pxz S^-1, via S K^T = Pxz^T; K S K^T = K Pxz^T.
  const Eigen::Matrix<S, kN, kMeas> K = llt.solve(Pxz.transpose()).transpose();
  const ErrVec dx = Pxz * Siy;  // K y
  Cov Pn = P;
  Pn.noalias() -= K * Pxz.transpose();
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
