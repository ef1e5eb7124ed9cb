// Bayes linear regression over a sliding window, in information form, with
// several outputs sharing one information matrix (section 3.2 of
// "Online Dynamic Modeling and Localization for Small-Spacecraft
// Proximity Operations" (Rogers-Marcovitz), eqs. 19-23; eqs. 17-18 of the paper carry sign and typo errors and are not
// used).
//
// Model, per output k = 0..K-1:  y_k = theta_k^T x + e_k,  e_k ~ N(0, s_k^2),
// prior theta_k ~ N(0, s_k^2 / lambda I). Every output has the same inputs,
// so the information matrices differ only by the scale 1/s_k^2 and one
// unscaled matrix is kept for all of them:
//
//   A = lambda I + sum_window x x^T          (P_k = A / s_k^2,     eq. 19)
//   B = sum_window x y^T          (D x K)    (J_k = B_k / s_k^2,   eq. 20)
//   theta = A^-1 B                           (mu = P^-1 J,         eq. 21)
//   Sigma_k = s_k^2 A^-1                     (                     eq. 22)
//   mean_k = theta_k^T x,  var_k = s_k^2 (1 + x^T A^-1 x)        (eq. 23)
//
// The posterior mean does not depend on s_k. s_k^2 is either configured or
// estimated from the window residual, (sum y_k^2 - B_k^T theta_k) / (n - D).
//
// Sliding window: a ring buffer of capacity W. add() enters a sample
// (O(D^2 + D K)), evicting the oldest when the window is full; remove_oldest()
// subtracts one (eq. 19-20 with a minus sign). Prediction factors A = L L^T
// by Cholesky (O(D^3), cached until the window changes), keeps C = L^-1 B,
// and then costs O(D^2 + D K): u = L^-1 x, mean = C^T u, leverage = |u|^2.
//
// Exactness over long runs (shadow accumulator): subtracting samples from
// running sums leaves rounding residue that a random walk of adds and removes
// would grow without bound, and large samples that have left the window would
// leave their rounding behind. So a second accumulator ("fresh") sums, by
// additions only, every sample entered since the start of the current epoch.
// Once the last sample that predates the epoch has been removed (at most W
// removals later), the fresh sums are exactly the window's sums built from
// scratch; they replace the running sums and a new epoch starts. The running
// sums therefore never carry more than about 3 W rank-one updates of
// rounding, whatever the run length, and every add/remove stays O(D^2):
// no periodic O(W D^2) rebuild spikes.
//
// Real-time core: fixed-size Eigen only, no heap, no exceptions, no I/O,
// bounded loops. Non-finite samples are rejected with a status and never
// enter the window.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>

#include "fsw/math/step_status.hpp"

namespace fsw {

// The project's step status (step_status.hpp). Here:
//   Ok        done;
//   BadInput  non-finite input or output (sample not entered, no prediction),
//             or remove_oldest() on an empty window; state untouched;
//   NotPosDef information matrix not positive definite (lambda = 0 with a
//             rank-deficient window); the last good posterior is kept.
using BlrStatus = StepStatus;

template <typename S, int K>
struct BlrConfig {
  // lambda: prior precision of each weight, in units of the noise variance
  // (prior theta_k ~ N(0, s_k^2 / lambda I)). Must be >= 0; 0 is plain least
  // squares over the window. [1 / x^2]
  S prior_precision = S(1e-3);
  // Noise variance s_k^2 per output [y_k^2], used for the predictive variance
  // when estimate_noise is false or the window holds no more than D samples.
  Eigen::Matrix<S, K, 1> noise_var = Eigen::Matrix<S, K, 1>::Ones();
  // Estimate s_k^2 from the window residual once the window holds more than D samples.
  bool estimate_noise = true;
};

// Inputs from the eight valve states: [v0 .. v7, 1] and, with kPairs, the 28
// pairwise products v_i v_j (i < j) after them (Rogers-Marcovitz, section 3.4).
// Bit i of the mask is valve i (1 = open).
template <typename S, bool kPairs = false>
struct ValveFeatures {
  static constexpr int kValves = 8;
  static constexpr int kDim = kValves + 1 + (kPairs ? kValves * (kValves - 1) / 2 : 0);
  using Vec = Eigen::Matrix<S, kDim, 1>;

  static Vec from_mask(std::uint8_t mask) {
    Vec x;
    for (int i = 0; i < kValves; ++i) x(i) = ((mask >> i) & 1u) ? S(1) : S(0);
    x(kValves) = S(1);
    if (kPairs) {
      int k = kValves + 1;
      for (int i = 0; i < kValves; ++i)
        for (int j = i + 1; j < kValves; ++j) x(k++) = x(i) * x(j);
    }
    return x;
  }
};

template <typename S, int D, int K, int W>
class BayesLinReg {
  static_assert(D >= 1 && K >= 1 && W >= 1, "dimensions must be positive");

 public:
  static constexpr int kInputs = D;
  static constexpr int kOutputs = K;
  static constexpr int kWindow = W;
  using VecX = Eigen::Matrix<S, D, 1>;
  using VecY = Eigen::Matrix<S, K, 1>;
  using MatA = Eigen::Matrix<S, D, D>;
  using MatB = Eigen::Matrix<S, D, K>;
  using Config = BlrConfig<S, K>;

  // What add() did.
  struct AddRecord {
    BlrStatus status = BlrStatus::Ok;
    bool entered = false;    // the sample is now in the window
    bool evicted = false;    // the oldest sample was removed to make room
    bool refreshed = false;  // the running sums were replaced by the exact fresh sums
    int count = 0;           // samples in the window afterwards
  };

  // What predict() returns: the posterior predictive per output.
  struct Prediction {
    BlrStatus status = BlrStatus::Ok;
    VecY mean = VecY::Zero();       // theta^T x
    VecY variance = VecY::Zero();   // s_k^2 (1 + x^T A^-1 x)
    VecY noise_var = VecY::Zero();  // s_k^2 used
    S leverage = S(0);              // x^T A^-1 x (dimensionless)
    int count = 0;                  // samples the posterior is built on
  };

  explicit BayesLinReg(const Config& cfg = Config()) : cfg_(cfg) {
    // A negative or NaN prior precision would make A indefinite: use 0.
    if (!(cfg_.prior_precision >= S(0)) || !std::isfinite(cfg_.prior_precision)) cfg_.prior_precision = S(0);
    for (int k = 0; k < K; ++k)
      if (!(cfg_.noise_var(k) >= S(0)) || !std::isfinite(cfg_.noise_var(k))) cfg_.noise_var(k) = S(1);
    reset();
  }

  void reset();

  // Enter one sample (x, y); evicts the oldest sample first if the window is full.
  AddRecord add(const VecX& x, const VecY& y);

  // Remove the oldest sample (eqs. 19-20 with a minus sign). BadInput if empty.
  BlrStatus remove_oldest();

  // Posterior predictive at x. Re-factors A only if the window changed.
  Prediction predict(const VecX& x);

  // Factor A = L L^T and form C = L^-1 B if the window changed since the last
  // call (O(D^3 / 6 + D^2 K / 2)). On failure the previous posterior is kept
  // and NotPosDef returned.
  BlrStatus refresh_posterior();

  // Posterior mean of the weights theta = A^-1 B (D x K, column k = theta_k),
  // of the last successful refresh_posterior() (back substitution on demand).
  const MatB& theta() const;
  // The shared unscaled information matrix A = lambda I + sum x x^T.
  MatA information() const;
  // The shared unscaled information vectors B = sum x y^T (D x K).
  const MatB& information_vectors() const { return run_.xy; }
  // Noise variances s_k^2 of the last refresh.
  const VecY& noise_var() const { return sigma2_; }

  int count() const { return count_; }
  bool full() const { return count_ == W; }
  const Config& config() const { return cfg_; }
  // How many times the running sums were replaced by the exact fresh sums.
  std::uint64_t refresh_count() const { return refresh_count_; }
  // Window contents, i = 0 is the oldest (0 <= i < count()).
  VecX window_x(int i) const { return xs_.col((head_ + i) % W); }
  VecY window_y(int i) const { return ys_.col((head_ + i) % W); }

 private:
  struct Sums {
    MatA xx;
    MatB xy;
    VecY yy;
    void clear() {
      xx.setZero();
      xy.setZero();
      yy.setZero();
    }
    void add(const VecX& x, const VecY& y) {
      xx.noalias() += x * x.transpose();
      xy.noalias() += x * y.transpose();
      yy.array() += y.array().square();
    }
    void sub(const VecX& x, const VecY& y) {
      xx.noalias() -= x * x.transpose();
      xy.noalias() -= x * y.transpose();
      yy.array() -= y.array().square();
    }
  };

  // Lower Cholesky factor of xx + lambda I, right-looking (each step scales
  // one column and updates the trailing block with contiguous inner loops;
  // D is small and fixed, so the loops unroll). False if a pivot is not
  // positive and finite.
  static bool cholesky(const MatA& xx, S lambda, MatA& l, VecX& inv_diag);

  // Solve L u = b (L lower triangular with reciprocal diagonal inv_diag).
  template <typename Vb>
  static void forward_solve(const MatA& l, const VecX& inv_diag, const Vb& b, VecX& u) {
    for (int i = 0; i < D; ++i) {
      S v = b(i);
      for (int k = 0; k < i; ++k) v -= l(i, k) * u(k);
      u(i) = v * inv_diag(i);
    }
  }

  // Returns true if the running sums were replaced by the fresh sums.
  bool remove_oldest_impl();

  Config cfg_;
  Sums run_;                   // running window sums (adds and subtractions)
  Sums fresh_;                 // additions only, since the start of the epoch
  Eigen::Matrix<S, D, W> xs_;  // ring buffer of inputs
  Eigen::Matrix<S, K, W> ys_;  // ring buffer of outputs
  int head_ = 0;               // slot of the oldest sample
  int count_ = 0;              // samples in the window
  int pre_epoch_ = 0;          // window samples older than the current epoch
  std::uint64_t refresh_count_ = 0;
  bool dirty_ = true;
  bool factor_ok_ = false;
  BlrStatus last_status_ = BlrStatus::Ok;
  MatA l_;                     // Cholesky factor of A (last good)
  VecX inv_diag_;              // 1 / diag(L)
  Eigen::Matrix<S, K, D> ct_;  // (L^-1 B)^T
  mutable MatB theta_;
  mutable bool theta_stale_ = false;
  VecY sigma2_;
};

template <typename S, int D, int K, int W>
void BayesLinReg<S, D, K, W>::reset() {
  run_.clear();
  fresh_.clear();
  head_ = 0;
  count_ = 0;
  pre_epoch_ = 0;
  refresh_count_ = 0;
  dirty_ = true;
  factor_ok_ = false;
  theta_.setZero();
  theta_stale_ = false;
  l_.setIdentity();
  inv_diag_.setOnes();
  ct_.setZero();
  sigma2_ = cfg_.noise_var;
  xs_.setZero();
  ys_.setZero();
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::add(const VecX& x, const VecY& y) -> AddRecord {
  AddRecord rec;
  if (!x.allFinite() || !y.allFinite()) {
    rec.status = BlrStatus::BadInput;
    rec.count = count_;
    return rec;
  }
  if (count_ == W) {
    rec.refreshed = remove_oldest_impl();
    rec.evicted = true;
  }
  const int slot = (head_ + count_) % W;
  xs_.col(slot) = x;
  ys_.col(slot) = y;
  ++count_;
  run_.add(x, y);
  fresh_.add(x, y);
  dirty_ = true;
  rec.entered = true;
  rec.count = count_;
  return rec;
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::remove_oldest() -> BlrStatus {
  if (count_ == 0) return BlrStatus::BadInput;
  remove_oldest_impl();
  return BlrStatus::Ok;
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::predict(const VecX& x) -> Prediction {
  Prediction p;
  p.count = count_;
  if (!x.allFinite()) {
    p.status = BlrStatus::BadInput;
    return p;
  }
  p.status = refresh_posterior();
  if (!factor_ok_) {
    // Never had a positive-definite A: no information about theta.
    p.mean.setZero();
    p.variance.setConstant(std::numeric_limits<S>::infinity());
    p.noise_var = sigma2_;
    p.leverage = std::numeric_limits<S>::infinity();
    return p;
  }
  // On NotPosDef the last good posterior is used and the status says so.
  // u = L^-1 x; mean = theta^T x = C^T u with C = L^-1 B; leverage = |u|^2.
  VecX u;
  forward_solve(l_, inv_diag_, x, u);
  p.leverage = u.squaredNorm();
  p.mean.noalias() = ct_ * u;
  p.noise_var = sigma2_;
  p.variance = sigma2_ * (S(1) + p.leverage);
  return p;
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::refresh_posterior() -> BlrStatus {
  if (!dirty_) return last_status_;
  dirty_ = false;
  MatA l;
  VecX inv_diag;
  if (!cholesky(run_.xx, cfg_.prior_precision, l, inv_diag)) {
    last_status_ = BlrStatus::NotPosDef;
    return last_status_;
  }
  l_ = l;
  inv_diag_ = inv_diag;
  // C^T = (L^-1 B)^T column by column: all K outputs at once per row of L.
  for (int i = 0; i < D; ++i) {
    VecY v = run_.xy.row(i).transpose();
    for (int k = 0; k < i; ++k) v -= l_(i, k) * ct_.col(k);
    ct_.col(i) = v * inv_diag_(i);
  }
  theta_stale_ = true;
  factor_ok_ = true;
  if (cfg_.estimate_noise && count_ > D) {
    for (int k = 0; k < K; ++k) {
      // Residual sum of squares plus the prior term: sum y^2 - B_k^T A^-1 B_k >= 0.
      const S rss = run_.yy(k) - ct_.row(k).squaredNorm();
      sigma2_(k) = rss > S(0) ? rss / S(count_ - D) : S(0);
    }
  } else {
    sigma2_ = cfg_.noise_var;
  }
  last_status_ = BlrStatus::Ok;
  return last_status_;
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::theta() const -> const MatB& {
  if (theta_stale_) {
    for (int k = 0; k < K; ++k) {
      for (int i = D - 1; i >= 0; --i) {
        S v = ct_(k, i);
        for (int j = i + 1; j < D; ++j) v -= l_(j, i) * theta_(j, k);
        theta_(i, k) = v * inv_diag_(i);
      }
    }
    theta_stale_ = false;
  }
  return theta_;
}

template <typename S, int D, int K, int W>
auto BayesLinReg<S, D, K, W>::information() const -> MatA {
  MatA a = run_.xx;
  a.diagonal().array() += cfg_.prior_precision;
  return a;
}

template <typename S, int D, int K, int W>
// cppcheck-suppress constParameter ; inv_diag is an output (cppcheck does not read Eigen)
inline bool BayesLinReg<S, D, K, W>::cholesky(const MatA& xx, S lambda, MatA& l, VecX& inv_diag) {
  l = xx;
  l.diagonal().array() += lambda;
  for (int j = 0; j < D; ++j) {
    const S d = l(j, j);
    if (!(d > S(0)) || !std::isfinite(d)) return false;
    const S ljj = std::sqrt(d);
    const S inv = S(1) / ljj;
    l(j, j) = ljj;
    inv_diag(j) = inv;
    for (int i = j + 1; i < D; ++i) l(i, j) *= inv;
    for (int k = j + 1; k < D; ++k) {
      const S lkj = l(k, j);
      for (int i = k; i < D; ++i) l(i, k) -= l(i, j) * lkj;
    }
  }
  for (int k = 1; k < D; ++k)
    for (int i = 0; i < k; ++i) l(i, k) = S(0);
  return true;
}

template <typename S, int D, int K, int W>
inline bool BayesLinReg<S, D, K, W>::remove_oldest_impl() {
  const int slot = head_;
  head_ = (head_ + 1) % W;
  --count_;
  dirty_ = true;
  if (count_ == 0) {
    // Empty window: the sums are exactly zero.
    run_.clear();
    fresh_.clear();
    pre_epoch_ = 0;
    return false;
  }
  run_.sub(xs_.col(slot), ys_.col(slot));
  if (pre_epoch_ == 0) {
    // The removed sample was in the fresh sums: start a new epoch now; the
    // running sums carry this one subtraction until the next refresh.
    fresh_.clear();
    pre_epoch_ = count_;
    return false;
  }
  if (--pre_epoch_ == 0) {
    // Every sample older than the epoch has left: fresh == window sums.
    run_ = fresh_;
    fresh_.clear();
    pre_epoch_ = count_;
    ++refresh_count_;
    return true;
  }
  return false;
}

// The thruster learner of Rogers-Marcovitz: eight valves plus bias in, change in body
// linear velocity [m/s] (3) and angular velocity [rad/s] (3) per firing out.
template <typename S, int W = 30>
using ThrusterBlr = BayesLinReg<S, ValveFeatures<S, false>::kDim, 6, W>;
template <typename S, int W = 30>
using ThrusterBlrPairs = BayesLinReg<S, ValveFeatures<S, true>::kDim, 6, W>;

// Compiled once, in fsw_core (instantiate_blr.cpp); see nav_ukf.hpp.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class BayesLinReg<double, 9, 6, 30>;
extern template class BayesLinReg<float, 9, 6, 30>;
extern template class BayesLinReg<double, 37, 6, 30>;
extern template class BayesLinReg<float, 37, 6, 30>;
#endif

}  // namespace fsw
