// Tightly coupled relative navigation from image features (the dual-quaternion paper on kinematically coupled relative
// dynamics and feature-based pose estimation,
// section 4): the image coordinates of points, line points and circle points
// are fused directly, by an EKF (as in the paper) or a UKF (the paper's stated
// future work). Both share the model below; only the update rule differs.
//
// State (nominal, FeatureNavState):
//   q_lf, w_fl_f, r_l, v_l   relative_dynamics.hpp (follower w.r.t. the leader)
//   phi (3 per circle)       the angles of the three imaged points of each
//                            circle about its twist (the paper's Phi), constant
// Error state (covariance), layout FeatureLayout:
//   [dtheta (3, body), dw (3), dr (3, L), dv (3, L), dphi (3 C)]
// The paper carries an 8-component dual quaternion in the covariance; its
// unit and orthogonality constraints make that covariance singular, so here
// the same pose is carried as q_lf (x) Exp(dtheta) and r + dr: six degrees of
// freedom, and the dual quaternion of the pose is formed for the models
// (feature_models.hpp) at every evaluation.
//
// Predict(t): RK4 over `substeps` sub-steps of the nonlinear dynamics; the
// EKF propagates P with F = prod (I + A h + (A h)^2 / 2) (the paper uses
// I + A T over the whole step), the UKF propagates its sigma points.
// Process noise Q = diag(q_att, q_rate, q_pos, q_vel, q_phi) dt.
//
// Update(z, mask): z stacks [points (2 each), lines (2 each), circles
// (3 points x 2 each)] in fixed slots (kMaxPoints, kMaxLines, kMaxCircles);
// bit k of mask marks slot pair k as measured (points, then lines, then the
// circle points). Unmeasured and unconfigured slots are padded (innovation 0,
// unit variance, no H row) and drop out of NIS and the likelihood.
// R = image_sigma^2 I. The EKF uses the Joseph form; the UKF uses the scaled
// unscented transform with sigma points in the tangent space (its covariance
// update in Joseph form with H = Pxz^T P^-1, for the float build), and halves
// alpha (at most max_alpha_halvings times) when a sigma point would put a
// feature behind the lens, so every sigma point stays in the model's domain;
// with a halved spread the update takes the divided-difference (DD1)
// statistics of the same points (mean at the central point), since the
// scaled weights would then extrapolate with a large negative central weight.
//
// Every step returns a StepRecord; on any status other than Ok the filter is
// left bit-identical. Time is double in both scalar builds.
// Real-time core: fixed-size Eigen, no heap, no exceptions, no I/O, bounded
// loops.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>

#include "fsw/dynamics/relative_dynamics.hpp"
#include "fsw/features/feature_models.hpp"
#include "fsw/math/covariance.hpp"
#include "fsw/math/dual_quaternion.hpp"
#include "fsw/math/so3.hpp"
#include "fsw/math/step_status.hpp"

namespace fsw {

struct FeatureBlock {
  int index;
  int size;
};

template <int kMaxCircles>
struct FeatureLayout {
  static constexpr FeatureBlock kDTheta{0, 3};
  static constexpr FeatureBlock kDRate{3, 3};
  static constexpr FeatureBlock kDPos{6, 3};
  static constexpr FeatureBlock kDVel{9, 3};
  static constexpr FeatureBlock kDPhi{12, 3 * kMaxCircles};
  static constexpr int kErrorSize = 12 + 3 * kMaxCircles;
  static constexpr int kStoredSize = 13 + 3 * kMaxCircles;  // quaternion stored as 4
  static_assert(kDPhi.index + kDPhi.size == kErrorSize, "error layout is contiguous");
  static_assert(kStoredSize == kErrorSize + 1, "one more stored than error component (the quaternion)");
};

template <typename S, int kPhi>
struct FeatureNavState {
  Quat<S> q_lf = Quat<S>::Identity();                                     // follower body -> leader frame
  Vec3<S> w_fl_f_rps = Vec3<S>::Zero();                                   // omega_FL, body frame [rad/s]
  Vec3<S> r_l_m = Vec3<S>::Zero();                                        // follower c.m. in L [m]
  Vec3<S> v_l_mps = Vec3<S>::Zero();                                      // its rate in L [m/s]
  Eigen::Matrix<S, kPhi, 1> phi_rad = Eigen::Matrix<S, kPhi, 1>::Zero();  // circle-point angles [rad]
  bool all_finite() const {
    return q_lf.coeffs().allFinite() && w_fl_f_rps.allFinite() && r_l_m.allFinite() && v_l_mps.allFinite() &&
           phi_rad.allFinite();
  }
  DualQuat<S> pose_lf() const { return DualQuat<S>::from_rotation_translation(q_lf, r_l_m); }
};

// Feature geometry in the leader feature frame lP (feature_models.hpp).
template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
struct FeatureSet {
  int n_points = 0;
  int n_lines = 0;
  int n_circles = 0;
  std::array<Vec3<S>, kMaxPoints> point_lp_m{};           // D
  std::array<Vec3<S>, kMaxLines> line_dir_lp{};           // l (unit)
  std::array<Vec3<S>, kMaxLines> line_moment_lp_m{};      // m = p x l
  std::array<Vec3<S>, kMaxCircles> circle_axis_lp{};      // l_t (unit)
  std::array<Vec3<S>, kMaxCircles> circle_moment_lp_m{};  // m_t = p x l_t
  std::array<Vec3<S>, kMaxCircles> circle_start_lp_m{};   // S0
};

template <typename S>
struct FeatureFilterConfig {
  LeaderOrbit<S> leader;
  Vec3<S> inertia_f_kgm2 = Vec3<S>(S(522), S(420), S(600));  // follower principal inertia (the paper's) [kg m^2]
  CameraMount<S> camera;
  S image_sigma_m = S(1e-5);  // image-plane noise, 1-sigma per coordinate [m]
  int substeps = 10;          // RK4 sub-steps per predict
  double max_dt_s = 10.0;     // longest predict step [s]
  S q_att = S(1e-8);          // process noise densities: attitude [rad^2/s]
  S q_rate = S(1e-8);         // relative rate [(rad/s)^2/s]
  S q_pos = S(1e-4);          // position [m^2/s]
  S q_vel = S(1e-6);          // velocity [(m/s)^2/s]
  S q_phi = S(0);             // circle angles [rad^2/s]
  S gate_chi2 = S(0);         // NIS gate; <= 0 disables
  S alpha = S(0.5);           // UKF sigma-point spread (gamma = 2.1 for 18 states: attitude sigma
                              // points stay inside pi for attitude sigmas up to 1.4 rad)
  S beta = S(2);
  S kappa = S(0);
  int max_alpha_halvings = 6;  // UKF: spread reductions tried when a sigma point is not imageable
  S var_min = S(1e-16);
  S att_var_max_rad2 = S(10);
  S rate_var_max = S(1);
  S pos_var_max_m2 = S(1e8);
  S vel_var_max = S(1e4);
  S phi_var_max_rad2 = S(100);
};

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline const char* feature_config_invalid_field(const FeatureFilterConfig<S>& c,
                                                const FeatureSet<S, kMaxPoints, kMaxLines, kMaxCircles>& fs) {
  auto pos = [](double x) { return std::isfinite(x) && x > 0.0; };
  auto nonneg = [](double x) { return std::isfinite(x) && x >= 0.0; };
  if (!c.leader.valid()) return "leader";
  if (!pos(double(c.inertia_f_kgm2.minCoeff())) || !c.inertia_f_kgm2.allFinite()) return "inertia_f_kgm2";
  if (!pos(double(c.camera.focal_m))) return "camera.focal_m";
  if (!c.camera.camera_offset_f_m.allFinite()) return "camera.camera_offset_f_m";
  if (!c.camera.feature_origin_l_m.allFinite()) return "camera.feature_origin_l_m";
  if (!pos(double(c.camera.min_depth_m))) return "camera.min_depth_m";
  if (!pos(double(c.image_sigma_m))) return "image_sigma_m";
  if (c.substeps < 1 || c.substeps > 1000) return "substeps";
  if (!pos(c.max_dt_s)) return "max_dt_s";
  if (!nonneg(double(c.q_att))) return "q_att";
  if (!nonneg(double(c.q_rate))) return "q_rate";
  if (!nonneg(double(c.q_pos))) return "q_pos";
  if (!nonneg(double(c.q_vel))) return "q_vel";
  if (!nonneg(double(c.q_phi))) return "q_phi";
  if (!std::isfinite(double(c.gate_chi2))) return "gate_chi2";
  if (!pos(double(c.alpha))) return "alpha";
  // beta >= alpha^2: the UKF's innovation covariance is then a sum of outer
  // products with positive weights (FeatureUkf::update), factored from its rows.
  if (!nonneg(double(c.beta)) || double(c.beta) < double(c.alpha) * double(c.alpha)) return "beta";
  if (!std::isfinite(double(c.kappa))) return "kappa";
  if (c.max_alpha_halvings < 0 || c.max_alpha_halvings > 30) return "max_alpha_halvings";
  if (!pos(double(c.var_min))) return "var_min";
  if (!(c.att_var_max_rad2 > c.var_min) || !std::isfinite(double(c.att_var_max_rad2))) return "att_var_max_rad2";
  if (!(c.rate_var_max > c.var_min) || !std::isfinite(double(c.rate_var_max))) return "rate_var_max";
  if (!(c.pos_var_max_m2 > c.var_min) || !std::isfinite(double(c.pos_var_max_m2))) return "pos_var_max_m2";
  if (!(c.vel_var_max > c.var_min) || !std::isfinite(double(c.vel_var_max))) return "vel_var_max";
  if (!(c.phi_var_max_rad2 > c.var_min) || !std::isfinite(double(c.phi_var_max_rad2))) return "phi_var_max_rad2";
  if (fs.n_points < 0 || fs.n_points > kMaxPoints) return "features.n_points";
  if (fs.n_lines < 0 || fs.n_lines > kMaxLines) return "features.n_lines";
  if (fs.n_circles < 0 || fs.n_circles > kMaxCircles) return "features.n_circles";
  for (int i = 0; i < fs.n_points; ++i)
    if (!fs.point_lp_m[i].allFinite()) return "features.point_lp_m";
  for (int i = 0; i < fs.n_lines; ++i) {
    const Vec3<S>& l = fs.line_dir_lp[i];
    const Vec3<S>& m = fs.line_moment_lp_m[i];
    if (!l.allFinite() || !m.allFinite() || std::abs(double(l.norm()) - 1.0) > 1e-3 ||
        std::abs(double(l.dot(m))) > 1e-3 * (1.0 + double(m.norm())))
      return "features.line";
  }
  for (int i = 0; i < fs.n_circles; ++i) {
    const Vec3<S>& l = fs.circle_axis_lp[i];
    const Vec3<S>& m = fs.circle_moment_lp_m[i];
    if (!l.allFinite() || !m.allFinite() || !fs.circle_start_lp_m[i].allFinite() ||
        std::abs(double(l.norm()) - 1.0) > 1e-3 || std::abs(double(l.dot(m))) > 1e-3 * (1.0 + double(m.norm())))
      return "features.circle";
  }
  return nullptr;
}

// The model both filters share: dynamics, error-state algebra, stacked
// measurement, checks. Not used on its own.
template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
class FeatureFilterBase {
 public:
  using Layout = FeatureLayout<kMaxCircles>;
  static constexpr int kN = Layout::kErrorSize;
  static constexpr int kPhi = 3 * kMaxCircles;
  static constexpr int kPairs = kMaxPoints + kMaxLines + 3 * kMaxCircles;
  static constexpr int kMeas = 2 * kPairs;
  static_assert(kPairs >= 1 && kPairs <= 32, "1 to 32 measurement slots (one mask bit each)");

  using State = FeatureNavState<S, kPhi>;
  using Features = FeatureSet<S, kMaxPoints, kMaxLines, kMaxCircles>;
  using Config = FeatureFilterConfig<S>;
  using ErrVec = Eigen::Matrix<S, kN, 1>;
  using Cov = Eigen::Matrix<S, kN, kN>;
  using MeasVec = Eigen::Matrix<S, kMeas, 1>;
  using MeasCov = Eigen::Matrix<S, kMeas, kMeas>;
  using MeasJac = Eigen::Matrix<S, kMeas, kN>;
  using Record = StepRecord<S, kMeas>;

  static constexpr std::uint32_t kAllSlots =
      kPairs >= 32 ? 0xFFFFFFFFu : static_cast<std::uint32_t>((std::uint64_t(1) << kPairs) - 1);

  FeatureFilterBase(const Config& cfg, const Features& fs) : cfg_(cfg), fs_(fs) {
    bad_field_ = feature_config_invalid_field(cfg_, fs_);
    if (bad_field_ != nullptr) return;
    J_ = cfg_.inertia_f_kgm2.asDiagonal();
    J_inv_ = cfg_.inertia_f_kgm2.cwiseInverse().asDiagonal();
    var_min_.setConstant(cfg_.var_min);
    var_max_.template segment<3>(Layout::kDTheta.index).setConstant(cfg_.att_var_max_rad2);
    var_max_.template segment<3>(Layout::kDRate.index).setConstant(cfg_.rate_var_max);
    var_max_.template segment<3>(Layout::kDPos.index).setConstant(cfg_.pos_var_max_m2);
    var_max_.template segment<3>(Layout::kDVel.index).setConstant(cfg_.vel_var_max);
    if constexpr (kPhi > 0) var_max_.template segment<kPhi>(Layout::kDPhi.index).setConstant(cfg_.phi_var_max_rad2);
    q_density_.template segment<3>(Layout::kDTheta.index).setConstant(cfg_.q_att);
    q_density_.template segment<3>(Layout::kDRate.index).setConstant(cfg_.q_rate);
    q_density_.template segment<3>(Layout::kDPos.index).setConstant(cfg_.q_pos);
    q_density_.template segment<3>(Layout::kDVel.index).setConstant(cfg_.q_vel);
    if constexpr (kPhi > 0) q_density_.template segment<kPhi>(Layout::kDPhi.index).setConstant(cfg_.q_phi);
    configured_ = 0;
    for (int i = 0; i < fs_.n_points; ++i) configured_ |= 1u << i;
    for (int i = 0; i < fs_.n_lines; ++i) configured_ |= 1u << (kMaxPoints + i);
    for (int i = 0; i < 3 * fs_.n_circles; ++i) configured_ |= 1u << (kMaxPoints + kMaxLines + i);
  }

  bool config_ok() const { return bad_field_ == nullptr; }
  const char* config_invalid_field() const { return bad_field_; }
  const Config& config() const { return cfg_; }
  const Features& features() const { return fs_; }
  bool initialized() const { return initialized_; }
  const State& state() const { return x_; }
  const Cov& covariance() const { return P_; }
  double t_s() const { return t_; }
  S nu_rad() const { return nu_; }
  DualQuat<S> pose_lf() const { return x_.pose_lf(); }
  std::uint32_t configured_slots() const { return configured_; }

  // Sets the state at t_s, the leader's true anomaly nu0 [rad], and P0.
  Record init(double t_s, S nu0_rad, const State& x0, const Cov& P0);

  // Predicted measurement at the current state (padding slots zero), for
  // the bench's residual plots. False when a configured feature is not imageable.
  bool predict_measurement(MeasVec& z) const;

 protected:
  // ---- error-state algebra -------------------------------------------------
  static State boxplus(const State& x, const ErrVec& d);

  static ErrVec boxminus(const State& a, const State& b);

  // ---- dynamics ------------------------------------------------------------
  static RelVec<S> pack(const State& x, S nu);

  static void unpack(const RelVec<S>& v, State& x, S& nu);

  // Moves x (and nu) over dt; F (optional) gets the error-state transition.
  void propagate(State& x, S& nu, S dt, Cov* F) const;

  // Process noise over dt.
  Cov process_noise(S dt) const;

  // ---- measurement -----------------------------------------------------------
  // Stacked prediction and Jacobian over the slots in `slots` (others zero).
  bool measure(const State& x, MeasVec& z, MeasJac* H, std::uint32_t slots) const;

  static void put(int row, const Vec2<S>& zz, const Mat26<S>* Hp, const Vec2<S>* hphi, int j, MeasVec& z, MeasJac* H);

  // Measurement checks common to both filters; fills the row mask.
  bool check_update(const MeasVec& z, std::uint32_t mask, Record& rec, std::uint32_t& slots,
                    Eigen::Matrix<S, kMeas, 1>& rowmask) const;

  // z - zhat on the used rows, 0 elsewhere (whatever z holds there, NaN included).
  static MeasVec select_rows(const MeasVec& z, const MeasVec& zhat, const Eigen::Matrix<S, kMeas, 1>& rowmask);

  // R with unit padding on unused rows.
  MeasCov meas_cov(const Eigen::Matrix<S, kMeas, 1>& rowmask) const;

  bool check_predict(double t_s, Record& rec) const;

  // NIS and the log-likelihood over the used rows.
  // Ls: lower factor of the innovation covariance.
  static void score(Record& rec, const MeasVec& y, const MeasCov& Ls, int used_rows);

  // The innovation covariance's factor from the rows of its square root
  // (cholesky_from_rows: in float, forming the covariance of a metres-wide
  // prior against micrometre image noise loses its small directions).
  // B's last kMeas rows receive R^1/2 (R diagonal); the rows above hold the
  // prediction's spread, filled by the caller.
  template <int Rows>
  static bool innovation_factor(Eigen::Matrix<S, Rows, kMeas>& B, const MeasCov& R, MeasCov& Ls) {
    B.template bottomRows<kMeas>().setZero();
    B.template bottomRows<kMeas>().diagonal() = R.diagonal().cwiseSqrt();
    return cholesky_from_rows(B, Ls);
  }

  static Record& reject(Record& rec, StepStatus s, StepDetail d);

  // The last part of every predict (EKF and UKF): the propagated state and
  // covariance replace the old ones only if finite and positive; otherwise
  // NotPosDef with the filter untouched.
  Record& commit_predict(Record& rec, double t_s, const State& x, S nu, Cov& P);

  // The last part of every update: the correction dx and the posterior P
  // (Joseph form) are applied only if finite and P factors; otherwise
  // NotPosDef with the filter untouched.
  Record& commit_update(Record& rec, const ErrVec& dx, Cov& P);

  Config cfg_;
  Features fs_;
  const char* bad_field_ = nullptr;
  Mat3<S> J_ = Mat3<S>::Identity();
  Mat3<S> J_inv_ = Mat3<S>::Identity();
  ErrVec var_min_ = ErrVec::Zero();
  ErrVec var_max_ = ErrVec::Zero();
  ErrVec q_density_ = ErrVec::Zero();
  std::uint32_t configured_ = 0;
  bool initialized_ = false;
  State x_;
  Cov P_ = Cov::Identity();
  double t_ = 0.0;
  S nu_ = S(0);
};

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::init(double t_s, S nu0_rad, const State& x0,
                                                                    const Cov& P0) -> Record {
  Record rec;
  rec.t_s = t_s;
  if (!config_ok()) return reject(rec, StepStatus::BadInput, StepDetail::BadConfig);
  if (!std::isfinite(t_s) || !std::isfinite(nu0_rad) || !x0.all_finite() || !P0.allFinite())
    return reject(rec, StepStatus::BadInput, StepDetail::NonFinite);
  if (std::abs(x0.q_lf.norm() - S(1)) > S(1e-3))
    return reject(rec, StepStatus::BadInput, StepDetail::NonUnitQuaternion);
  Cov P = P0;
  Cov L;
  if (!condition_covariance(P, var_min_, var_max_) || !cholesky_lower(P, L))
    return reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  x_ = x0;
  x_.q_lf = normalized(x0.q_lf);
  P_ = P;
  t_ = t_s;
  nu_ = nu0_rad;
  initialized_ = true;
  rec.status = StepStatus::Ok;
  return rec;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
bool FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::predict_measurement(MeasVec& z) const {
  MeasJac H;
  return measure(x_, z, &H, configured_);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::boxplus(const State& x, const ErrVec& d)
    -> State {
  State out;
  out.q_lf = fsw::boxplus(x.q_lf, Vec3<S>(d.template segment<3>(Layout::kDTheta.index)));
  out.w_fl_f_rps = x.w_fl_f_rps + d.template segment<3>(Layout::kDRate.index);
  out.r_l_m = x.r_l_m + d.template segment<3>(Layout::kDPos.index);
  out.v_l_mps = x.v_l_mps + d.template segment<3>(Layout::kDVel.index);
  if constexpr (kPhi > 0) out.phi_rad = x.phi_rad + d.template segment<kPhi>(Layout::kDPhi.index);
  return out;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::boxminus(const State& a, const State& b)
    -> ErrVec {
  ErrVec d;
  d.template segment<3>(Layout::kDTheta.index) = fsw::boxminus(a.q_lf, b.q_lf);
  d.template segment<3>(Layout::kDRate.index) = a.w_fl_f_rps - b.w_fl_f_rps;
  d.template segment<3>(Layout::kDPos.index) = a.r_l_m - b.r_l_m;
  d.template segment<3>(Layout::kDVel.index) = a.v_l_mps - b.v_l_mps;
  if constexpr (kPhi > 0) d.template segment<kPhi>(Layout::kDPhi.index) = a.phi_rad - b.phi_rad;
  return d;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::pack(const State& x, S nu) -> RelVec<S> {
  RelVec<S> v;
  v << x.q_lf.w(), x.q_lf.x(), x.q_lf.y(), x.q_lf.z(), x.w_fl_f_rps, x.r_l_m, x.v_l_mps, nu;
  return v;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline void FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::unpack(const RelVec<S>& v, State& x, S& nu) {
  x.q_lf = Quat<S>(v(0), v(1), v(2), v(3));
  x.w_fl_f_rps = v.template segment<3>(4);
  x.r_l_m = v.template segment<3>(7);
  x.v_l_mps = v.template segment<3>(10);
  nu = v(13);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline void FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::propagate(State& x, S& nu, S dt, Cov* F) const {
  RelVec<S> v = pack(x, nu);
  const S h = dt / S(cfg_.substeps);
  if (F != nullptr) F->setIdentity();
  for (int k = 0; k < cfg_.substeps; ++k) {
    if (F != nullptr) {
      const Mat12<S> Ah = relative_jacobian(v, cfg_.leader, J_, J_inv_) * h;
      const Mat12<S> Phi = Mat12<S>::Identity() + Ah + S(0.5) * Ah * Ah;
      const Eigen::Matrix<S, 12, kN> top = Phi * F->template topRows<12>();
      F->template topRows<12>() = top;
    }
    v = relative_rk4(v, h, cfg_.leader, J_, J_inv_);
  }
  unpack(v, x, nu);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::process_noise(S dt) const -> Cov {
  Cov Q = Cov::Zero();
  Q.diagonal() = q_density_ * dt;
  return Q;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline bool FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::measure(const State& x, MeasVec& z, MeasJac* H,
                                                                              std::uint32_t slots) const {
  z.setZero();
  if (H != nullptr) H->setZero();
  const DualQuat<S> pose = x.pose_lf();
  const CameraMount<S>& cam = cfg_.camera;
  Vec2<S> zz;
  Mat26<S> Hp;
  Vec2<S> hphi;
  Mat26<S>* Hpp = H != nullptr ? &Hp : nullptr;
  for (int i = 0; i < fs_.n_points; ++i) {
    if (!(slots & (1u << i))) continue;
    if (!point_model(pose, cam, fs_.point_lp_m[i], zz, Hpp)) return false;
    put(2 * i, zz, Hpp, nullptr, 0, z, H);
  }
  for (int i = 0; i < fs_.n_lines; ++i) {
    const int slot = kMaxPoints + i;
    if (!(slots & (1u << slot))) continue;
    if (!line_model(pose, cam, fs_.line_dir_lp[i], fs_.line_moment_lp_m[i], zz, Hpp)) return false;
    put(2 * slot, zz, Hpp, nullptr, 0, z, H);
  }
  for (int c = 0; c < fs_.n_circles; ++c) {
    for (int s = 0; s < 3; ++s) {
      const int slot = kMaxPoints + kMaxLines + 3 * c + s;
      if (!(slots & (1u << slot))) continue;
      const int j = 3 * c + s;
      if (!circle_model(pose, cam, fs_.circle_axis_lp[c], fs_.circle_moment_lp_m[c], fs_.circle_start_lp_m[c],
                        x.phi_rad(j), zz, Hpp, H != nullptr ? &hphi : nullptr))
        return false;
      put(2 * slot, zz, Hpp, H != nullptr ? &hphi : nullptr, j, z, H);
    }
  }
  return true;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline void FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::put(int row, const Vec2<S>& zz,
                                                                          const Mat26<S>* Hp, const Vec2<S>* hphi,
                                                                          int j, MeasVec& z, MeasJac* H) {
  z.template segment<2>(row) = zz;
  if (H == nullptr) return;
  H->template block<2, 3>(row, Layout::kDTheta.index) = Hp->template leftCols<3>();
  H->template block<2, 3>(row, Layout::kDPos.index) = Hp->template rightCols<3>();
  if constexpr (kPhi > 0) {
    if (hphi != nullptr) H->template block<2, 1>(row, Layout::kDPhi.index + j) = *hphi;
  }
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline bool FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::check_update(
    const MeasVec& z, std::uint32_t mask, Record& rec, std::uint32_t& slots,
    Eigen::Matrix<S, kMeas, 1>& rowmask) const {
  if (!config_ok()) {
    reject(rec, StepStatus::BadInput, StepDetail::BadConfig);
    return false;
  }
  if (!initialized_) {
    reject(rec, StepStatus::BadInput, StepDetail::NotInitialized);
    return false;
  }
  slots = mask & configured_;
  rowmask.setZero();
  for (int k = 0; k < kPairs; ++k) {
    if (!(slots & (1u << k))) continue;
    if (!std::isfinite(z(2 * k)) || !std::isfinite(z(2 * k + 1))) {
      reject(rec, StepStatus::BadInput, StepDetail::NonFinite);
      return false;
    }
    rowmask(2 * k) = S(1);
    rowmask(2 * k + 1) = S(1);
  }
  return true;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::select_rows(
    const MeasVec& z, const MeasVec& zhat, const Eigen::Matrix<S, kMeas, 1>& rowmask) -> MeasVec {
  MeasVec y = MeasVec::Zero();
  for (int i = 0; i < kMeas; ++i)
    if (rowmask(i) > S(0)) y(i) = z(i) - zhat(i);
  return y;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::meas_cov(
    const Eigen::Matrix<S, kMeas, 1>& rowmask) const -> MeasCov {
  MeasCov R = MeasCov::Zero();
  const S r = cfg_.image_sigma_m * cfg_.image_sigma_m;
  for (int i = 0; i < kMeas; ++i) R(i, i) = rowmask(i) > S(0) ? r : S(1);
  return R;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline bool FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::check_predict(double t_s, Record& rec) const {
  StepDetail why = StepDetail::None;
  if (!config_ok()) {
    why = StepDetail::BadConfig;
  } else if (!initialized_) {
    why = StepDetail::NotInitialized;
  } else if (!std::isfinite(t_s)) {
    why = StepDetail::NonFinite;
  } else if (!(t_s > t_)) {
    why = StepDetail::TimeNotIncreasing;
  } else if (t_s - t_ > cfg_.max_dt_s) {
    why = StepDetail::StepTooLong;
  }
  if (why == StepDetail::None) return true;
  reject(rec, StepStatus::BadInput, why);
  return false;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline void FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::score(Record& rec, const MeasVec& y,
                                                                            const MeasCov& Ls, int used_rows) {
  // Eigen's solveInPlace takes its argument as const and writes through it.
  MeasVec w = y;  // NOLINT(performance-unnecessary-copy-initialization): solved in place below
  Ls.template triangularView<Eigen::Lower>().solveInPlace(w);
  rec.nis = w.squaredNorm();
  const S l2pi = std::log(S(2) * S(3.14159265358979323846));
  // Padding rows add log(2 pi * 1) each to log det(2 pi S); remove them.
  rec.log_likelihood = -(rec.nis + log_det_lower(Ls) + S(kMeas) * l2pi - S(kMeas - used_rows) * l2pi) / S(2);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::reject(Record& rec, StepStatus s, StepDetail d)
    -> Record& {
  rec.status = s;
  rec.detail = d;
  rec.fused = false;
  return rec;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::commit_predict(Record& rec, double t_s,
                                                                                     const State& x, S nu, Cov& P)
    -> Record& {
  if (!x.all_finite() || !condition_covariance(P, var_min_, var_max_))
    return reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  x_ = x;
  nu_ = nu;
  P_ = P;
  t_ = t_s;
  rec.status = StepStatus::Ok;
  return rec;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>::commit_update(Record& rec, const ErrVec& dx,
                                                                                    Cov& P) -> Record& {
  Cov L;
  if (!dx.allFinite() || !condition_covariance(P, var_min_, var_max_) || !cholesky_lower(P, L))
    return reject(rec, StepStatus::NotPosDef, StepDetail::PosteriorCholesky);
  x_ = boxplus(x_, dx);
  P_ = P;
  rec.status = StepStatus::Ok;
  rec.fused = true;
  return rec;
}

// ---------------------------------------------------------------------------
// EKF (the paper's filter, with the error-state covariance).
template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
class FeatureEkf : public FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles> {
  using Base = FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>;

 public:
  using Base::kMeas;
  using Base::kN;
  using typename Base::Config;
  using typename Base::Cov;
  using typename Base::ErrVec;
  using typename Base::Features;
  using typename Base::MeasCov;
  using typename Base::MeasJac;
  using typename Base::MeasVec;
  using typename Base::Record;
  using typename Base::State;

  FeatureEkf(const Config& cfg, const Features& fs) : Base(cfg, fs) {}

  Record predict(double t_s);

  // Fuses the image coordinates z (slots per the header) marked in mask.
  Record update(const MeasVec& z, std::uint32_t mask = Base::kAllSlots);
};

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
auto FeatureEkf<S, kMaxPoints, kMaxLines, kMaxCircles>::predict(double t_s) -> Record {
  Record rec;
  rec.t_s = t_s;
  if (!this->check_predict(t_s, rec)) return rec;
  const S dt = S(t_s - this->t_);
  State x = this->x_;
  S nu = this->nu_;
  Cov F;
  this->propagate(x, nu, dt, &F);
  Cov P = F * this->P_ * F.transpose() + this->process_noise(dt);
  return this->commit_predict(rec, t_s, x, nu, P);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
auto FeatureEkf<S, kMaxPoints, kMaxLines, kMaxCircles>::update(const MeasVec& z, std::uint32_t mask) -> Record {
  Record rec;
  rec.t_s = this->t_;
  std::uint32_t slots = 0;
  Eigen::Matrix<S, kMeas, 1> rowmask;
  if (!this->check_update(z, mask, rec, slots, rowmask)) return rec;
  MeasVec zhat;
  MeasJac H;
  if (!this->measure(this->x_, zhat, &H, slots))
    return Base::reject(rec, StepStatus::BadInput, StepDetail::FeatureNotImageable);
  const MeasVec y = Base::select_rows(z, zhat, rowmask);
  const MeasCov R = this->meas_cov(rowmask);
  MeasCov Sm = H * this->P_ * H.transpose() + R;
  symmetrize(Sm);
  rec.innovation = y;
  rec.innovation_cov = Sm;
  Cov Lp;
  if (!cholesky_lower(this->P_, Lp)) return Base::reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  // S = (H Lp)(H Lp)^T + R, factored from its rows [(H Lp)^T; R^1/2].
  Eigen::Matrix<S, kN + kMeas, kMeas> B;
  B.template topRows<kN>() = (H * Lp).transpose();
  MeasCov Ls;
  if (!Base::innovation_factor(B, R, Ls))
    return Base::reject(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  Base::score(rec, y, Ls, int(rowmask.sum()));
  if (this->cfg_.gate_chi2 > S(0) && rec.nis > this->cfg_.gate_chi2)
    return Base::reject(rec, StepStatus::Gated, StepDetail::None);
  // K = P H^T S^-1, from S K^T = H P.
  Eigen::Matrix<S, kMeas, kN> Kt = H * this->P_;
  solve_lower_llt(Ls, Kt);
  const Eigen::Matrix<S, kN, kMeas> K = Kt.transpose();
  const ErrVec dx = K * y;
  const Cov IKH = Cov::Identity() - K * H;
  Cov P = IKH * this->P_ * IKH.transpose() + K * R * K.transpose();
  return this->commit_update(rec, dx, P);
}

// ---------------------------------------------------------------------------
// UKF (scaled unscented transform in the tangent space).
template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
class FeatureUkf : public FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles> {
  using Base = FeatureFilterBase<S, kMaxPoints, kMaxLines, kMaxCircles>;

 public:
  using Base::kMeas;
  using Base::kN;
  using typename Base::Config;
  using typename Base::Cov;
  using typename Base::ErrVec;
  using typename Base::Features;
  using typename Base::MeasCov;
  using typename Base::MeasJac;
  using typename Base::MeasVec;
  using typename Base::Record;
  using typename Base::State;
  static constexpr int kSigma = 2 * kN + 1;

  FeatureUkf(const Config& cfg, const Features& fs) : Base(cfg, fs) {}

  // Spread used by the last update (alpha after any halvings).
  S last_alpha() const { return last_alpha_; }

  Record predict(double t_s);

  Record update(const MeasVec& z, std::uint32_t mask = Base::kAllSlots);

 private:
  struct Weights {
    S gamma = S(1), wm0 = S(0), wc0 = S(0), wi = S(0);
  };

  Weights weights(S alpha) const;

  std::array<State, kSigma> sig_{};
  Eigen::Matrix<S, kMeas, kSigma> Z_ = Eigen::Matrix<S, kMeas, kSigma>::Zero();
  S last_alpha_ = S(1);
};

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
auto FeatureUkf<S, kMaxPoints, kMaxLines, kMaxCircles>::predict(double t_s) -> Record {
  Record rec;
  rec.t_s = t_s;
  if (!this->check_predict(t_s, rec)) return rec;
  const S dt = S(t_s - this->t_);
  Weights w = weights(this->cfg_.alpha);
  Cov L;
  if (!cholesky_lower(this->P_, L)) return Base::reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  // Propagate the central point, then each sigma point.
  State x0 = this->x_;
  S nu0 = this->nu_;
  this->propagate(x0, nu0, dt, nullptr);
  for (int i = 0; i < kN; ++i) {
    for (int sgn = 0; sgn < 2; ++sgn) {
      const ErrVec d = (sgn == 0 ? w.gamma : -w.gamma) * L.col(i);
      State xi = Base::boxplus(this->x_, d);
      S nui = this->nu_;
      this->propagate(xi, nui, dt, nullptr);
      sig_[1 + 2 * i + sgn] = xi;
    }
  }
  sig_[0] = x0;
  // Mean in the tangent space of the propagated central point.
  ErrVec mean_d = ErrVec::Zero();
  for (int k = 1; k < kSigma; ++k) mean_d += w.wi * Base::boxminus(sig_[k], x0);
  const State xm = Base::boxplus(x0, mean_d);
  Cov P = this->process_noise(dt);
  for (int k = 0; k < kSigma; ++k) {
    const ErrVec d = Base::boxminus(sig_[k], xm);
    P += (k == 0 ? w.wc0 : w.wi) * d * d.transpose();
  }
  return this->commit_predict(rec, t_s, xm, nu0, P);
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
auto FeatureUkf<S, kMaxPoints, kMaxLines, kMaxCircles>::update(const MeasVec& z, std::uint32_t mask) -> Record {
  Record rec;
  rec.t_s = this->t_;
  std::uint32_t slots = 0;
  Eigen::Matrix<S, kMeas, 1> rowmask;
  if (!this->check_update(z, mask, rec, slots, rowmask)) return rec;
  Cov L;
  if (!cholesky_lower(this->P_, L)) return Base::reject(rec, StepStatus::NotPosDef, StepDetail::PriorCholesky);
  Weights w;
  bool all_imageable = false;
  S alpha = this->cfg_.alpha;
  for (int h = 0; h <= this->cfg_.max_alpha_halvings && !all_imageable; ++h) {
    w = weights(alpha);
    MeasVec zk;
    all_imageable = this->measure(this->x_, zk, nullptr, slots);
    Z_.col(0) = zk;
    for (int i = 0; i < kN && all_imageable; ++i) {
      for (int sgn = 0; sgn < 2 && all_imageable; ++sgn) {
        const ErrVec d = (sgn == 0 ? w.gamma : -w.gamma) * L.col(i);
        all_imageable = this->measure(Base::boxplus(this->x_, d), zk, nullptr, slots);
        Z_.col(1 + 2 * i + sgn) = zk;
      }
    }
    if (!all_imageable) alpha *= S(0.5);
  }
  if (!all_imageable) return Base::reject(rec, StepStatus::BadInput, StepDetail::FeatureNotImageable);
  const MeasCov R = this->meas_cov(rowmask);
  MeasCov Sm = R;
  Eigen::Matrix<S, kN, kMeas> Pxz = Eigen::Matrix<S, kN, kMeas>::Zero();
  // Rows of the innovation covariance's square root: the weighted sigma
  // point spreads, then R^1/2 (innovation_factor).
  Eigen::Matrix<S, kSigma + kMeas, kMeas> B = Eigen::Matrix<S, kSigma + kMeas, kMeas>::Zero();
  MeasVec zm;
  if (alpha == this->cfg_.alpha) {
    // The scaled statistics written about the central point: with
    // d_k = z_k - z_0 (d_0 = 0) and the mean offset dm = sum_k wi d_k,
    //   zm  = z_0 + dm,
    //   Pzz = sum_k wi d_k d_k^T + (beta - alpha^2) dm dm^T,
    //   Pxz = sum_k wi e_k d_k^T          (e_k = +-gamma L_i, sum wi e_k = 0),
    // equal in exact arithmetic to the textbook sums with the central
    // weights wm0 and wc0 (negative for alpha < 1), but every weight is
    // positive: no cancellation against a large negative central term,
    // which in float left the innovation covariance of a prior of more
    // than a few decimetres indefinite.
    MeasVec dm = MeasVec::Zero();
    for (int k = 1; k < kSigma; ++k) {
      Z_.col(k) -= Z_.col(0);
      dm += w.wi * Z_.col(k);
    }
    zm = Z_.col(0) + dm;
    const S swi = std::sqrt(w.wi);
    for (int i = 0; i < kN; ++i) {
      for (int sgn = 0; sgn < 2; ++sgn) {
        const auto dz = Z_.col(1 + 2 * i + sgn);
        const ErrVec d = (sgn == 0 ? w.gamma : -w.gamma) * L.col(i);
        Sm += w.wi * dz * dz.transpose();
        Pxz += w.wi * d * dz.transpose();
        B.row(2 * i + sgn) = swi * dz.transpose();
      }
    }
    const S c = this->cfg_.beta - alpha * alpha;  // >= 0 (config)
    Sm += c * dm * dm.transpose();
    B.row(2 * kN) = std::sqrt(c) * dm.transpose();
  } else {
    // Spread reduced: the scaled weights would extrapolate the mean with a
    // large negative central weight; use the divided-difference (DD1)
    // statistics of the same points instead (mean at the central point,
    // covariances from the central differences over the step gamma).
    zm = Z_.col(0);
    for (int i = 0; i < kN; ++i) {
      const MeasVec dd = (Z_.col(1 + 2 * i) - Z_.col(2 + 2 * i)) / (S(2) * w.gamma);
      Sm += dd * dd.transpose();
      Pxz += L.col(i) * dd.transpose();
      B.row(i) = dd.transpose();
    }
  }
  symmetrize(Sm);
  const MeasVec y = Base::select_rows(z, zm, rowmask);
  rec.innovation = y;
  rec.innovation_cov = Sm;
  MeasCov Ls;
  if (!Base::innovation_factor(B, R, Ls))
    return Base::reject(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  Base::score(rec, y, Ls, int(rowmask.sum()));
  if (this->cfg_.gate_chi2 > S(0) && rec.nis > this->cfg_.gate_chi2)
    return Base::reject(rec, StepStatus::Gated, StepDetail::None);
  Eigen::Matrix<S, kMeas, kN> Kt = Pxz.transpose();
  solve_lower_llt(Ls, Kt);
  const Eigen::Matrix<S, kN, kMeas> K = Kt.transpose();
  const ErrVec dx = K * y;
  // Joseph form with the statistically linearised H = Pxz^T P^-1 (equal to
  // P - K S K^T in exact arithmetic, but keeps P positive definite in float).
  Eigen::Matrix<S, kN, kMeas> PinvPxz = L.template triangularView<Eigen::Lower>().solve(Pxz);
  L.transpose().template triangularView<Eigen::Upper>().solveInPlace(PinvPxz);
  const MeasJac Hs = PinvPxz.transpose();
  const Cov IKH = Cov::Identity() - K * Hs;
  Cov P = IKH * this->P_ * IKH.transpose() + K * R * K.transpose();
  if (this->commit_update(rec, dx, P).ok()) last_alpha_ = alpha;
  return rec;
}

template <typename S, int kMaxPoints, int kMaxLines, int kMaxCircles>
inline auto FeatureUkf<S, kMaxPoints, kMaxLines, kMaxCircles>::weights(S alpha) const -> Weights {
  const S n = S(kN);
  const S lambda = alpha * alpha * (n + this->cfg_.kappa) - n;
  Weights w;
  w.gamma = std::sqrt(n + lambda);
  w.wm0 = lambda / (n + lambda);
  w.wc0 = w.wm0 + S(1) - alpha * alpha + this->cfg_.beta;
  w.wi = S(1) / (S(2) * (n + lambda));
  return w;
}

// Compiled once, in fsw_core (instantiate_features.cpp); see nav_ukf.hpp.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class FeatureFilterBase<double, 4, 4, 2>;
extern template class FeatureFilterBase<float, 4, 4, 2>;
extern template class FeatureEkf<double, 4, 4, 2>;
extern template class FeatureEkf<float, 4, 4, 2>;
extern template class FeatureUkf<double, 4, 4, 2>;
extern template class FeatureUkf<float, 4, 4, 2>;
#endif

}  // namespace fsw
