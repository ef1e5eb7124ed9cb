// A small synthetic log for the replay tests (fsw/app/nav_replay.hpp) and
// the arrays its replay writes.
#pragma once

#include <cmath>
#include <vector>

#include "fsw/app/nav_replay.hpp"

namespace nav_replay_test {

using namespace fsw;

template <typename S>
struct Log {
  std::vector<double> t, tc, tf;
  std::vector<S> acc, gyr, r, q, R, v0;
  std::vector<char> start;  // bool storage without std::vector<bool>
  double t_init = 0.0;

  // 8 s at 10 Hz (the tick at 2.3 s lost), a pose each second captured on a
  // tick and fused 0.2 s later, a new run from the pose at 5 s, the pose at
  // 3 s one metre off (gated when gating is on).
  Log() {
    for (int k = 1; k <= 80; ++k) {
      if (k == 23) continue;
      t.push_back(0.1 * k);
      const double s = 0.1 * k;
      for (const double a : {1e-3 * std::sin(s), 2e-4, -1e-3 * std::cos(s)}) acc.push_back(S(a));
      for (const double w : {0.01, -0.02 * std::sin(0.5 * s), 0.005}) gyr.push_back(S(w));
    }
    for (int i = 0; i <= 7; ++i) {
      tc.push_back(double(i));
      tf.push_back(double(i) + 0.2);
      const double x = 0.1 + 0.001 * i + (i == 3 ? 1.0 : 0.0);
      for (const double v : {x, -0.7, 0.02}) r.push_back(S(v));
      const Quat<S> qi = boxplus(Quat<S>::Identity(), Vec3<S>(S(0.01 * i), S(-0.02 * i), S(0.03)));
      const Vec4<S> w = to_wxyz(qi);
      for (int c = 0; c < 4; ++c) q.push_back(w(c));
      for (int a = 0; a < 6; ++a)
        for (int b = 0; b < 6; ++b) R.push_back(a == b ? S(1e-4) : S(0));
      start.push_back(i == 5);
      v0.push_back(S(i == 5 ? 0.05 : 0.003));
    }
    t_init = 0.0;
  }

  NavReplayLog<S> view() const {
    NavReplayLog<S> v;
    v.imu_t_s = t.data();
    v.accel_b_mps2 = acc.data();
    v.omega_bi_b_rps = gyr.data();
    v.n_imu = long(t.size());
    v.pose_t_capture_s = tc.data();
    v.pose_t_fuse_s = tf.data();
    v.pose_r_hill_m = r.data();
    v.pose_q_hb_wxyz = q.data();
    v.pose_R = R.data();
    v.pose_run_start = reinterpret_cast<const bool*>(start.data());
    v.pose_v0_sigma_mps = v0.data();
    v.n_pose = long(tc.size());
    v.t_init_s = t_init;
    return v;
  }
};

template <typename S>
struct Result {
  std::vector<S> innovation, cov, nis, ll, states;
  std::vector<char> fused;
  explicit Result(const Log<S>& log)
      : innovation(6 * log.tc.size()),
        cov(36 * log.tc.size()),
        nis(log.tc.size()),
        ll(log.tc.size()),
        states(10 * log.t.size()),
        fused(log.tc.size()) {}
  NavReplayOutput<S> view() {
    NavReplayOutput<S> o;
    o.innovation = innovation.data();
    o.innovation_cov = cov.data();
    o.nis = nis.data();
    o.log_likelihood = ll.data();
    o.fused = reinterpret_cast<bool*>(fused.data());
    o.states = states.data();
    return o;
  }
};

}  // namespace nav_replay_test
