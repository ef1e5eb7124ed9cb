// Status and record returned by every estimator step.
//
// A step never throws and never asserts on data: it returns a StepStatus and
// a StepRecord saying what it did (innovation, its covariance, NIS, the
// measurement log-likelihood, fused or rejected). On any status other than
// Ok the estimator state is left bit-identical.
// Real-time core: no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>

namespace fsw {

enum class StepStatus : std::uint8_t {
  Ok = 0,         // step done (a measurement was fused, or a predict applied)
  Gated = 1,      // measurement rejected by the chi-square gate; state untouched
  NotPosDef = 2,  // a Cholesky factorisation failed; state untouched
  BadInput = 3,   // non-finite or inconsistent input (see StepDetail); state untouched
};

// Why a step ended as it did; finer than StepStatus, for counters and logs.
enum class StepDetail : std::uint8_t {
  None = 0,
  NonFinite,            // NaN or Inf in an input
  NotInitialized,       // step before a successful init
  BadConfig,            // configuration rejected at construction
  TimeNotIncreasing,    // predict time not after the current time
  StepTooLong,          // predict step longer than the configured maximum
  FromFuture,           // measurement capture time after the current time
  TooOld,               // capture time older than max_delay_s or than the history
  OffTick,              // capture time not on a stored IMU tick
  OutOfSequence,        // capture time before the last fused measurement's
  NonUnitQuaternion,    // quaternion norm too far from 1
  PriorCholesky,        // Cholesky of the state covariance failed
  InnovationCholesky,   // Cholesky of the innovation covariance failed
  PosteriorCholesky,    // updated covariance not positive definite
  FeatureNotImageable,  // a predicted image feature is behind the lens or at infinity
  CovarianceRepaired,   // status Ok: the covariance factored only after a relative diagonal jitter (rounding)
};

constexpr const char* to_string(StepStatus s) {
  switch (s) {
    case StepStatus::Ok: return "ok";
    case StepStatus::Gated: return "gated";
    case StepStatus::NotPosDef: return "not_pos_def";
    case StepStatus::BadInput: return "bad_input";
  }
  return "unknown";
}

constexpr const char* to_string(StepDetail d) {
  switch (d) {
    case StepDetail::None: return "none";
    case StepDetail::NonFinite: return "non_finite";
    case StepDetail::NotInitialized: return "not_initialized";
    case StepDetail::BadConfig: return "bad_config";
    case StepDetail::TimeNotIncreasing: return "time_not_increasing";
    case StepDetail::StepTooLong: return "step_too_long";
    case StepDetail::FromFuture: return "from_future";
    case StepDetail::TooOld: return "too_old";
    case StepDetail::OffTick: return "off_tick";
    case StepDetail::OutOfSequence: return "out_of_sequence";
    case StepDetail::NonUnitQuaternion: return "non_unit_quaternion";
    case StepDetail::PriorCholesky: return "prior_cholesky";
    case StepDetail::InnovationCholesky: return "innovation_cholesky";
    case StepDetail::PosteriorCholesky: return "posterior_cholesky";
    case StepDetail::FeatureNotImageable: return "feature_not_imageable";
    case StepDetail::CovarianceRepaired: return "covariance_repaired";
  }
  return "unknown";
}

// Record of one step with an M-dimensional measurement. For a predict the
// innovation fields are zero and fused is false.
template <typename S, int M>
struct StepRecord {
  StepStatus status = StepStatus::BadInput;
  StepDetail detail = StepDetail::None;
  bool fused = false;
  double t_s = 0.0;  // time the step refers to (capture time for a measurement) [s]
  Eigen::Matrix<S, M, 1> innovation = Eigen::Matrix<S, M, 1>::Zero();
  Eigen::Matrix<S, M, M> innovation_cov = Eigen::Matrix<S, M, M>::Zero();
  S nis = S(0);             // y^T S^-1 y
  S log_likelihood = S(0);  // log p_z = -(y^T S^-1 y + log det(2 pi S)) / 2
  bool ok() const { return status == StepStatus::Ok; }
};

}  // namespace fsw
