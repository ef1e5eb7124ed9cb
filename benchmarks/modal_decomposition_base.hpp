// The modal decomposition of fsw/include/fsw/modal/modal_decomposition.hpp
// written with per-value scalar finiteness checks before the gather
// (namespace fsw_base): the reference bench_modal compares the vectorised
// gather against. Benchmark use only.
// Modal decomposition of one range image (section III, eqs. 2-4, of
// "Shape, Motion, and Parameter Estimation of Large Flexible Space
// Structures using Range Images" (Lichter and Dubowsky)).
//
// The deflection of the structure is z(x, t) = A(t)^T Phi(x) (eq. 1) with M
// known mode shapes Phi. One range image gives n points y_k with measured
// deflections z_k (n changes from image to image: the points actually seen).
//
//   M_Y = sum_k Phi(y_k) Phi(y_k)^T        modal correlation matrix   (eq. 2)
//   b   = sum_k Phi(y_k) z_k               projection <Phi, z>_Y
//   A~  = M_Y^-1 b                         coarse estimate            (eq. 3)
//   cov = M_Y^-1 G M_Y^-1,  G = sum_k s_k^2 Phi Phi^T   (per point,   eq. 4a)
//   cov = s_e^2 M_Y^-1                     (equal variance,           eq. 4b)
//
// Points are streamed in (pointer + count, or one at a time): memory is
// O(M^2), independent of n. Points are gathered into a fixed chunk of K and
// folded into M_Y with one symmetric rank-K update per chunk, so the O(n M^2)
// work runs as a blocked matrix product rather than n rank-one updates.
//
// Observability: M_Y is positive semidefinite; it is singular when modes are
// not observable or are aliased in the sample space. solve() computes the
// eigenvalues of M_Y and reports IllConditioned (no estimate) when the
// condition number exceeds the configured bound, and TooFewPoints when fewer
// than max(M + 1, min_points) finite points were seen. Never inverted silently.
//
// Bad input: a point with a non-finite deflection or mode-shape value is
// skipped and counted; a point whose variance is given but not finite and
// positive is skipped and counted separately.
//
// Real-time core: fixed-size Eigen only, no heap, no exceptions, no I/O.
// The object holds O(M^2 + M K) scalars; construct it once (statically or
// at start-up) and reuse it with reset().
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

namespace fsw_base {

// Outcome of a modal decomposition. (Estimator steps use StepStatus from
// step_status.hpp; these are the decomposition's own, finer outcomes.)
enum class ModalStatus : std::uint8_t {
  Ok = 0,
  TooFewPoints = 1,    // fewer usable points than max(M + 1, min_points): no estimate
  IllConditioned = 2,  // cond(M_Y) above the bound (unobservable / aliased modes): no estimate
  BadInput = 3,        // inconsistent input (some points with variances, some without) or bad config
};

constexpr const char* to_string(ModalStatus s) {
  switch (s) {
    case ModalStatus::Ok: return "ok";
    case ModalStatus::TooFewPoints: return "too_few_points";
    case ModalStatus::IllConditioned: return "ill_conditioned";
    case ModalStatus::BadInput: return "bad_input";
  }
  return "unknown";
}

template <typename S>
struct ModalDecompositionConfig {
  // Equal range-noise standard deviation along the deflection [m] for eq. 4b.
  // 0: use the residual estimate RSS / (n - M) instead.
  S sigma_e_m = S(0);
  // Largest accepted condition number of M_Y (ratio of its extreme eigenvalues).
  S max_condition = std::is_same<S, float>::value ? S(1e5) : S(1e10);
  // Minimum number of usable points (the effective minimum is max(M + 1, this)).
  int min_points = 0;
};

// Result of one decomposition. On any status other than Ok, a_coarse and
// cov_a are zero and must not be used; the counters and the eigenvalues (when
// computed) are always filled.
template <typename S, int M>
struct ModalDecompositionRecord {
  ModalStatus status = ModalStatus::TooFewPoints;
  Eigen::Matrix<S, M, 1> a_coarse = Eigen::Matrix<S, M, 1>::Zero();  // eq. 3 [-]
  Eigen::Matrix<S, M, M> cov_a = Eigen::Matrix<S, M, M>::Zero();     // eq. 4a / 4b [-^2]
  S condition_number = std::numeric_limits<S>::infinity();           // cond(M_Y)
  S eig_min = S(0);                                                  // extreme eigenvalues of M_Y
  S eig_max = S(0);
  S sigma2_residual_m2 = S(0);      // RSS / (n - M) [m^2], 0 when n <= M
  int n_used = 0;                   // points entered into M_Y
  int n_nonfinite = 0;              // points skipped: NaN / Inf deflection or mode value
  int n_bad_variance = 0;           // points skipped: variance given but not finite and > 0
  bool per_point_variance = false;  // true: eq. 4a, false: eq. 4b
  bool ok() const { return status == ModalStatus::Ok; }
};

template <typename S, int M, int K = 32>
class ModalDecomposition {
  static_assert(M >= 1, "at least one mode");
  static_assert(K >= 1, "chunk of at least one point");

 public:
  using VecM = Eigen::Matrix<S, M, 1>;
  using MatM = Eigen::Matrix<S, M, M>;
  using Config = ModalDecompositionConfig<S>;
  using Record = ModalDecompositionRecord<S, M>;
  static constexpr int kModes = M;

  explicit ModalDecomposition(const Config& cfg = Config()) : cfg_(cfg) { reset(); }

  const Config& config() const { return cfg_; }
  void set_config(const Config& cfg) { cfg_ = cfg; }

  // Starts a new image.
  void reset() {
    my_.setZero();
    g_.setZero();
    b_.setZero();
    zz_ = S(0);
    fill_ = 0;
    n_used_ = n_nonfinite_ = n_bad_var_ = n_with_var_ = 0;
  }

  // One point: phi[0..M) mode-shape values at the point, z measured deflection
  // [m], var its variance [m^2] (pass a negative value for "not given": eq. 4b).
  // Returns true if the point was used.
  bool add_point(const S* phi, S z, S var = S(-1)) {
    if (!std::isfinite(z)) return skip_nonfinite();
    for (int i = 0; i < M; ++i)
      if (!std::isfinite(phi[i])) return skip_nonfinite();
    const bool has_var = !(var < S(0));  // NaN counts as given (and bad)
    if (has_var && !(std::isfinite(var) && var > S(0))) {
      ++n_bad_var_;
      return false;
    }
    for (int i = 0; i < M; ++i) chunk_(i, fill_) = phi[i];
    zc_(fill_) = z;
    wc_(fill_) = has_var ? std::sqrt(var) : S(0);
    if (has_var) ++n_with_var_;
    ++n_used_;
    if (++fill_ == K) flush();
    return true;
  }

  template <typename Derived>
  bool add_point(const Eigen::MatrixBase<Derived>& phi, S z, S var = S(-1)) {
    static_assert(Derived::SizeAtCompileTime == M, "phi must have M entries");
    S tmp[M];
    for (int i = 0; i < M; ++i) tmp[i] = phi(i);
    return add_point(tmp, z, var);
  }

  // n points: phi row-major n x M (row k = mode-shape values at point k),
  // z[n] deflections [m], var[n] variances [m^2] or nullptr (eq. 4b).
  // Returns the number of points used. n <= 0 or null pointers add nothing.
  int add_points(const S* phi, const S* z, const S* var, int n) {
    if (phi == nullptr || z == nullptr || n <= 0) return 0;
    int used = 0;
    for (int k = 0; k < n; ++k) {
      used += add_point(phi + static_cast<long>(k) * M, z[k], var ? var[k] : S(-1)) ? 1 : 0;
    }
    return used;
  }

  int n_used() const { return n_used_; }
  int n_nonfinite() const { return n_nonfinite_; }

  // Eqs. 3-4 for the points entered since reset(). Fills out; returns its status.
  ModalStatus solve(Record& out) {
    flush();
    out.a_coarse.setZero();
    out.cov_a.setZero();
    out.n_used = n_used_;
    out.n_nonfinite = n_nonfinite_;
    out.n_bad_variance = n_bad_var_;
    out.per_point_variance = n_used_ > 0 && n_with_var_ == n_used_;
    out.condition_number = std::numeric_limits<S>::infinity();
    out.eig_min = out.eig_max = S(0);
    out.sigma2_residual_m2 = S(0);
    const int min_pts = cfg_.min_points > M + 1 ? cfg_.min_points : M + 1;
    if (!(cfg_.max_condition >= S(1)) || !(cfg_.sigma_e_m >= S(0)) || (n_with_var_ > 0 && n_with_var_ != n_used_)) {
      return out.status = ModalStatus::BadInput;
    }
    if (n_used_ < min_pts) return out.status = ModalStatus::TooFewPoints;

    // M_Y is accumulated in its lower triangle; complete it.
    for (int j = 0; j < M; ++j)
      for (int i = j + 1; i < M; ++i) my_(j, i) = my_(i, j);

    eig_.compute(my_, Eigen::EigenvaluesOnly);
    if (eig_.info() != Eigen::Success) return out.status = ModalStatus::IllConditioned;
    out.eig_min = eig_.eigenvalues()(0);
    out.eig_max = eig_.eigenvalues()(M - 1);
    if (!(out.eig_min > S(0)) || !(out.eig_max > S(0)) || !std::isfinite(out.eig_max)) {
      return out.status = ModalStatus::IllConditioned;
    }
    out.condition_number = out.eig_max / out.eig_min;
    if (!(out.condition_number <= cfg_.max_condition)) return out.status = ModalStatus::IllConditioned;

    llt_.compute(my_);
    if (llt_.info() != Eigen::Success) return out.status = ModalStatus::IllConditioned;

    out.a_coarse = b_;
    llt_.solveInPlace(out.a_coarse);  // eq. 3
    const S rss = zz_ - b_.dot(out.a_coarse);
    out.sigma2_residual_m2 = rss > S(0) ? rss / S(n_used_ - M) : S(0);

    inv_.setIdentity();
    llt_.solveInPlace(inv_);  // M_Y^-1
    if (out.per_point_variance) {
      for (int j = 0; j < M; ++j)
        for (int i = j + 1; i < M; ++i) g_(j, i) = g_(i, j);
      tmp_.noalias() = inv_ * g_;
      out.cov_a.noalias() = tmp_ * inv_;  // eq. 4a
    } else {
      const S s2 = cfg_.sigma_e_m > S(0) ? cfg_.sigma_e_m * cfg_.sigma_e_m : out.sigma2_residual_m2;
      out.cov_a = s2 * inv_;  // eq. 4b
    }
    for (int j = 0; j < M; ++j)
      for (int i = j + 1; i < M; ++i) {
        const S m = S(0.5) * (out.cov_a(i, j) + out.cov_a(j, i));
        out.cov_a(i, j) = out.cov_a(j, i) = m;
      }
    if (!out.a_coarse.allFinite() || !out.cov_a.allFinite()) {
      out.a_coarse.setZero();
      out.cov_a.setZero();
      return out.status = ModalStatus::IllConditioned;
    }
    return out.status = ModalStatus::Ok;
  }

  // M_Y (lower triangle complete after solve(); the full matrix then).
  const MatM& modal_correlation() const { return my_; }
  const VecM& projection() const { return b_; }

 private:
  bool skip_nonfinite() {
    ++n_nonfinite_;
    return false;
  }

  // Folds the gathered chunk into M_Y, b, G and sum z^2.
  void flush() {
    if (fill_ == 0) return;
    for (int k = fill_; k < K; ++k) {  // unused columns contribute nothing
      chunk_.col(k).setZero();
      zc_(k) = S(0);
      wc_(k) = S(0);
    }
    my_.template selfadjointView<Eigen::Lower>().rankUpdate(chunk_);
    b_.noalias() += chunk_ * zc_;
    zz_ += zc_.squaredNorm();
    if (n_with_var_ > 0) {
      for (int k = 0; k < K; ++k) chunk_.col(k) *= wc_(k);
      g_.template selfadjointView<Eigen::Lower>().rankUpdate(chunk_);
    }
    fill_ = 0;
  }

  Config cfg_;
  MatM my_;  // M_Y, lower triangle while accumulating
  MatM g_;   // sum s_k^2 Phi Phi^T, lower triangle while accumulating
  VecM b_;   // <Phi, z>_Y
  S zz_ = S(0);
  Eigen::Matrix<S, M, K> chunk_;  // gathered mode-shape columns
  Eigen::Matrix<S, K, 1> zc_;
  Eigen::Matrix<S, K, 1> wc_;  // per-point standard deviations
  int fill_ = 0;
  int n_used_ = 0, n_nonfinite_ = 0, n_bad_var_ = 0, n_with_var_ = 0;
  Eigen::SelfAdjointEigenSolver<MatM> eig_;
  Eigen::LLT<MatM> llt_;
  MatM inv_;
  MatM tmp_;
};

}  // namespace fsw_base
