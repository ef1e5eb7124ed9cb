// Unscented Kalman filters over the modal state of a vibrating structure
// (section IV, eqs. 5-7, of
// "Shape, Motion, and Parameter Estimation of Large Flexible Space
// Structures using Range Images" (Lichter and Dubowsky)).
//
// State per mode i: [A_i, V_i, omega_i, alpha_i] (amplitude [-], its rate
// [1/s], natural frequency [rad/s], damping rate [1/s]). Process model eq. 5,
// the exact one-step map of a decaying sinusoid, written with
// sin(D w) / w = D sinc(D w) so it stays finite for any sigma point (w <= 0
// included). Measurement: the coarse estimate A~ from the modal decomposition
// (eq. 3) with covariance from eq. 4; it is linear in the state, so the
// update is the exact Kalman update and needs no sigma points. Initial state
// eq. 7: [A~(0), 0, omega_exp, alpha_exp] with the amplitude covariance from
// eq. 4 and configured 1-sigma values for the rest.
//
// Two filters, same interface:
//
//  ModalUkfBank<S, M>: M decoupled 4-state filters. Each mode sees only its
//    own coarse amplitude with the diagonal variance cov_a(i, i); the
//    cross-mode correlation of the decomposition noise (off-diagonal of
//    eq. 4) is dropped. Cost per image O(M) (9 sigma points per mode), memory
//    O(M). Exact when M_Y is diagonal (dense uniform sampling, modes
//    orthogonal on Y); with partial views the coarse errors of different modes
//    are correlated and the bank over-weights them: its variances are
//    then optimistic and its estimates noisier than the joint filter's.
//
//  ModalUkfJoint<S, M>: one 4M-state filter with 8M + 1 sigma points and the
//    exact coupled measurement covariance cov_a (M x M). Statistically exact
//    for the linear-Gaussian measurement; cost per image O(M^3) (Cholesky of
//    the 4M covariance, 8M + 1 sigma points, a symmetric rank-(8M) update),
//    memory O(M^2): about 1.5 MB for M = 50 in double. Its matrices are
//    members (never stack temporaries), so construct it once, statically or
//    at start-up; the step itself never allocates. Eigen's product kernels
//    take at most about 100 KB of stack for packing buffers (M = 50, double).
//
// predict() and update() return a StepStatus and leave the filter state
// bit-identical on any status other than Ok. An image whose decomposition
// failed (too few points, ill-conditioned) gives BadInput and no update;
// step() = predict + update, so with such an image time still advances (the
// state is predicted over dt) and nothing is fused.
// Real-time core: fixed-size Eigen only, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <cstdint>

#include "fsw/math/step_status.hpp"
#include "fsw/modal/modal_decomposition.hpp"

namespace fsw {

namespace modal_detail {

// sin(x) / x
template <typename S>
inline S sinc(S x) {
  if (std::abs(x) < S(1e-3)) return S(1) - x * x / S(6);
  return std::sin(x) / x;
}

// Eq. 5 for one mode: out = f(in) over dt [s]. in/out may alias.
template <typename S>
inline void propagate_mode(const S* in, S* out, S dt) {
  const S a = in[0], v = in[1], w = in[2], al = in[3];
  const S e = std::exp(-dt * al);
  const S c = std::cos(dt * w);
  const S s_over_w = dt * sinc(dt * w);  // sin(dt w) / w
  out[0] = e * (a * c + (v + al * a) * s_over_w);
  out[1] = e * (v * c - (al * v + (w * w + al * al) * a) * s_over_w);
  out[2] = w;
  out[3] = al;
}

// Aligned storage for a fixed-size matrix too large for Eigen's
// stack-allocation limit; used through a fixed-size Map.
template <typename S, int R, int C>
struct Store {
  alignas(64) S v[R * C];
  using Map = Eigen::Map<Eigen::Matrix<S, R, C>, Eigen::AlignedMax>;
  Map m() { return Map(v); }
  Eigen::Map<const Eigen::Matrix<S, R, C>, Eigen::AlignedMax> m() const {
    return Eigen::Map<const Eigen::Matrix<S, R, C>, Eigen::AlignedMax>(v);
  }
};

// Largest divisor of n not above cap (chunk width for blocked products).
constexpr int chunk_width(int n, int cap) {
  int best = 1;
  for (int d = 1; d <= cap && d <= n; ++d)
    if (n % d == 0) best = d;
  return best;
}

}  // namespace modal_detail

// Per-mode a priori knowledge (eq. 7) and process noise (eq. 6).
template <typename S>
struct ModalModeConfig {
  S omega_radps = S(1);  // expected natural frequency omega_exp [rad/s]
  S alpha_ps = S(0);     // expected damping rate alpha_exp [1/s]
  S sigma_v0_ps = S(1);  // initial 1-sigma of the amplitude rate V [1/s]
  S sigma_omega0_radps = S(0.1);
  S sigma_alpha0_ps = S(0.05);
  // Process noise densities: Q = diag(q_a, q_v, q_omega, q_alpha) * dt.
  S q_a = S(0);      // [1/s]
  S q_v = S(0);      // [1/s^3]
  S q_omega = S(0);  // [rad^2/s^3]
  S q_alpha = S(0);  // [1/s^3]
};

// Scaled unscented transform: lambda = a^2 (N + kappa) - N.
template <typename S>
struct UtParams {
  S alpha = S(1);
  S beta = S(2);
  S kappa = S(0);
};

template <typename S, int M>
struct ModalFilterConfig {
  ModalModeConfig<S> mode[M];
  UtParams<S> ut;
  // Chi-square gate on the normalised innovation squared (0: no gate).
  // Bank: per mode (1 dof); joint: on the M-dof NIS.
  S gate_nis = S(0);
};

// What one step did.
template <typename S, int M>
struct ModalStepRecord {
  StepStatus status = StepStatus::BadInput;
  StepDetail detail = StepDetail::None;
  ModalStatus decomposition = ModalStatus::Ok;  // status of the image's decomposition
  bool fused = false;
  Eigen::Matrix<S, M, 1> innovation = Eigen::Matrix<S, M, 1>::Zero();      // A~ - A_pred
  Eigen::Matrix<S, M, 1> innovation_var = Eigen::Matrix<S, M, 1>::Zero();  // diag of its covariance
  S nis = S(0);     // joint: nu^T S^-1 nu; bank: sum of the per-mode NIS
  int n_gated = 0;  // bank: modes rejected by the gate
  bool ok() const { return status == StepStatus::Ok; }
};

template <typename S>
struct UtWeights {
  S wm0, wc0, wi, gamma;
  static UtWeights make(int n, const UtParams<S>& p) {
    const S lambda = p.alpha * p.alpha * (S(n) + p.kappa) - S(n);
    UtWeights w{};
    w.wm0 = lambda / (S(n) + lambda);
    w.wc0 = w.wm0 + S(1) - p.alpha * p.alpha + p.beta;
    w.wi = S(1) / (S(2) * (S(n) + lambda));
    w.gamma = std::sqrt(S(n) + lambda);
    return w;
  }
};

// One mode, 4 states, 9 sigma points.
template <typename S>
class ModeUkf {
 public:
  using Vec4 = Eigen::Matrix<S, 4, 1>;
  using Mat4 = Eigen::Matrix<S, 4, 4>;

  // Eq. 7.
  void init(S a0, S var_a0, const ModalModeConfig<S>& cfg);

  // Unscented predict over dt into (x_out, P_out); the filter is unchanged.
  bool predict_into(S dt, const UtWeights<S>& w, Vec4& x_out, Mat4& P_out) const;

  void set(const Vec4& x, const Mat4& P);

  // Exact update with the scalar measurement A~ of variance r. Returns the NIS
  // through nis; does nothing and returns false if the innovation variance is
  // not positive or the gate (if > 0) rejects it.
  enum class Update { Fused, Gated, NotPosDef };
  Update update(S a_meas, S r, S gate_nis, S& innov, S& innov_var, S& nis);

  const Vec4& state() const { return x_; }
  const Mat4& cov() const { return P_; }

 private:
  Vec4 x_ = Vec4::Zero();
  Mat4 P_ = Mat4::Identity();
  Vec4 q_ = Vec4::Zero();
};

// ModeUkf's members stay inline (as in the class body): the bank calls them
// per mode inside its loops.
template <typename S>
inline void ModeUkf<S>::init(S a0, S var_a0, const ModalModeConfig<S>& cfg) {
  x_ << a0, S(0), cfg.omega_radps, cfg.alpha_ps;
  P_.setZero();
  P_(0, 0) = var_a0;
  P_(1, 1) = cfg.sigma_v0_ps * cfg.sigma_v0_ps;
  P_(2, 2) = cfg.sigma_omega0_radps * cfg.sigma_omega0_radps;
  P_(3, 3) = cfg.sigma_alpha0_ps * cfg.sigma_alpha0_ps;
  q_ << cfg.q_a, cfg.q_v, cfg.q_omega, cfg.q_alpha;
}

template <typename S>
inline bool ModeUkf<S>::predict_into(S dt, const UtWeights<S>& w, Vec4& x_out, Mat4& P_out) const {
  Eigen::LLT<Mat4> llt(P_);
  if (llt.info() != Eigen::Success) return false;
  const Mat4 Lg = w.gamma * llt.matrixL().toDenseMatrix();
  Eigen::Matrix<S, 4, 9> X;
  X.col(0) = x_;
  for (int j = 0; j < 4; ++j) {
    X.col(1 + j) = x_ + Lg.col(j);
    X.col(5 + j) = x_ - Lg.col(j);
  }
  for (int k = 0; k < 9; ++k) modal_detail::propagate_mode(X.col(k).data(), X.col(k).data(), dt);
  x_out = w.wm0 * X.col(0);
  for (int k = 1; k < 9; ++k) x_out += w.wi * X.col(k);
  for (int k = 0; k < 9; ++k) X.col(k) -= x_out;
  P_out.noalias() = w.wc0 * X.col(0) * X.col(0).transpose();
  for (int k = 1; k < 9; ++k) P_out.noalias() += w.wi * X.col(k) * X.col(k).transpose();
  P_out.diagonal() += q_ * dt;
  P_out = S(0.5) * (P_out + P_out.transpose()).eval();
  return x_out.allFinite() && P_out.allFinite();
}

template <typename S>
inline void ModeUkf<S>::set(const Vec4& x, const Mat4& P) {
  x_ = x;
  P_ = P;
}

template <typename S>
inline auto ModeUkf<S>::update(S a_meas, S r, S gate_nis, S& innov, S& innov_var, S& nis) -> Update {
  innov = a_meas - x_(0);
  innov_var = P_(0, 0) + r;
  if (!(innov_var > S(0)) || !std::isfinite(innov_var)) return Update::NotPosDef;
  nis = innov * innov / innov_var;
  if (gate_nis > S(0) && nis > gate_nis) return Update::Gated;
  const Vec4 k = P_.col(0) / innov_var;
  const Vec4 pc0 = P_.col(0);
  x_ += k * innov;
  P_.noalias() -= k * pc0.transpose();
  P_ = S(0.5) * (P_ + P_.transpose()).eval();
  return Update::Fused;
}

namespace modal_detail {

// A step that did nothing: its status and why.
template <typename Record>
StepStatus fail(Record& rec, StepStatus s, StepDetail d) {
  rec.status = s;
  rec.detail = d;
  rec.fused = false;
  return s;
}

// One step of either modal filter: predict over dt, then update with the
// image; the first image the filter takes initialises it instead.
template <typename Filter, typename S>
StepStatus step(Filter& f, S dt, const typename Filter::Decomp& meas, typename Filter::Record& rec) {
  using Record = typename Filter::Record;
  if (!f.initialized()) {
    rec = Record();
    rec.decomposition = meas.status;
    rec.status = f.initialize(meas);
    rec.fused = rec.status == StepStatus::Ok;
    return rec.status;
  }
  const StepStatus sp = f.predict(dt);
  if (sp != StepStatus::Ok) {
    rec = Record();
    rec.decomposition = meas.status;
    return fail(rec, sp, sp == StepStatus::NotPosDef ? StepDetail::PriorCholesky : StepDetail::None);
  }
  return f.update(meas, rec);
}

}  // namespace modal_detail

// Bank of M decoupled per-mode filters.
template <typename S, int M>
class ModalUkfBank {
 public:
  using VecM = Eigen::Matrix<S, M, 1>;
  using MatM = Eigen::Matrix<S, M, M>;
  using Config = ModalFilterConfig<S, M>;
  using Record = ModalStepRecord<S, M>;
  using Decomp = ModalDecompositionRecord<S, M>;
  static constexpr int kModes = M;

  explicit ModalUkfBank(const Config& cfg = Config()) { reset(cfg); }

  // Back to uninitialised with a new configuration, in place.
  void reset(const Config& cfg);

  bool initialized() const { return initialized_; }

  // Eq. 7 from the first well-conditioned image.
  StepStatus initialize(const Decomp& meas);

  StepStatus predict(S dt);

  StepStatus update(const Decomp& meas, Record& rec);

  // Predict over dt then update with the image (the first Ok image initialises).
  StepStatus step(S dt, const Decomp& meas, Record& rec) { return modal_detail::step(*this, dt, meas, rec); }

  // cppcheck-suppress constParameter ; a is the output (Eigen's element access writes; cppcheck does not read Eigen)
  void amplitudes(VecM& a) const {
    for (int i = 0; i < M; ++i) a(i) = f_[i].state()(0);
  }
  // Amplitude covariance: diagonal (the bank carries no cross-mode terms).
  void amplitude_cov(MatM& P) const;
  Eigen::Matrix<S, 4, 1> mode_state(int i) const { return f_[i].state(); }
  Eigen::Matrix<S, 4, 4> mode_cov(int i) const { return f_[i].cov(); }
  const Config& config() const { return cfg_; }

 private:
  static StepStatus fail(Record& rec, StepStatus s, StepDetail d) { return modal_detail::fail(rec, s, d); }

  Config cfg_;
  UtWeights<S> w_;
  bool initialized_ = false;
  ModeUkf<S> f_[M];
  Eigen::Matrix<S, 4, 1> xs_[M];
  Eigen::Matrix<S, 4, 4> Ps_[M];
};

template <typename S, int M>
void ModalUkfBank<S, M>::reset(const Config& cfg) {
  cfg_ = cfg;
  w_ = UtWeights<S>::make(4, cfg.ut);
  initialized_ = false;
}

template <typename S, int M>
auto ModalUkfBank<S, M>::initialize(const Decomp& meas) -> StepStatus {
  if (meas.status != ModalStatus::Ok) return StepStatus::BadInput;
  for (int i = 0; i < M; ++i) f_[i].init(meas.a_coarse(i), meas.cov_a(i, i), cfg_.mode[i]);
  initialized_ = true;
  return StepStatus::Ok;
}

template <typename S, int M>
auto ModalUkfBank<S, M>::predict(S dt) -> StepStatus {
  if (!initialized_ || !(dt > S(0)) || !std::isfinite(dt)) return StepStatus::BadInput;
  for (int i = 0; i < M; ++i)
    if (!f_[i].predict_into(dt, w_, xs_[i], Ps_[i])) return StepStatus::NotPosDef;
  for (int i = 0; i < M; ++i) f_[i].set(xs_[i], Ps_[i]);
  return StepStatus::Ok;
}

template <typename S, int M>
auto ModalUkfBank<S, M>::update(const Decomp& meas, Record& rec) -> StepStatus {
  rec = Record();
  rec.decomposition = meas.status;
  if (!initialized_) return fail(rec, StepStatus::BadInput, StepDetail::NotInitialized);
  if (meas.status != ModalStatus::Ok) return fail(rec, StepStatus::BadInput, StepDetail::None);
  if (!meas.a_coarse.allFinite()) return fail(rec, StepStatus::BadInput, StepDetail::NonFinite);
  for (int i = 0; i < M; ++i)  // all innovation variances checked before any mode changes
    if (!(f_[i].cov()(0, 0) + meas.cov_a(i, i) > S(0)))
      return fail(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  int fused = 0;
  for (int i = 0; i < M; ++i) {
    S nu, s, nis = S(0);
    const auto r = f_[i].update(meas.a_coarse(i), meas.cov_a(i, i), cfg_.gate_nis, nu, s, nis);
    rec.innovation(i) = nu;
    rec.innovation_var(i) = s;
    rec.nis += nis;
    if (r == ModeUkf<S>::Update::Fused) ++fused;
    if (r == ModeUkf<S>::Update::Gated) ++rec.n_gated;
  }
  rec.fused = fused > 0;
  rec.status = fused > 0 ? StepStatus::Ok : StepStatus::Gated;
  return rec.status;
}

template <typename S, int M>
void ModalUkfBank<S, M>::amplitude_cov(MatM& P) const {
  P.setZero();
  for (int i = 0; i < M; ++i) P(i, i) = f_[i].cov()(0, 0);
}

// One joint filter over all M modes (N = 4M states).
template <typename S, int M>
class ModalUkfJoint {
 public:
  static constexpr int N = 4 * M;
  static constexpr int L = 2 * N + 1;
  static constexpr int kModes = M;
  using VecM = Eigen::Matrix<S, M, 1>;
  using MatM = Eigen::Matrix<S, M, M>;
  using VecN = Eigen::Matrix<S, N, 1>;
  using MatN = Eigen::Matrix<S, N, N>;
  using Config = ModalFilterConfig<S, M>;
  using Record = ModalStepRecord<S, M>;
  using Decomp = ModalDecompositionRecord<S, M>;

  explicit ModalUkfJoint(const Config& cfg = Config()) { reset(cfg); }

  // Back to uninitialised with a new configuration, in place (the filter
  // is too large to rebuild through a stack temporary).
  void reset(const Config& cfg);

  bool initialized() const { return initialized_; }

  // Eq. 7, with the full coupled amplitude covariance of eq. 4.
  StepStatus initialize(const Decomp& meas);

  StepStatus predict(S dt);

  StepStatus update(const Decomp& meas, Record& rec);

  // As ModalUkfBank::step.
  StepStatus step(S dt, const Decomp& meas, Record& rec) { return modal_detail::step(*this, dt, meas, rec); }

  // cppcheck-suppress constParameter ; a is the output (Eigen's element access writes; cppcheck does not read Eigen)
  void amplitudes(VecM& a) const {
    for (int i = 0; i < M; ++i) a(i) = x_.m()(4 * i);
  }
  void amplitude_cov(MatM& Pa) const;
  Eigen::Matrix<S, 4, 1> mode_state(int i) const { return x_.m().template segment<4>(4 * i); }
  Eigen::Matrix<S, 4, 4> mode_cov(int i) const { return P_.m().template block<4, 4>(4 * i, 4 * i); }
  S cov_entry(int r, int c) const { return P_.m()(r, c); }
  const Config& config() const { return cfg_; }

 private:
  static constexpr int C = modal_detail::chunk_width(L - 1, 32);
  static constexpr int C2 = modal_detail::chunk_width(N, 32);

  static StepStatus fail(Record& rec, StepStatus s, StepDetail d) { return modal_detail::fail(rec, s, d); }

  Config cfg_;
  UtWeights<S> w_;
  bool initialized_ = false;
  modal_detail::Store<S, N, 1> x_, xp_, q_;
  modal_detail::Store<S, N, N> P_, L_;
  modal_detail::Store<S, N, L> X_;
  modal_detail::Store<S, N, M> pxa_;
  modal_detail::Store<S, M, N> kt_;
  MatM s_;
  VecM nu_, y_;
  Eigen::LLT<MatM> llt_s_;
};

template <typename S, int M>
void ModalUkfJoint<S, M>::reset(const Config& cfg) {
  cfg_ = cfg;
  w_ = UtWeights<S>::make(N, cfg.ut);
  initialized_ = false;
  P_.m().setIdentity();
  x_.m().setZero();
  for (int i = 0; i < M; ++i) {
    const ModalModeConfig<S>& c = cfg_.mode[i];
    q_.m().template segment<4>(4 * i) << c.q_a, c.q_v, c.q_omega, c.q_alpha;
  }
}

template <typename S, int M>
auto ModalUkfJoint<S, M>::initialize(const Decomp& meas) -> StepStatus {
  if (meas.status != ModalStatus::Ok) return StepStatus::BadInput;
  auto x = x_.m();
  auto P = P_.m();
  P.setZero();
  for (int i = 0; i < M; ++i) {
    const ModalModeConfig<S>& c = cfg_.mode[i];
    x.template segment<4>(4 * i) << meas.a_coarse(i), S(0), c.omega_radps, c.alpha_ps;
    for (int j = 0; j < M; ++j) P(4 * i, 4 * j) = meas.cov_a(i, j);
    P(4 * i + 1, 4 * i + 1) = c.sigma_v0_ps * c.sigma_v0_ps;
    P(4 * i + 2, 4 * i + 2) = c.sigma_omega0_radps * c.sigma_omega0_radps;
    P(4 * i + 3, 4 * i + 3) = c.sigma_alpha0_ps * c.sigma_alpha0_ps;
  }
  initialized_ = true;
  return StepStatus::Ok;
}

template <typename S, int M>
auto ModalUkfJoint<S, M>::predict(S dt) -> StepStatus {
  if (!initialized_ || !(dt > S(0)) || !std::isfinite(dt)) return StepStatus::BadInput;
  auto Lc = L_.m();
  auto X = X_.m();
  auto x = x_.m();
  auto P = P_.m();
  // cppcheck-suppress redundantAssignment ; Lc is a view: this copies into L_
  Lc = P;
  {
    Eigen::LLT<Eigen::Ref<MatN>> llt(Lc);  // in place, lower triangle
    if (llt.info() != Eigen::Success) return StepStatus::NotPosDef;
  }
  // Sigma points x +- gamma L_j. Column j of L is zero above row j, so a
  // mode block above j is not perturbed and maps to f(x_block).
  X.col(0) = x;
  for (int j = 0; j < N; ++j) {
    X.col(1 + j) = x;
    X.col(1 + N + j) = x;
    X.col(1 + j).tail(N - j) += w_.gamma * Lc.col(j).tail(N - j);
    X.col(1 + N + j).tail(N - j) -= w_.gamma * Lc.col(j).tail(N - j);
  }
  S* xd = X_.v;
  for (int i = 0; i < M; ++i) {
    S f0[4];
    modal_detail::propagate_mode(xd + 4 * i, f0, dt);
    for (int r = 0; r < 4; ++r) xd[4 * i + r] = f0[r];
    const int last = 4 * i + 3;  // columns j > last leave block i at the mean
    for (int j = 0; j < N; ++j) {
      S* a = xd + static_cast<long>(1 + j) * N + 4 * i;
      S* b = xd + static_cast<long>(1 + N + j) * N + 4 * i;
      if (j <= last) {
        modal_detail::propagate_mode(a, a, dt);
        modal_detail::propagate_mode(b, b, dt);
      } else {
        for (int r = 0; r < 4; ++r) a[r] = b[r] = f0[r];
      }
    }
  }
  auto xp = xp_.m();
  xp.setZero();
  for (int k = 1; k < L; ++k) xp += X.col(k);
  xp *= w_.wi;
  xp += w_.wm0 * X.col(0);
  for (int k = 0; k < L; ++k) X.col(k) -= xp;
  // Lower triangle of sum_k w_k d_k d_k^T, in chunks of C sigma points.
  auto Pp = L_.m();  // the factor is no longer needed: reuse its storage
  Pp.setZero();
  for (int c = 0; c < (L - 1) / C; ++c) {
    Pp.template selfadjointView<Eigen::Lower>().rankUpdate(X.template middleCols<C>(1 + c * C), w_.wi);
  }
  Pp.template selfadjointView<Eigen::Lower>().rankUpdate(X.col(0), w_.wc0);
  for (int j = 0; j < N; ++j) {
    Pp(j, j) += q_.m()(j) * dt;
    for (int i = j + 1; i < N; ++i) Pp(j, i) = Pp(i, j);
  }
  if (!xp.allFinite() || !Pp.allFinite()) return StepStatus::NotPosDef;
  x = xp;
  P = Pp;
  return StepStatus::Ok;
}

template <typename S, int M>
auto ModalUkfJoint<S, M>::update(const Decomp& meas, Record& rec) -> StepStatus {
  rec = Record();
  rec.decomposition = meas.status;
  if (!initialized_) return fail(rec, StepStatus::BadInput, StepDetail::NotInitialized);
  if (meas.status != ModalStatus::Ok) return fail(rec, StepStatus::BadInput, StepDetail::None);
  if (!meas.a_coarse.allFinite() || !meas.cov_a.allFinite())
    return fail(rec, StepStatus::BadInput, StepDetail::NonFinite);
  auto P = P_.m();
  auto x = x_.m();
  auto PxA = pxa_.m();
  for (int i = 0; i < M; ++i) {
    PxA.col(i) = P.col(4 * i);
    for (int j = 0; j < M; ++j) s_(i, j) = P(4 * i, 4 * j) + meas.cov_a(i, j);
    nu_(i) = meas.a_coarse(i) - x(4 * i);
  }
  llt_s_.compute(s_);
  if (llt_s_.info() != Eigen::Success) return fail(rec, StepStatus::NotPosDef, StepDetail::InnovationCholesky);
  y_ = nu_;
  llt_s_.solveInPlace(y_);
  rec.innovation = nu_;
  rec.innovation_var = s_.diagonal();
  rec.nis = nu_.dot(y_);
  if (cfg_.gate_nis > S(0) && rec.nis > cfg_.gate_nis) return fail(rec, StepStatus::Gated, StepDetail::None);
  auto Kt = kt_.m();
  // cppcheck-suppress redundantAssignment ; Kt is a view: this copies into kt_
  Kt = PxA.transpose();
  llt_s_.solveInPlace(Kt);  // S^-1 P_Ax
  x.noalias() += PxA * y_;
  for (int c = 0; c < N / C2; ++c) {
    P.template middleCols<C2>(c * C2).noalias() -= PxA * Kt.template middleCols<C2>(c * C2);
  }
  for (int j = 0; j < N; ++j)
    for (int i = j + 1; i < N; ++i) {
      const S m = S(0.5) * (P(i, j) + P(j, i));
      P(i, j) = P(j, i) = m;
    }
  rec.fused = true;
  rec.status = StepStatus::Ok;
  return rec.status;
}

template <typename S, int M>
// cppcheck-suppress constParameter ; Pa is the output (cppcheck does not read Eigen)
void ModalUkfJoint<S, M>::amplitude_cov(MatM& Pa) const {
  for (int i = 0; i < M; ++i)
    for (int j = 0; j < M; ++j) Pa(i, j) = P_.m()(4 * i, 4 * j);
}

// Compiled once, in fsw_core (instantiate_modal.cpp, instantiate_modal_bank.cpp,
// instantiate_modal_joint.cpp); see nav_ukf.hpp.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class ModeUkf<double>;
extern template class ModeUkf<float>;
#define FSW_EXTERN_FILTERS(S, M)            \
  extern template class ModalUkfBank<S, M>; \
  extern template class ModalUkfJoint<S, M>;
FSW_MODAL_INSTANCES(FSW_EXTERN_FILTERS)
#undef FSW_EXTERN_FILTERS
#endif

}  // namespace fsw
