// Bindings of the navigation filter (fsw/nav_ukf.hpp): NavConfig, every
// variant the flight code builds (NavUkf: 9 states, double; NavUkfFloat;
// NavUkf15 and NavUkf15Float with the bias states) and their step records. Arrays are checked here (shape,
// finiteness, unit quaternion) and raise ValueError naming the argument; the
// flight code's own BadInput paths remain for what only it can judge
// (timing, history, configuration).
#include <cmath>
#include <memory>
#include <string>

#include "bind.hpp"
#include "fsw/nav/nav_ukf.hpp"
#include "nav_config.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {
using Cfg = fsw::NavConfig<double>;

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

// Three finite doubles from a 1-D array, without the generic accessor's
// per-element checks (the hot path of predict and update_pose).
template <typename S>
fsw::Vec3<S> vec3_as(const Arr& a, const char* name) {
  if (a.ndim() != 1 || a.shape(0) != 3)
    throw py::value_error(std::string(name) + ": expected shape (3,), got " + shape_str(a));
  const double* p = a.data();
  if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
    throw py::value_error(std::string(name) + ": element is not finite");
  return fsw::Vec3<S>(S(p[0]), S(p[1]), S(p[2]));
}

// A C-contiguous (R, C) array of finite doubles, read through its pointer
// (the generic accessor's per-element index checks cost microseconds on a 6 x 6).
template <typename S, int R, int C>
Eigen::Matrix<S, R, C> mat_as(const Arr& a, const char* name) {
  if (a.ndim() != 2 || a.shape(0) != R || a.shape(1) != C) {
    throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(R) + ", " + std::to_string(C) +
                          "), got " + shape_str(a));
  }
  const Eigen::Map<const Eigen::Matrix<double, R, C, (C == 1 ? Eigen::ColMajor : Eigen::RowMajor)>> m(a.data());
  if (!m.allFinite()) return mat<R, C>(a, name).template cast<S>();  // names the element that is not finite
  return m.template cast<S>();
}

// A unit quaternion [w, x, y, z], read through the array's pointer.
template <typename S>
fsw::Quat<S> quat_as(const Arr& a, const char* name) {
  if (a.ndim() != 1 || a.shape(0) != 4) return quat(a, name).template cast<S>();  // its message
  const double* p = a.data();
  const double norm = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]);
  if (!std::isfinite(norm) || std::abs(norm - 1.0) > kUnitTol) return quat(a, name).template cast<S>();
  return fsw::from_wxyz(fsw::Vec4<S>(S(p[0]), S(p[1]), S(p[2]), S(p[3])));
}

template <typename Derived>
auto cast_to(const Eigen::MatrixBase<Derived>& m) {
  return m.template cast<double>().eval();
}

template <typename S>
void bind_record(py::module_& m, const char* name) {
  using R = fsw::StepRecord<S, 6>;
  py::class_<R>(m, name, "What one navigation filter step did.")
      .def_property_readonly(
          "status", [](const R& r) { return fsw::to_string(r.status); }, "'ok' | 'gated' | 'not_pos_def' | 'bad_input'")
      .def_property_readonly(
          "detail", [](const R& r) { return fsw::to_string(r.detail); },
          "Finer reason, e.g. 'too_old', 'off_tick', 'time_not_increasing'.")
      .def_readonly("fused", &R::fused)
      .def_readonly("t_s", &R::t_s, "Time of the step (capture time for a pose) [s].")
      .def_property_readonly(
          "innovation", [](const R& r) { return to_numpy(cast_to(r.innovation)); },
          "(6,) [r_meas - r_pred (Hill, m), q_meas [-] q_pred (rad, body)]; zeros for predict.")
      .def_property_readonly(
          "innovation_cov", [](const R& r) { return to_numpy(cast_to(r.innovation_cov)); }, "(6, 6)")
      .def_property_readonly(
          "nis", [](const R& r) { return double(r.nis); }, "Normalised innovation squared y^T S^-1 y.")
      .def_property_readonly(
          "log_likelihood", [](const R& r) { return double(r.log_likelihood); },
          "log p_z (Rogers-Marcovitz, Table 1 step 14).")
      .def("ok", &R::ok)
      .def("__repr__", [name](const R& r) {
        return std::string(name) + "(status='" + fsw::to_string(r.status) + "', detail='" + fsw::to_string(r.detail) +
               "', fused=" + (r.fused ? "True" : "False") + ", nis=" + std::to_string(double(r.nis)) + ")";
      });
}

// A filter with the flight application's pose slot (fsw/app/flight_app.hpp,
// on_pose): a pose captured after the filter's time (its IMU sample not yet
// given), up to max_dt_s ahead, waits in one slot (a newer one replaces it)
// and is fused after the predict that reaches its tick.
template <typename U>
struct Filter {
  U u;
  bool pending = false;
  double pending_t_s = 0.0;
  fsw::Vec3<typename U::MeasVec::Scalar> pending_r;
  fsw::Quat<typename U::MeasVec::Scalar> pending_q;
  typename U::MeasCov pending_R;
  bool has_deferred = false;
  typename U::Record deferred;  // the record of the waiting pose's fusion, after the predict that made it

  explicit Filter(const fsw::NavConfig<typename U::MeasVec::Scalar>& cfg) : u(cfg) {}

  typename U::Record predict(double t, const fsw::Vec3<typename U::MeasVec::Scalar>& a,
                             const fsw::Vec3<typename U::MeasVec::Scalar>& w) {
    const typename U::Record rec = u.predict(t, a, w);
    has_deferred = false;
    if (pending && u.initialized() && u.t_s() >= pending_t_s - u.config().time_tol_s) {
      pending = false;
      deferred = u.update_pose(pending_t_s, pending_r, pending_q, pending_R);
      has_deferred = true;
    }
    return rec;
  }

  typename U::Record update_pose(double t, const fsw::Vec3<typename U::MeasVec::Scalar>& r,
                                 const fsw::Quat<typename U::MeasVec::Scalar>& q, const typename U::MeasCov& R) {
    const typename U::Record rec = u.update_pose(t, r, q, R);
    if (rec.status == fsw::StepStatus::BadInput && rec.detail == fsw::StepDetail::FromFuture && u.initialized() &&
        t - u.t_s() <= u.config().max_dt_s) {
      pending = true;
      pending_t_s = t;
      pending_r = r;
      pending_q = q;
      pending_R = R;
    }
    return rec;
  }
};

// One filter variant: NavUkf<S, kWithBias> under `name`.
template <typename S, bool kWithBias>
void bind_ukf(py::module_& m, const char* name, const char* doc) {
  using U = fsw::NavUkf<S, kWithBias>;
  using F = Filter<U>;
  constexpr int kN = U::kN;
  py::class_<F>(m, name, doc)
      .def(py::init([](const Cfg& cfg) {
             auto f = std::make_unique<F>(nav_config_as<S>(cfg));
             if (!f->u.config_ok())
               throw py::value_error(std::string("cfg.") + f->u.config_invalid_field() + ": invalid value");
             return f;
           }),
           py::arg("cfg"))
      .def(
          "init",
          [](F& f, double t, const Arr& r, const Arr& v, const Arr& q, const Arr& P0, py::object gyro_bias,
             py::object accel_bias) {
            U& u = f.u;
            f.pending = false;
            f.has_deferred = false;
            typename U::State x;
            x.r_hill_m = vec<3>(r, "r_hill_m").template cast<S>();
            x.v_hill_mps = vec<3>(v, "v_hill_mps").template cast<S>();
            x.q_hb = quat(q, "q_hb_wxyz").template cast<S>();
            if constexpr (kWithBias) {
              if (!gyro_bias.is_none())
                x.gyro_bias_rps = vec<3>(gyro_bias.cast<Arr>(), "gyro_bias_rps").template cast<S>();
              if (!accel_bias.is_none())
                x.accel_bias_mps2 = vec<3>(accel_bias.cast<Arr>(), "accel_bias_mps2").template cast<S>();
            } else if (!gyro_bias.is_none() || !accel_bias.is_none()) {
              throw py::value_error("gyro_bias_rps, accel_bias_mps2: this filter has no bias states");
            }
            const auto rec = u.init(finite(t, "t_s"), x, mat<kN, kN>(P0, "P0").template cast<S>());
            if (!rec.ok())
              throw py::value_error(std::string("P0: ") + fsw::to_string(rec.status) + " (" +
                                    fsw::to_string(rec.detail) + ")");
            return rec;
          },
          py::arg("t_s"), py::arg("r_hill_m"), py::arg("v_hill_mps"), py::arg("q_hb_wxyz"), py::arg("P0"),
          py::arg("gyro_bias_rps") = py::none(), py::arg("accel_bias_mps2") = py::none(),
          "Sets the state at t_s [s]; P0 over the error state [dr, dv, dtheta(, dbg, dba)]. ValueError if P0 "
          "does not factor.")
      .def(
          "predict",
          [](F& f, double t, const Arr& a, const Arr& w) {
            return f.predict(finite(t, "t_s"), vec3_as<S>(a, "accel_b_mps2"), vec3_as<S>(w, "omega_bi_b_rps"));
          },
          py::arg("t_s"), py::arg("accel_b_mps2"), py::arg("omega_bi_b_rps"),
          "IMU sample (specific force, body [m/s^2]; omega_BI_B [rad/s]) held over (t_current, t_s]; "
          "moves the filter to t_s. A pose waiting for this tick is then fused (deferred_record).")
      .def(
          "update_pose",
          [](F& f, double t, const Arr& r, const Arr& q, const Arr& R) {
            return f.update_pose(finite(t, "t_capture_s"), vec3_as<S>(r, "r_hill_m"), quat_as<S>(q, "q_hb_wxyz"),
                                 mat_as<S, 6, 6>(R, "R"));
          },
          py::arg("t_capture_s"), py::arg("r_hill_m"), py::arg("q_hb_wxyz"), py::arg("R"),
          "Pose captured at t_capture_s (an IMU tick, at most max_delay_s old); R (6, 6) over "
          "[position m^2, attitude rad^2 (body-frame boxminus)]. A pose captured after the filter's time "
          "(up to max_dt_s) answers 'from_future' and waits, as in the flight application, for the predict "
          "that reaches its tick (pose_pending; its record: deferred_record).")
      .def_property_readonly(
          "pose_pending", [](const F& f) { return f.pending; }, "A pose waits for the predict that reaches its tick.")
      .def_property_readonly(
          "deferred_record",
          [](const F& f) -> py::object { return f.has_deferred ? py::cast(f.deferred) : py::none(); },
          "The record of the waiting pose's fusion made by the last predict, else None.")
      .def_property_readonly("t_s", [](const F& f) { return f.u.t_s(); })
      .def_property_readonly("r_hill_m", [](const F& f) { return to_numpy(cast_to(f.u.state().r_hill_m)); })
      .def_property_readonly("v_hill_mps", [](const F& f) { return to_numpy(cast_to(f.u.state().v_hill_mps)); })
      .def_property_readonly(
          "q_hb", [](const F& f) { return to_numpy(cast_to(fsw::to_wxyz(f.u.state().q_hb))); }, "[w, x, y, z]")
      .def_property_readonly(
          "P", [](const F& f) { return to_numpy(cast_to(f.u.P())); }, "Covariance over the error state.")
      .def_property_readonly("initialized", [](const F& f) { return f.u.initialized(); })
      .def_property_readonly("history_count", [](const F& f) { return f.u.history_count(); })
      .def_property_readonly_static("history_capacity", [](py::object) { return U::kHistoryCapacity; })
      .def_property_readonly_static("error_size", [](py::object) { return kN; })
      .def_property_readonly_static("scalar", [](py::object) { return sizeof(S) == 4 ? "float" : "double"; })
      .def(
          "state", [](const F& f) { return to_numpy(cast_to(f.u.state().stored())); },
          "Stored state [r(3), v(3), q_wxyz(4)(, gyro bias(3), accel bias(3))].");
}

}  // namespace

void bind_nav(py::module_& m) {
  bind_config(m);
  bind_record<double>(m, "NavStepRecord");
  bind_record<float>(m, "NavStepRecordFloat");
  bind_ukf<double, false>(m, "NavUkf",
                          "9-state multiplicative quaternion UKF (double): Hill-frame position, velocity and q_hb; "
                          "covariance over [dr_hill, dv_hill, dtheta_body]. IMU predict, pose update with delay.");
  bind_ukf<float, false>(m, "NavUkfFloat", "The 9-state filter of NavUkf built for float (the flight float build).");
  bind_ukf<double, true>(m, "NavUkf15",
                         "15-state filter (double): NavUkf's states plus gyro and accelerometer biases; "
                         "covariance over [dr, dv, dtheta, dbg, dba].");
  bind_ukf<float, true>(m, "NavUkf15Float", "The 15-state filter of NavUkf15 built for float.");
}
