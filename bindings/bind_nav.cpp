// Bindings of the navigation filter (fsw/nav_ukf.hpp): NavConfig, NavUkf
// (9-state, double) and its step record. Arrays are checked here (shape,
// finiteness, unit quaternion) and raise ValueError naming the argument; the
// flight code's own BadInput paths remain for what only it can judge
// (timing, history, configuration).
#include <string>

#include "bind.hpp"
#include "fsw/nav/nav_ukf.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {
using Cfg = fsw::NavConfig<double>;
using Ukf = fsw::NavUkf<double, false>;
using Rec = Ukf::Record;

void bind_config(py::module_& m) {
  py::class_<Cfg>(m, "NavConfig", "Navigation filter configuration (plain struct, all fields read/write, SI units).")
      .def(py::init<>())
      .def_readwrite("n_radps", &Cfg::n_radps, "Orbit rate n [rad/s]; default 500 km circular.")
      .def_readwrite("dt_imu_s", &Cfg::dt_imu_s, "Nominal IMU period [s] (0.1).")
      .def_readwrite("accel_sigma_mps2", &Cfg::accel_sigma_mps2,
                     "Accelerometer white noise, 1-sigma per axis, per sample held over its step [m/s^2].")
      .def_readwrite("gyro_sigma_rps", &Cfg::gyro_sigma_rps,
                     "Gyro white noise, 1-sigma per axis, per sample held over its step [rad/s].")
      .def_readwrite("gyro_bias_walk", &Cfg::gyro_bias_walk, "Gyro bias random walk [rad/s/sqrt(s)] (15-state only).")
      .def_readwrite("accel_bias_walk", &Cfg::accel_bias_walk,
                     "Accelerometer bias random walk [m/s^2/sqrt(s)] (15-state only).")
      .def_readwrite("gate_chi2", &Cfg::gate_chi2,
                     "NIS gate of the 6-dof pose update (22.46: p = 0.999); <= 0 disables.")
      .def_readwrite("max_delay_s", &Cfg::max_delay_s, "How late a pose may arrive [s] (0.5).")
      .def_readwrite("time_tol_s", &Cfg::time_tol_s, "A capture time within this of an IMU tick is on it [s].")
      .def_readwrite("max_dt_s", &Cfg::max_dt_s, "Longest accepted off-grid predict step [s].")
      .def_readwrite("max_gap_s", &Cfg::max_gap_s, "Longest run of lost IMU ticks coasted through [s].")
      .def_readwrite("gap_accel_sigma_mps2", &Cfg::gap_accel_sigma_mps2,
                     "Specific-force uncertainty of a lost IMU tick bridged by the next sample [m/s^2].")
      .def_readwrite("gap_gyro_sigma_rps", &Cfg::gap_gyro_sigma_rps,
                     "Rate uncertainty of a lost IMU tick bridged by the next sample [rad/s].")
      .def_readwrite("alpha", &Cfg::alpha, "UKF sigma-point spread (1).")
      .def_readwrite("beta", &Cfg::beta, "UKF prior-distribution term (2).")
      .def_readwrite("kappa", &Cfg::kappa, "UKF secondary scaling (0).")
      .def_readwrite("var_min", &Cfg::var_min, "Floor of every variance.")
      .def_readwrite("pos_var_max_m2", &Cfg::pos_var_max_m2, "Ceiling of position variances [m^2].")
      .def_readwrite("vel_var_max_m2ps2", &Cfg::vel_var_max_m2ps2, "Ceiling of velocity variances [m^2/s^2].")
      .def_readwrite("att_var_max_rad2", &Cfg::att_var_max_rad2, "Ceiling of attitude variances [rad^2].")
      .def_readwrite("gyro_bias_var_max", &Cfg::gyro_bias_var_max, "Ceiling of gyro-bias variances.")
      .def_readwrite("accel_bias_var_max", &Cfg::accel_bias_var_max, "Ceiling of accel-bias variances.")
      .def_readwrite("quat_unit_tol", &Cfg::quat_unit_tol, "Accepted | |q| - 1 | inside the flight code.")
      .def("__repr__", [](const Cfg& c) {
        return "NavConfig(n_radps=" + std::to_string(c.n_radps) + ", dt_imu_s=" + std::to_string(c.dt_imu_s) +
               ", accel_sigma_mps2=" + std::to_string(c.accel_sigma_mps2) +
               ", gyro_sigma_rps=" + std::to_string(c.gyro_sigma_rps) + ", gate_chi2=" + std::to_string(c.gate_chi2) +
               ", max_delay_s=" + std::to_string(c.max_delay_s) + ")";
      });
}

void bind_record(py::module_& m) {
  py::class_<Rec>(m, "NavStepRecord", "What one navigation filter step did.")
      .def_property_readonly(
          "status", [](const Rec& r) { return std::string(fsw::to_string(r.status)); },
          "'ok' | 'gated' | 'not_pos_def' | 'bad_input'")
      .def_property_readonly(
          "detail", [](const Rec& r) { return std::string(fsw::to_string(r.detail)); },
          "Finer reason, e.g. 'too_old', 'off_tick', 'time_not_increasing'.")
      .def_readonly("fused", &Rec::fused)
      .def_readonly("t_s", &Rec::t_s, "Time of the step (capture time for a pose) [s].")
      .def_property_readonly(
          "innovation", [](const Rec& r) { return to_numpy(r.innovation); },
          "(6,) [r_meas - r_pred (Hill, m), q_meas [-] q_pred (rad, body)]; zeros for predict.")
      .def_property_readonly(
          "innovation_cov", [](const Rec& r) { return to_numpy(r.innovation_cov); }, "(6, 6)")
      .def_readonly("nis", &Rec::nis, "Normalised innovation squared y^T S^-1 y.")
      .def_readonly("log_likelihood", &Rec::log_likelihood, "log p_z (Rogers-Marcovitz, Table 1 step 14).")
      .def("__repr__", [](const Rec& r) {
        return std::string("NavStepRecord(status='") + fsw::to_string(r.status) + "', detail='" +
               fsw::to_string(r.detail) + "', fused=" + (r.fused ? "True" : "False") +
               ", nis=" + std::to_string(r.nis) + ")";
      });
}

void bind_ukf(py::module_& m) {
  py::class_<Ukf>(m, "NavUkf",
                  "9-state multiplicative quaternion UKF (double): Hill-frame position, velocity and q_hb; "
                  "covariance over [dr_hill, dv_hill, dtheta_body]. IMU predict, pose update with delay.")
      .def(py::init([](const Cfg& cfg) {
             Ukf u(cfg);
             if (!u.config_ok())
               throw py::value_error(std::string("cfg.") + u.config_invalid_field() + ": invalid value");
             return u;
           }),
           py::arg("cfg"))
      .def(
          "init",
          [](Ukf& u, double t, const Arr& r, const Arr& v, const Arr& q, const Arr& P0) {
            Ukf::State x;
            x.r_hill_m = vec<3>(r, "r_hill_m");
            x.v_hill_mps = vec<3>(v, "v_hill_mps");
            x.q_hb = quat(q, "q_hb_wxyz");
            const Rec rec = u.init(finite(t, "t_s"), x, mat<9, 9>(P0, "P0"));
            if (!rec.ok())
              throw py::value_error(std::string("P0: ") + fsw::to_string(rec.status) + " (" +
                                    fsw::to_string(rec.detail) + ")");
            return rec;
          },
          py::arg("t_s"), py::arg("r_hill_m"), py::arg("v_hill_mps"), py::arg("q_hb_wxyz"), py::arg("P0"),
          "Sets the state at t_s [s]; P0 (9, 9) over [dr, dv, dtheta]. ValueError if P0 does not factor.")
      .def(
          "predict",
          [](Ukf& u, double t, const Arr& a, const Arr& w) {
            return u.predict(finite(t, "t_s"), vec<3>(a, "accel_b_mps2"), vec<3>(w, "omega_bi_b_rps"));
          },
          py::arg("t_s"), py::arg("accel_b_mps2"), py::arg("omega_bi_b_rps"),
          "IMU sample (specific force, body [m/s^2]; omega_BI_B [rad/s]) held over (t_current, t_s]; "
          "moves the filter to t_s.")
      .def(
          "update_pose",
          [](Ukf& u, double t, const Arr& r, const Arr& q, const Arr& R) {
            return u.update_pose(finite(t, "t_capture_s"), vec<3>(r, "r_hill_m"), quat(q, "q_hb_wxyz"),
                                 mat<6, 6>(R, "R"));
          },
          py::arg("t_capture_s"), py::arg("r_hill_m"), py::arg("q_hb_wxyz"), py::arg("R"),
          "Pose captured at t_capture_s (an IMU tick, at most max_delay_s old); R (6, 6) over "
          "[position m^2, attitude rad^2 (body-frame boxminus)].")
      .def_property_readonly("t_s", &Ukf::t_s)
      .def_property_readonly("r_hill_m", [](const Ukf& u) { return to_numpy(u.state().r_hill_m); })
      .def_property_readonly("v_hill_mps", [](const Ukf& u) { return to_numpy(u.state().v_hill_mps); })
      .def_property_readonly(
          "q_hb", [](const Ukf& u) { return quat_to_numpy(u.state().q_hb); }, "[w, x, y, z]")
      .def_property_readonly(
          "P", [](const Ukf& u) { return to_numpy(u.P()); }, "(9, 9) over [dr, dv, dtheta].")
      .def_property_readonly("initialized", &Ukf::initialized)
      .def_property_readonly("history_count", &Ukf::history_count)
      .def_property_readonly_static("history_capacity", [](py::object) { return Ukf::kHistoryCapacity; })
      .def(
          "state", [](const Ukf& u) { return to_numpy(u.state().stored()); }, "(10,) [r(3), v(3), q_wxyz(4)].");
}

}  // namespace

void bind_nav(py::module_& m) {
  bind_config(m);
  bind_record(m);
  bind_ukf(m);
}
