// Bindings of the feature filters (fsw/feature_filter.hpp): configuration,
// the EKF and UKF for the feature paper's budget (4 points, 4 lines, 2
// circles; double) and their step record. Arrays are checked here (shape,
// finiteness, unit quaternion) and raise ValueError naming the argument. The
// image coordinates z are passed through as given: a NaN in a measured slot
// is the flight code's BadInput (non_finite), in an unmeasured slot it is
// ignored.
#include <cstdint>
#include <string>

#include "bind.hpp"
#include "fsw/features/feature_filter.hpp"
#include "validate.hpp"

using namespace bind_detail;

namespace {
constexpr int kP = 4, kL = 4, kC = 2;
using Cfg = fsw::FeatureFilterConfig<double>;
using Ekf = fsw::FeatureEkf<double, kP, kL, kC>;
using Ukf = fsw::FeatureUkf<double, kP, kL, kC>;
using Base = fsw::FeatureFilterBase<double, kP, kL, kC>;
using Rec = Base::Record;
using Features = Base::Features;
constexpr int kN = Base::kN;
constexpr int kM = Base::kMeas;

// (n, 3) array of finite rows, n <= cap.
template <std::size_t Cap>
int rows3(const Arr& a, const char* name, std::array<fsw::Vec3<double>, Cap>& out) {
  if (a.ndim() != 2 || a.shape(1) != 3 || a.shape(0) > py::ssize_t(Cap))
    throw py::value_error(std::string(name) + ": expected shape (n, 3) with n <= " + std::to_string(Cap) + ", got " +
                          shape_str(a));
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    for (int j = 0; j < 3; ++j) {
      out[i](j) = a.at(i, j);
      if (!std::isfinite(out[i](j))) throw py::value_error(std::string(name) + ": not finite");
    }
  return int(a.shape(0));
}

Features make_features(const Arr& points, const Arr& line_dir, const Arr& line_moment, const Arr& circle_axis,
                       const Arr& circle_moment, const Arr& circle_start) {
  Features fs;
  fs.n_points = rows3(points, "points_lp_m", fs.point_lp_m);
  fs.n_lines = rows3(line_dir, "line_dir_lp", fs.line_dir_lp);
  if (rows3(line_moment, "line_moment_lp_m", fs.line_moment_lp_m) != fs.n_lines)
    throw py::value_error("line_moment_lp_m: one row per line direction");
  fs.n_circles = rows3(circle_axis, "circle_axis_lp", fs.circle_axis_lp);
  if (rows3(circle_moment, "circle_moment_lp_m", fs.circle_moment_lp_m) != fs.n_circles ||
      rows3(circle_start, "circle_start_lp_m", fs.circle_start_lp_m) != fs.n_circles)
    throw py::value_error("circle_moment_lp_m, circle_start_lp_m: one row per circle axis");
  return fs;
}

// z (kM,) as given (NaN allowed; the flight code judges measured slots).
Base::MeasVec meas(const Arr& a) {
  if (a.ndim() != 1 || a.shape(0) != kM)
    throw py::value_error("z: expected shape (" + std::to_string(kM) + ",), got " + shape_str(a));
  Base::MeasVec z;
  for (int i = 0; i < kM; ++i) z(i) = a.at(i);
  return z;
}

template <typename F>
void bind_filter(py::module_& m, const char* name, const char* doc) {
  py::class_<F>(m, name, doc)
      .def(py::init([](const Cfg& cfg, const Arr& pts, const Arr& ld, const Arr& lm, const Arr& ca, const Arr& cm,
                       const Arr& cs) {
             F f(cfg, make_features(pts, ld, lm, ca, cm, cs));
             if (!f.config_ok()) throw py::value_error(std::string(f.config_invalid_field()) + ": invalid value");
             return f;
           }),
           py::arg("cfg"), py::arg("points_lp_m"), py::arg("line_dir_lp"), py::arg("line_moment_lp_m"),
           py::arg("circle_axis_lp"), py::arg("circle_moment_lp_m"), py::arg("circle_start_lp_m"),
           "Features in the leader feature frame lP: points (n, 3) [m]; lines as unit direction and moment "
           "m = p x l (n, 3); circles as twist axis, moment and start point (n, 3). Empty (0, 3) arrays allowed.")
      .def(
          "init",
          [](F& f, double t, double nu0, const Arr& q, const Arr& w, const Arr& r, const Arr& v, const Arr& phi,
             const Arr& P0) {
            typename F::State x;
            x.q_lf = quat(q, "q_lf_wxyz");
            x.w_fl_f_rps = vec<3>(w, "w_fl_f_rps");
            x.r_l_m = vec<3>(r, "r_l_m");
            x.v_l_mps = vec<3>(v, "v_l_mps");
            x.phi_rad = vec<3 * kC>(phi, "phi_rad");
            return f.init(finite(t, "t_s"), finite(nu0, "nu0_rad"), x, mat<kN, kN>(P0, "P0"));
          },
          py::arg("t_s"), py::arg("nu0_rad"), py::arg("q_lf_wxyz"), py::arg("w_fl_f_rps"), py::arg("r_l_m"),
          py::arg("v_l_mps"), py::arg("phi_rad"), py::arg("P0"),
          "State at t_s [s] with the leader's true anomaly nu0 [rad]; P0 (18, 18) over "
          "[dtheta (body), dw, dr (L), dv (L), dphi (6)].")
      .def(
          "predict", [](F& f, double t) { return f.predict(t); }, py::arg("t_s"),
          "Propagates to t_s [s] (NaN or not after the current time: bad_input).")
      .def(
          "update", [](F& f, const Arr& z, std::uint32_t mask) { return f.update(meas(z), mask); }, py::arg("z"),
          py::arg("mask") = F::kAllSlots,
          "Image coordinates z (28,) [m on the image plane]: points 0-7, line points 8-15, circle points "
          "16-27 (x, y pairs); bit k of mask marks pair k as measured.")
      .def(
          "predicted_measurement",
          [](const F& f) -> py::object {
            typename F::MeasVec z;
            if (!f.predict_measurement(z)) return py::none();
            return to_numpy(z);
          },
          "(28,) model prediction at the current state (zeros in unconfigured slots), None if not imageable.")
      .def_property_readonly("t_s", &F::t_s)
      .def_property_readonly("nu_rad", &F::nu_rad, "Leader true anomaly [rad].")
      .def_property_readonly("initialized", &F::initialized)
      .def_property_readonly(
          "q_lf", [](const F& f) { return quat_to_numpy(f.state().q_lf); },
          "Follower body -> leader frame, [w, x, y, z].")
      .def_property_readonly("w_fl_f_rps", [](const F& f) { return to_numpy(f.state().w_fl_f_rps); })
      .def_property_readonly(
          "r_l_m", [](const F& f) { return to_numpy(f.state().r_l_m); },
          "Follower centre of mass in the leader frame [m].")
      .def_property_readonly("v_l_mps", [](const F& f) { return to_numpy(f.state().v_l_mps); })
      .def_property_readonly("phi_rad", [](const F& f) { return to_numpy(f.state().phi_rad); })
      .def_property_readonly(
          "pose_dq", [](const F& f) { return to_numpy(fsw::to_wxyz8(f.pose_lf())); },
          "(8,) dual quaternion of the follower body in L [rw, rx, ry, rz, dw, dx, dy, dz].")
      .def_property_readonly(
          "P", [](const F& f) { return to_numpy(f.covariance()); }, "(18, 18)")
      .def_property_readonly("configured_slots", &F::configured_slots)
      .def_property_readonly_static("n_error", [](py::object) { return kN; })
      .def_property_readonly_static("n_meas", [](py::object) { return kM; });
}
}  // namespace

void bind_features(py::module_& m) {
  py::class_<Cfg>(m, "FeatureFilterConfig", "Feature filter configuration (plain struct, SI units).")
      .def(py::init<>())
      .def_property(
          "leader_a_m", [](const Cfg& c) { return c.leader.a_m; }, [](Cfg& c, double v) { c.leader.a_m = v; },
          "Leader semi-major axis [m] (7.2e6).")
      .def_property(
          "leader_e", [](const Cfg& c) { return c.leader.e; }, [](Cfg& c, double v) { c.leader.e = v; },
          "Leader eccentricity (0.02).")
      .def_property(
          "inertia_f_kgm2", [](const Cfg& c) { return to_numpy(c.inertia_f_kgm2); },
          [](Cfg& c, const Arr& a) { c.inertia_f_kgm2 = vec<3>(a, "inertia_f_kgm2"); },
          "Follower principal inertia (3,) [kg m^2].")
      .def_property(
          "focal_m", [](const Cfg& c) { return c.camera.focal_m; }, [](Cfg& c, double v) { c.camera.focal_m = v; },
          "Focal length [m].")
      .def_property(
          "camera_offset_f_m", [](const Cfg& c) { return to_numpy(c.camera.camera_offset_f_m); },
          [](Cfg& c, const Arr& a) { c.camera.camera_offset_f_m = vec<3>(a, "camera_offset_f_m"); },
          "Lens centre from the follower c.m., body frame (3,) [m].")
      .def_property(
          "feature_origin_l_m", [](const Cfg& c) { return to_numpy(c.camera.feature_origin_l_m); },
          [](Cfg& c, const Arr& a) { c.camera.feature_origin_l_m = vec<3>(a, "feature_origin_l_m"); },
          "Leader feature frame origin from the leader c.m., leader frame (3,) [m].")
      .def_property(
          "min_depth_m", [](const Cfg& c) { return c.camera.min_depth_m; },
          [](Cfg& c, double v) { c.camera.min_depth_m = v; }, "Nearest imageable depth [m].")
      .def_readwrite("image_sigma_m", &Cfg::image_sigma_m, "Image-plane noise, 1-sigma [m].")
      .def_readwrite("substeps", &Cfg::substeps, "RK4 sub-steps per predict.")
      .def_readwrite("max_dt_s", &Cfg::max_dt_s, "Longest predict step [s].")
      .def_readwrite("q_att", &Cfg::q_att, "Attitude process noise [rad^2/s].")
      .def_readwrite("q_rate", &Cfg::q_rate, "Rate process noise [(rad/s)^2/s].")
      .def_readwrite("q_pos", &Cfg::q_pos, "Position process noise [m^2/s].")
      .def_readwrite("q_vel", &Cfg::q_vel, "Velocity process noise [(m/s)^2/s].")
      .def_readwrite("q_phi", &Cfg::q_phi, "Circle-angle process noise [rad^2/s].")
      .def_readwrite("gate_chi2", &Cfg::gate_chi2, "NIS gate; <= 0 disables.")
      .def_readwrite("alpha", &Cfg::alpha, "UKF sigma-point spread.")
      .def_readwrite("beta", &Cfg::beta)
      .def_readwrite("kappa", &Cfg::kappa)
      .def_readwrite("max_alpha_halvings", &Cfg::max_alpha_halvings,
                     "UKF: spread halvings tried when a sigma point puts a feature behind the lens.");

  py::class_<Rec>(m, "FeatureStepRecord", "What one feature filter step did.")
      .def_property_readonly(
          "status", [](const Rec& r) { return std::string(fsw::to_string(r.status)); },
          "'ok' | 'gated' | 'not_pos_def' | 'bad_input'")
      .def_property_readonly(
          "detail", [](const Rec& r) { return std::string(fsw::to_string(r.detail)); },
          "Finer reason, e.g. 'non_finite', 'feature_not_imageable'.")
      .def_readonly("fused", &Rec::fused)
      .def_readonly("t_s", &Rec::t_s)
      .def_property_readonly(
          "innovation", [](const Rec& r) { return to_numpy(r.innovation); }, "(28,) [m]")
      .def_property_readonly(
          "innovation_cov", [](const Rec& r) { return to_numpy(r.innovation_cov); }, "(28, 28)")
      .def_readonly("nis", &Rec::nis, "Normalised innovation squared over the measured rows.")
      .def_readonly("log_likelihood", &Rec::log_likelihood)
      .def("__repr__", [](const Rec& r) {
        return std::string("FeatureStepRecord(status='") + fsw::to_string(r.status) + "', detail='" +
               fsw::to_string(r.detail) + "', nis=" + std::to_string(r.nis) + ")";
      });

  bind_filter<Ekf>(m, "FeatureEkf",
                   "Tightly coupled EKF over image features (the dual-quaternion feature paper): 4 points, 4 lines, 2 "
                   "circles at most.");
  bind_filter<Ukf>(m, "FeatureUkf",
                   "Tightly coupled UKF over image features (the feature paper's stated future work), same interface "
                   "as FeatureEkf.");
}
