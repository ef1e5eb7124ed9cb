// Shape reconstruction with its uncertainty (section V, eqs. 8-9,
// of "Shape, Motion, and Parameter Estimation of Large Flexible Space
// Structures using Range Images" (Lichter and Dubowsky)).
//
//   z^(x)   = A^T Phi^(x)                 estimated deflection [m]   (eq. 8)
//   var(x)  = Phi^(x)^T P_AA Phi^(x)      its variance [m^2]         (eq. 9)
//
// Phi^(x) are the estimator's mode shapes at the requested points (row-major
// n x M, one row per point); A and P_AA come from either modal filter
// (amplitudes() / amplitude_cov()). Eq. 9 assumes the mode shapes are exact;
// mode-shape error adds to the true error and is not in var.
// Real-time core: no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <limits>

#include "fsw/math/step_status.hpp"

namespace fsw {

struct ShapeRecord {
  StepStatus status = StepStatus::BadInput;
  int n_points = 0;     // points evaluated
  int n_nonfinite = 0;  // points whose mode-shape row was not finite (output NaN)
};

// Eqs. 8-9 at one point.
template <typename S, int M>
inline void shape_at(const Eigen::Matrix<S, M, 1>& a, const Eigen::Matrix<S, M, M>& cov_a, const S* phi, S& z_m,
                     S& var_m2) {
  const Eigen::Map<const Eigen::Matrix<S, M, 1>> p(phi);
  z_m = a.dot(p);
  var_m2 = p.dot(cov_a.template selfadjointView<Eigen::Lower>() * p);
}

// Eqs. 8-9 at n points. var_m2 may be null (no uncertainty wanted).
template <typename S, int M>
inline ShapeRecord reconstruct_shape(const Eigen::Matrix<S, M, 1>& a, const Eigen::Matrix<S, M, M>& cov_a, const S* phi,
                                     int n, S* z_m, S* var_m2) {
  ShapeRecord rec;
  if (phi == nullptr || z_m == nullptr || n < 0 || !a.allFinite() || !cov_a.allFinite()) return rec;
  for (int k = 0; k < n; ++k) {
    const S* row = phi + static_cast<long>(k) * M;
    bool finite = true;
    for (int i = 0; i < M; ++i) finite = finite && std::isfinite(row[i]);
    if (!finite) {
      ++rec.n_nonfinite;
      z_m[k] = std::numeric_limits<S>::quiet_NaN();
      if (var_m2) var_m2[k] = std::numeric_limits<S>::quiet_NaN();
      continue;
    }
    const Eigen::Map<const Eigen::Matrix<S, M, 1>> p(row);
    z_m[k] = a.dot(p);
    if (var_m2) {
      S v = S(0);
      for (int j = 0; j < M; ++j) v += p(j) * cov_a.col(j).dot(p);
      var_m2[k] = v;
    }
  }
  rec.n_points = n;
  rec.status = StepStatus::Ok;
  return rec;
}

}  // namespace fsw
