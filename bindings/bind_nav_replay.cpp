// Binding of a log replayed through the navigation filter in one call
// (fsw/app/nav_replay.hpp): nav_replay(cfg, streams...) -> dict of arrays.
// The arrays are checked here (shapes, finiteness, unit quaternions) and
// raise ValueError naming the argument; the replay runs without the GIL.
#include <pybind11/numpy.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bind.hpp"
#include "fsw/app/nav_replay.hpp"
#include "nav_config.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {
using Cfg = fsw::NavConfig<double>;
using Flags = py::array_t<bool, py::array::c_style | py::array::forcecast>;

// The array's rows: shape (rows,) + tail, every value finite.
py::ssize_t checked_rows(const Arr& a, const std::vector<py::ssize_t>& tail, const char* name, py::ssize_t rows = -1) {
  bool ok = a.ndim() == py::ssize_t(1 + tail.size()) && (rows < 0 || a.shape(0) == rows);
  for (std::size_t i = 0; ok && i < tail.size(); ++i) ok = a.shape(py::ssize_t(1 + i)) == tail[i];
  if (!ok) {
    std::string want = "(" + (rows < 0 ? std::string("N") : std::to_string(rows));
    for (const auto d : tail) want += ", " + std::to_string(d);
    throw py::value_error(std::string(name) + ": expected shape " + want + (tail.empty() ? ",)" : ")") + ", got " +
                          shape_str(a));
  }
  const double* p = a.data();
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(p[i])) {
      throw py::value_error(std::string(name) + ": element " + std::to_string(i) + " (flat) is not finite");
    }
  }
  return a.shape(0);
}

// The replay in scalar S over the checked arrays; results into the double outputs.
template <typename S>
fsw::NavReplaySummary run_in(const Cfg& cfg, const fsw::NavReplayLog<double>& in,
                             const fsw::NavReplayOutput<double>& o) {
  auto rep = std::make_unique<fsw::NavReplay<S>>(nav_config_as<S>(cfg));
  if (!rep->config_ok()) throw py::value_error(std::string("cfg.") + rep->config_invalid_field() + ": invalid value");
  const long n = in.n_imu, m = in.n_pose;
  auto conv = [](const double* p, long count) { return std::vector<S>(p, p + count); };
  const std::vector<S> accel = conv(in.accel_b_mps2, 3 * n), gyro = conv(in.omega_bi_b_rps, 3 * n);
  const std::vector<S> r = conv(in.pose_r_hill_m, 3 * m), q = conv(in.pose_q_hb_wxyz, 4 * m);
  const std::vector<S> R = conv(in.pose_R, 36 * m), v0 = conv(in.pose_v0_sigma_mps, m);
  std::vector<S> innov(6 * m, S(0)), innov_cov(36 * m, S(0)), nis(m, S(0)), ll(m, S(0));
  std::vector<S> states(o.states != nullptr ? 10 * n : 0, S(0));
  fsw::NavReplayLog<S> log;
  log.imu_t_s = in.imu_t_s;
  log.accel_b_mps2 = accel.data();
  log.omega_bi_b_rps = gyro.data();
  log.n_imu = n;
  log.pose_t_capture_s = in.pose_t_capture_s;
  log.pose_t_fuse_s = in.pose_t_fuse_s;
  log.pose_r_hill_m = r.data();
  log.pose_q_hb_wxyz = q.data();
  log.pose_R = R.data();
  log.pose_run_start = in.pose_run_start;
  log.pose_v0_sigma_mps = v0.data();
  log.n_pose = m;
  log.t_init_s = in.t_init_s;
  fsw::NavReplayOutput<S> out;
  out.innovation = innov.data();
  out.innovation_cov = innov_cov.data();
  out.nis = nis.data();
  out.log_likelihood = ll.data();
  out.fused = o.fused;
  out.states = o.states != nullptr ? states.data() : nullptr;
  fsw::NavReplaySummary summary;
  {
    py::gil_scoped_release release;
    summary = rep->run(log, out);
  }
  std::copy(innov.begin(), innov.end(), o.innovation);
  std::copy(innov_cov.begin(), innov_cov.end(), o.innovation_cov);
  std::copy(nis.begin(), nis.end(), o.nis);
  std::copy(ll.begin(), ll.end(), o.log_likelihood);
  if (o.states != nullptr) std::copy(states.begin(), states.end(), o.states);
  return summary;
}

py::dict replay(const Cfg& cfg, const Arr& imu_t, const Arr& accel, const Arr& gyro, const Arr& pose_tc,
                const Arr& pose_tf, const Arr& pose_r, const Arr& pose_q, const Arr& pose_R, const Flags& run_start,
                const Arr& v0_sigma, double t_init, bool record_states, const std::string& scalar) {
  const py::ssize_t n = checked_rows(imu_t, {}, "imu_t_s");
  checked_rows(accel, {3}, "accel_b_mps2", n);
  checked_rows(gyro, {3}, "omega_bi_b_rps", n);
  const py::ssize_t m = checked_rows(pose_tc, {}, "pose_t_capture_s");
  if (m < 1) throw py::value_error("pose_t_capture_s: at least one pose is needed (the first initialises the filter)");
  checked_rows(pose_tf, {}, "pose_t_fuse_s", m);
  checked_rows(pose_r, {3}, "pose_r_hill_m", m);
  checked_rows(pose_q, {4}, "pose_q_hb_wxyz", m);
  checked_rows(pose_R, {6, 6}, "pose_R", m);
  checked_rows(v0_sigma, {}, "pose_v0_sigma_mps", m);
  if (run_start.ndim() != 1 || run_start.shape(0) != m) {
    throw py::value_error("pose_run_start: expected shape (" + std::to_string(m) + ",)");
  }
  for (py::ssize_t j = 0; j < m; ++j) {
    const double* q = pose_q.data() + 4 * j;
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (std::abs(norm - 1.0) > kUnitTol) {
      throw py::value_error("pose_q_hb_wxyz: quaternion " + std::to_string(j) +
                            " [w, x, y, z] must have unit norm, got " + std::to_string(norm));
    }
  }
  finite(t_init, "t_init_s");
  if (scalar != "double" && scalar != "float")
    throw py::value_error("scalar: 'double' or 'float', got '" + scalar + "'");

  py::array_t<double> innovation({m, py::ssize_t(6)});
  py::array_t<double> innovation_cov({m, py::ssize_t(6), py::ssize_t(6)});
  py::array_t<double> nis(m), loglik(m);
  py::array_t<bool> fused(m);
  py::object states = py::none();
  fsw::NavReplayOutput<double> out;
  out.innovation = innovation.mutable_data();
  out.innovation_cov = innovation_cov.mutable_data();
  out.nis = nis.mutable_data();
  out.log_likelihood = loglik.mutable_data();
  out.fused = fused.mutable_data();
  std::fill(out.innovation, out.innovation + 6 * m, 0.0);
  std::fill(out.innovation_cov, out.innovation_cov + 36 * m, 0.0);
  std::fill(out.nis, out.nis + m, 0.0);
  std::fill(out.log_likelihood, out.log_likelihood + m, 0.0);
  std::fill(out.fused, out.fused + m, false);
  if (record_states) {
    py::array_t<double> s({n, py::ssize_t(10)});
    out.states = s.mutable_data();
    std::fill(out.states, out.states + 10 * n, 0.0);
    states = s;
  }
  fsw::NavReplayLog<double> log;
  log.imu_t_s = imu_t.data();
  log.accel_b_mps2 = accel.data();
  log.omega_bi_b_rps = gyro.data();
  log.n_imu = long(n);
  log.pose_t_capture_s = pose_tc.data();
  log.pose_t_fuse_s = pose_tf.data();
  log.pose_r_hill_m = pose_r.data();
  log.pose_q_hb_wxyz = pose_q.data();
  log.pose_R = pose_R.data();
  log.pose_run_start = run_start.data();
  log.pose_v0_sigma_mps = v0_sigma.data();
  log.n_pose = long(m);
  log.t_init_s = t_init;
  const fsw::NavReplaySummary summary =
      scalar == "float" ? run_in<float>(cfg, log, out) : run_in<double>(cfg, log, out);
  if (!summary.ok()) {
    throw py::value_error("P0 of pose " + std::to_string(summary.failed_pose) + ": " + fsw::to_string(summary.status) +
                          " (" + fsw::to_string(summary.detail) + ")");
  }
  py::dict d;
  d["innovation"] = innovation;
  d["innovation_cov"] = innovation_cov;
  d["nis"] = nis;
  d["log_likelihood"] = loglik;
  d["fused"] = fused;
  d["states"] = states;
  d["predicts_rejected"] = summary.predicts_rejected;
  return d;
}

}  // namespace

void bind_nav_replay(py::module_& m) {
  m.def("nav_replay", &replay, py::arg("cfg"), py::arg("imu_t_s"), py::arg("accel_b_mps2"), py::arg("omega_bi_b_rps"),
        py::arg("pose_t_capture_s"), py::arg("pose_t_fuse_s"), py::arg("pose_r_hill_m"), py::arg("pose_q_hb_wxyz"),
        py::arg("pose_R"), py::arg("pose_run_start"), py::arg("pose_v0_sigma_mps"), py::arg("t_init_s"),
        py::arg("record_states") = false, py::arg("scalar") = "double",
        "A log replayed through a fresh 9-state NavUkf(cfg) (scalar 'double', or 'float': the float build), as the "
        "flight application steps it: pose 0 "
        "initialises it at t_init_s, every later IMU sample is a predict, a pose flagged in pose_run_start resets "
        "it at the first tick at or after its capture, the others are fused once the tick reaches their "
        "pose_t_fuse_s. Returns a dict: innovation (M, 6), innovation_cov (M, 6, 6), nis (M,), log_likelihood "
        "(M,), fused (M,) bool (rows not fused are zero), states (N, 10) [r, v, q_wxyz] after each tick or None, "
        "predicts_rejected. ValueError for a bad array, configuration or a run's P0 that does not factor.");
}
