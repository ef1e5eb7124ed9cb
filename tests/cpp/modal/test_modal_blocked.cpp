// The blocked accumulation of the modal decomposition (points gathered into a
// chunk of K, one symmetric rank-K update of M_Y per chunk) against a plain
// per-point reference written here: M_Y = sum_k phi_k phi_k^T, b = sum_k
// phi_k z_k, G = sum_k s_k^2 phi_k phi_k^T, over the same finite points.
// Point counts are not multiples of the chunk, and non-finite points (NaN or
// Inf deflection, NaN or Inf mode value) and bad variances are interleaved:
// they must be skipped and counted exactly as the per-point path does.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "fsw/modal/modal_decomposition.hpp"

using namespace fsw;

namespace {

template <int M>
struct Points {
  std::vector<double> phi, z, var;  // phi row-major n x M
  int n = 0;
  int n_nonfinite = 0, n_bad_var = 0;
};

// Plate-like shapes at random points; every 7th point has a NaN deflection,
// every 11th an Inf or NaN mode value, and (with variances) every 13th a
// non-positive variance.
template <int M>
Points<M> make_points(int n, unsigned seed, bool with_var) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Points<M> p;
  p.n = n;
  p.phi.resize(static_cast<size_t>(n) * M);
  p.z.resize(n);
  p.var.resize(n);
  for (int k = 0; k < n; ++k) {
    const double x = u(rng), y = u(rng);
    for (int i = 0; i < M; ++i) {
      const int a = 1 + i % 7, b = 1 + i / 7;
      p.phi[static_cast<size_t>(k) * M + i] = std::sin(a * M_PI * x) * std::sin(b * M_PI * y) + 0.1 * (i == 0);
    }
    p.z[k] = 0.01 * (u(rng) - 0.5);
    p.var[k] = 1e-4 * (1.0 + 3.0 * u(rng));
    if (k % 7 == 3) {
      p.z[k] = std::numeric_limits<double>::quiet_NaN();
      ++p.n_nonfinite;
    } else if (k % 11 == 5) {
      p.phi[static_cast<size_t>(k) * M + (k % M)] =
          (k % 2) ? std::numeric_limits<double>::infinity() : std::numeric_limits<double>::quiet_NaN();
      ++p.n_nonfinite;
    } else if (with_var && k % 13 == 6) {
      p.var[k] = (k % 2) ? 0.0 : std::numeric_limits<double>::quiet_NaN();
      ++p.n_bad_var;
    }
  }
  return p;
}

template <int M>
struct Reference {
  Eigen::MatrixXd my, g;
  Eigen::VectorXd b;
  int n_used = 0;
};

// The per-point sums, one outer product per finite point.
template <int M>
Reference<M> per_point(const Points<M>& p, bool with_var) {
  Reference<M> r;
  r.my = Eigen::MatrixXd::Zero(M, M);
  r.g = Eigen::MatrixXd::Zero(M, M);
  r.b = Eigen::VectorXd::Zero(M);
  for (int k = 0; k < p.n; ++k) {
    const Eigen::Map<const Eigen::VectorXd> phi(p.phi.data() + static_cast<size_t>(k) * M, M);
    if (!std::isfinite(p.z[k]) || !phi.allFinite()) continue;
    if (with_var && !(std::isfinite(p.var[k]) && p.var[k] > 0.0)) continue;
    r.my += phi * phi.transpose();
    if (with_var) r.g += p.var[k] * phi * phi.transpose();
    r.b += phi * p.z[k];
    ++r.n_used;
  }
  return r;
}

double rel_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& ref) {
  return (a - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff();
}

template <int M, int K>
void blocked_equals_per_point(int n, bool with_var) {
  SCOPED_TRACE(::testing::Message() << "M=" << M << " K=" << K << " n=" << n << " var=" << with_var);
  const Points<M> p = make_points<M>(n, 17u + static_cast<unsigned>(n), with_var);
  const Reference<M> ref = per_point<M>(p, with_var);
  ModalDecomposition<double, M, K> d;
  const int used = d.add_points(p.phi.data(), p.z.data(), with_var ? p.var.data() : nullptr, n);
  ModalDecompositionRecord<double, M> rec;
  ASSERT_EQ(d.solve(rec), ModalStatus::Ok);
  EXPECT_EQ(used, ref.n_used);
  EXPECT_EQ(rec.n_used, ref.n_used);
  EXPECT_EQ(rec.n_nonfinite, p.n_nonfinite);
  EXPECT_EQ(rec.n_bad_variance, with_var ? p.n_bad_var : 0);
  EXPECT_EQ(rec.per_point_variance, with_var);
  EXPECT_LE(rel_diff(d.modal_correlation(), ref.my), 1e-12);
  EXPECT_LE(rel_diff(d.projection(), ref.b), 1e-12);

  // The estimate and its covariance from the reference sums (eq. 3, eq. 4a / 4b).
  const Eigen::MatrixXd inv = ref.my.inverse();
  const Eigen::VectorXd a = inv * ref.b;
  EXPECT_LE(rel_diff(rec.a_coarse, a), 1e-9);
  if (with_var) {
    const Eigen::MatrixXd cov = inv * ref.g * inv;
    EXPECT_LE(rel_diff(rec.cov_a, cov), 1e-9);
  }

  // The flight class with a chunk of one point (rank-one updates) agrees too.
  ModalDecomposition<double, M, 1> single;
  EXPECT_EQ(single.add_points(p.phi.data(), p.z.data(), with_var ? p.var.data() : nullptr, n), used);
  ModalDecompositionRecord<double, M> rec1;
  ASSERT_EQ(single.solve(rec1), ModalStatus::Ok);
  EXPECT_EQ(rec1.n_nonfinite, rec.n_nonfinite);
  EXPECT_EQ(rec1.n_bad_variance, rec.n_bad_variance);
  EXPECT_LE(rel_diff(d.modal_correlation(), single.modal_correlation()), 1e-12);
  EXPECT_LE(rel_diff(rec.a_coarse, rec1.a_coarse), 1e-9);
  EXPECT_LE(rel_diff(rec.cov_a, rec1.cov_a), 1e-9);
}

}  // namespace

TEST(ModalBlockedTest, BlockedAccumulationEqualsPerPointReference) {
  for (bool with_var : {false, true}) {
    for (int n : {97, 1000, 1001, 3333}) {  // not multiples of the chunk
      blocked_equals_per_point<50, 32>(n, with_var);
      blocked_equals_per_point<7, 32>(n, with_var);
    }
    blocked_equals_per_point<7, 5>(61, with_var);
    blocked_equals_per_point<50, 64>(1001, with_var);
  }
}

TEST(ModalBlockedTest, PointsOneAtATimeEqualThePointerPath) {
  const Points<50> p = make_points<50>(515, 3u, true);
  ModalDecomposition<double, 50> bulk, one;
  bulk.add_points(p.phi.data(), p.z.data(), p.var.data(), p.n);
  for (int k = 0; k < p.n; ++k) one.add_point(p.phi.data() + static_cast<size_t>(k) * 50, p.z[k], p.var[k]);
  ModalDecompositionRecord<double, 50> rb, ro;
  ASSERT_EQ(bulk.solve(rb), ModalStatus::Ok);
  ASSERT_EQ(one.solve(ro), ModalStatus::Ok);
  EXPECT_EQ(rb.n_used, ro.n_used);
  EXPECT_EQ(rb.n_nonfinite, ro.n_nonfinite);
  EXPECT_EQ(rb.n_bad_variance, ro.n_bad_variance);
  EXPECT_EQ(bulk.modal_correlation(), one.modal_correlation());  // same chunks, same arithmetic
  EXPECT_EQ(rb.a_coarse, ro.a_coarse);
}
