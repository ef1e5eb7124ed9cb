// A recorded flight replayed through the navigation filter in one call: the
// ground's use of the flight filter (the gap diagnosis re-runs it over a
// log's IMU and pose streams, bench/gap/replay.py), without a step per call.
//
// What it does is what the flight application does with the same streams:
//   - the first pose initialises the filter at t_init_s (position and
//     attitude from it, its own R; velocity 0 with that pose's v0 sigma);
//     poses captured up to t_init_s are skipped;
//   - every IMU sample k after t_init_s is a predict(t_k, accel_k, omega_k);
//   - a pose that starts a run (the flight filter was reset there) resets
//     the filter at the first tick at or after its capture time: a fresh
//     filter initialised from it at its capture time, then that tick's
//     predict when the tick is later than the capture time;
//   - after each tick, the poses whose fusion time has come (in order, up to
//     the next run start) are fused with update_pose.
// Per pose, the update's record is kept when the filter accepted it (Ok);
// a rejected or gated pose leaves its outputs as the caller set them.
// Times compare with a 1e-9 s tolerance. The arrays are the caller's;
// nothing is allocated.
//
// Real-time core rules hold (fixed-size Eigen, no heap, no exceptions, no
// I/O); every loop is bounded by the samples given.
#pragma once

#include "fsw/math/so3.hpp"
#include "fsw/math/step_status.hpp"
#include "fsw/nav/nav_ukf.hpp"

namespace fsw {

// The streams of one log, row-major arrays owned by the caller.
template <typename S>
struct NavReplayLog {
  const double* imu_t_s = nullptr;    // (n,) increasing; sample k held over (t_{k-1}, t_k]
  const S* accel_b_mps2 = nullptr;    // (n, 3) specific force, body
  const S* omega_bi_b_rps = nullptr;  // (n, 3)
  long n_imu = 0;
  const double* pose_t_capture_s = nullptr;  // (m,) on an IMU tick
  const double* pose_t_fuse_s = nullptr;     // (m,) when the pose is fused (>= its capture time)
  const S* pose_r_hill_m = nullptr;          // (m, 3)
  const S* pose_q_hb_wxyz = nullptr;         // (m, 4)
  const S* pose_R = nullptr;                 // (m, 6, 6) over [position m^2, attitude rad^2]
  const bool* pose_run_start = nullptr;      // (m,) the filter is reset at this pose
  const S* pose_v0_sigma_mps = nullptr;      // (m,) initial velocity sigma where a run starts
  long n_pose = 0;
  double t_init_s = 0.0;  // the first run starts here, from pose 0
};

// Where the replay writes, row-major arrays owned by the caller. Pose rows
// are written only for the poses fused.
template <typename S>
struct NavReplayOutput {
  S* innovation = nullptr;      // (m, 6)
  S* innovation_cov = nullptr;  // (m, 6, 6)
  S* nis = nullptr;             // (m,)
  S* log_likelihood = nullptr;  // (m,)
  bool* fused = nullptr;        // (m,) set true for each pose fused
  S* states = nullptr;          // (n, 10) [r, v, q_wxyz] after each tick from the first predict on; nullptr: none
};

// How a replay ended: Ok, or the status and detail of the initialisation
// that failed and the pose it was made from (the replay stops there).
struct NavReplaySummary {
  StepStatus status = StepStatus::Ok;
  StepDetail detail = StepDetail::None;
  long failed_pose = -1;
  long predicts_rejected = 0;
  long poses_fused = 0;
  bool ok() const { return status == StepStatus::Ok; }
};

template <typename S>
class NavReplay {
 public:
  using Ukf = NavUkf<S, false>;

  explicit NavReplay(const NavConfig<S>& cfg) : cfg_(cfg), ukf_(cfg) {}

  bool config_ok() const { return ukf_.config_ok(); }
  const char* config_invalid_field() const { return ukf_.config_invalid_field(); }

  // Replays the log into out (see the file comment). Needs n_pose >= 1.
  NavReplaySummary run(const NavReplayLog<S>& log, const NavReplayOutput<S>& out);

 private:
  static constexpr double kEps = 1e-9;

  // A fresh filter started from pose j at time t; false (with the reason in
  // summary) when its initialisation fails.
  bool start_run(const NavReplayLog<S>& log, long j, double t, NavReplaySummary& summary);

  NavConfig<S> cfg_;
  Ukf ukf_;
};

template <typename S>
bool NavReplay<S>::start_run(const NavReplayLog<S>& log, long j, double t, NavReplaySummary& summary) {
  const S* R = log.pose_R + 36 * j;
  typename Ukf::Cov P0 = Ukf::Cov::Zero();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      P0(a, b) = R[6 * a + b];
      P0(6 + a, 6 + b) = R[6 * (3 + a) + 3 + b];
    }
  }
  const S v0 = log.pose_v0_sigma_mps[j];
  for (int a = 0; a < 3; ++a) P0(3 + a, 3 + a) = v0 * v0;
  typename Ukf::State x;
  x.r_hill_m = Vec3<S>(log.pose_r_hill_m[3 * j], log.pose_r_hill_m[3 * j + 1], log.pose_r_hill_m[3 * j + 2]);
  x.v_hill_mps.setZero();
  const S* q = log.pose_q_hb_wxyz + 4 * j;
  x.q_hb = from_wxyz(Vec4<S>(q[0], q[1], q[2], q[3]));
  ukf_ = Ukf(cfg_);
  const typename Ukf::Record rec = ukf_.init(t, x, P0);
  if (rec.ok()) return true;
  summary.status = rec.status;
  summary.detail = rec.detail;
  summary.failed_pose = j;
  return false;
}

template <typename S>
NavReplaySummary NavReplay<S>::run(const NavReplayLog<S>& log, const NavReplayOutput<S>& out) {
  NavReplaySummary summary;
  if (!config_ok()) {
    summary.status = StepStatus::BadInput;
    summary.detail = StepDetail::BadConfig;
    return summary;
  }
  const long n = log.n_imu, m = log.n_pose;
  if (m < 1) {
    summary.status = StepStatus::BadInput;
    summary.detail = StepDetail::NotInitialized;
    return summary;
  }
  const double* t = log.imu_t_s;
  const double* tc = log.pose_t_capture_s;
  const double* tf = log.pose_t_fuse_s;
  const double t_init = log.t_init_s;
  if (!start_run(log, 0, t_init, summary)) return summary;
  long j = 1;
  while (j < m && tc[j] <= t_init + kEps) ++j;
  long k0 = 0;
  while (k0 < n && !(t[k0] > t_init + kEps)) ++k0;
  for (long k = k0; k < n; ++k) {
    const double tk = t[k];
    const Vec3<S> a(log.accel_b_mps2[3 * k], log.accel_b_mps2[3 * k + 1], log.accel_b_mps2[3 * k + 2]);
    const Vec3<S> w(log.omega_bi_b_rps[3 * k], log.omega_bi_b_rps[3 * k + 1], log.omega_bi_b_rps[3 * k + 2]);
    if (j < m && log.pose_run_start[j] && tc[j] <= tk + kEps) {
      // A new run (the flight filter was reset): start again from its first pose.
      if (!start_run(log, j, tc[j], summary)) return summary;
      ++j;
      if (tk > tc[j - 1] + kEps && !ukf_.predict(tk, a, w).ok()) ++summary.predicts_rejected;
    } else if (!ukf_.predict(tk, a, w).ok()) {
      ++summary.predicts_rejected;
    }
    if (out.states != nullptr) {
      const auto s = ukf_.state().stored();
      for (int i = 0; i < 10; ++i) out.states[10 * k + i] = s(i);
    }
    while (j < m && tf[j] <= tk + kEps && !log.pose_run_start[j]) {
      const S* q = log.pose_q_hb_wxyz + 4 * j;
      const Vec3<S> r(log.pose_r_hill_m[3 * j], log.pose_r_hill_m[3 * j + 1], log.pose_r_hill_m[3 * j + 2]);
      const Eigen::Map<const Eigen::Matrix<S, 6, 6, Eigen::RowMajor>> R(log.pose_R + 36 * j);
      const typename Ukf::Record rec =
          ukf_.update_pose(tc[j], r, from_wxyz(Vec4<S>(q[0], q[1], q[2], q[3])), typename Ukf::MeasCov(R));
      if (rec.status == StepStatus::Ok) {
        out.fused[j] = true;
        for (int i = 0; i < 6; ++i) out.innovation[6 * j + i] = rec.innovation(i);
        for (int row = 0; row < 6; ++row)
          for (int col = 0; col < 6; ++col) out.innovation_cov[36 * j + 6L * row + col] = rec.innovation_cov(row, col);
        out.nis[j] = rec.nis;
        out.log_likelihood[j] = rec.log_likelihood;
        ++summary.poses_fused;
      }
      ++j;
    }
  }
  return summary;
}

// Compiled once, in fsw_core (instantiate_nav_replay.cpp).
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class NavReplay<double>;
extern template class NavReplay<float>;
#endif

}  // namespace fsw
