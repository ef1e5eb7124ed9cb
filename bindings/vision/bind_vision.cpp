// Bindings of the LED pose pipeline (fsw/vision, OpenCV): LedPoseConfig,
// LedPoseEstimator and its measurement. Compiled only when OpenCV is found
// (PROXOPS_HAVE_VISION). Images cross as uint8 arrays of shape (height,
// width), wrapped without a copy; quaternions are [w, x, y, z].
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <string>

#include "../bind.hpp"
#include "../validate.hpp"
#include "fsw_vision/led_pose.hpp"

using namespace bind_detail;
using fsw_vision::LedPoseConfig;
using fsw_vision::LedPoseEstimator;
using fsw_vision::LedPoseMeasurement;

namespace {

using Img = py::array_t<uint8_t, py::array::c_style>;

cv::Mat wrap_image(const Img& img) {
  if (img.ndim() != 2) throw py::value_error("image: expected a 2-D uint8 array (height, width)");
  return cv::Mat(static_cast<int>(img.shape(0)), static_cast<int>(img.shape(1)), CV_8UC1,
                 const_cast<uint8_t*>(img.data()));
}

Arr identity_wxyz() {
  Arr a(4);
  a.mutable_at(0) = 1.0;
  a.mutable_at(1) = a.mutable_at(2) = a.mutable_at(3) = 0.0;
  return a;
}

Eigen::Quaterniond host_quat(const Arr& a) { return quat(a, "q_h_host"); }

py::array_t<double> points_to_numpy(const std::array<cv::Point2d, fsw_vision::kNumLeds>& px) {
  py::array_t<double> out({fsw_vision::kNumLeds, 2});
  for (int i = 0; i < fsw_vision::kNumLeds; ++i) {
    out.mutable_at(i, 0) = px[i].x;
    out.mutable_at(i, 1) = px[i].y;
  }
  return out;
}

// Blobs as rows [u_px, v_px, flux, area_px, sigma_px, n_saturated,
// sigma_noise_px, width_px].
py::array_t<double> blobs_to_numpy(const std::vector<fsw_vision::Blob>& blobs) {
  py::array_t<double> out({static_cast<py::ssize_t>(blobs.size()), py::ssize_t(8)});
  for (size_t i = 0; i < blobs.size(); ++i) {
    out.mutable_at(i, 0) = blobs[i].u_px;
    out.mutable_at(i, 1) = blobs[i].v_px;
    out.mutable_at(i, 2) = blobs[i].flux;
    out.mutable_at(i, 3) = blobs[i].area_px;
    out.mutable_at(i, 4) = blobs[i].sigma_px;
    out.mutable_at(i, 5) = blobs[i].n_saturated;
    out.mutable_at(i, 6) = blobs[i].sigma_noise_px;
    out.mutable_at(i, 7) = blobs[i].width_px;
  }
  return out;
}

// The camera: intrinsics, distortion and its mount on the inspector.
void bind_camera(py::class_<LedPoseConfig>& cls) {
  cls.def_property(
         "width", [](const LedPoseConfig& c) { return c.camera.width; },
         [](LedPoseConfig& c, int v) { c.camera.width = int(positive(v, "width")); }, "Image width [px].")
      .def_property(
          "height", [](const LedPoseConfig& c) { return c.camera.height; },
          [](LedPoseConfig& c, int v) { c.camera.height = int(positive(v, "height")); }, "Image height [px].")
      .def_property(
          "fx_px", [](const LedPoseConfig& c) { return c.camera.fx_px; },
          [](LedPoseConfig& c, double v) { c.camera.fx_px = positive(v, "fx_px"); }, "Focal length, x [px].")
      .def_property(
          "fy_px", [](const LedPoseConfig& c) { return c.camera.fy_px; },
          [](LedPoseConfig& c, double v) { c.camera.fy_px = positive(v, "fy_px"); }, "Focal length, y [px].")
      .def_property(
          "cx_px", [](const LedPoseConfig& c) { return c.camera.cx_px; },
          [](LedPoseConfig& c, double v) { c.camera.cx_px = finite(v, "cx_px"); },
          "Principal point column [px] (pixel centres at integers).")
      .def_property(
          "cy_px", [](const LedPoseConfig& c) { return c.camera.cy_px; },
          [](LedPoseConfig& c, double v) { c.camera.cy_px = finite(v, "cy_px"); }, "Principal point row [px].")
      .def_property(
          "dist", [](const LedPoseConfig& c) { return to_numpy(Eigen::Matrix<double, 5, 1>(c.camera.dist.data())); },
          [](LedPoseConfig& c, const Arr& a) {
            const auto v = vec<5>(a, "dist");
            for (int i = 0; i < 5; ++i) c.camera.dist[i] = v(i);
          },
          "Distortion [k1, k2, p1, p2, k3] (OpenCV radial-tangential model).")
      .def_property(
          "R_bc", [](const LedPoseConfig& c) { return to_numpy(c.camera.R_bc); },
          [](LedPoseConfig& c, const Arr& a) {
            const Eigen::Matrix3d R = mat<3, 3>(a, "R_bc");
            if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0.0)
              throw py::value_error("R_bc: must be a rotation matrix");
            c.camera.R_bc = R;
          },
          "Camera -> inspector body rotation (columns: camera x right, y down, z boresight in body axes).")
      .def_property(
          "p_cam_b_m", [](const LedPoseConfig& c) { return to_numpy(c.camera.p_cam_b_m); },
          [](LedPoseConfig& c, const Arr& a) { c.camera.p_cam_b_m = vec<3>(a, "p_cam_b_m"); },
          "Camera centre relative to the inspector's centre of mass, body frame [m].");
}

// The LED pattern on the host.
void bind_pattern(py::class_<LedPoseConfig>& cls) {
  cls.def_property_readonly(
         "pattern_host_m",
         [](const LedPoseConfig& c) {
           Eigen::Matrix<double, fsw_vision::kNumLeds, 3> P;
           for (int i = 0; i < fsw_vision::kNumLeds; ++i) P.row(i) = c.pattern.p_host_m[i].transpose();
           return to_numpy(P);
         },
         "LED positions in the host body frame [m], rows: corners 0..3, identifier.")
      .def_property_readonly(
          "pattern_normal_host", [](const LedPoseConfig& c) { return to_numpy(c.pattern.normal_host); },
          "Outward normal of the LED face, host body frame.")
      .def(
          "set_pattern",
          [](LedPoseConfig& c, double half_side_m, double face_offset_m) {
            c.pattern = fsw_vision::default_pattern(positive(half_side_m, "half_side_m"),
                                                    finite(face_offset_m, "face_offset_m"));
          },
          py::arg("half_side_m"), py::arg("face_offset_m"),
          "Square of side 2*half_side_m on the host face at x = face_offset_m [m].");
}

// Detection, identification, centroid and pose thresholds.
void bind_thresholds(py::class_<LedPoseConfig>& cls) {
  cls.def_readwrite("background_kernel_px", &LedPoseConfig::background_kernel_px)
      .def_readwrite("threshold_counts", &LedPoseConfig::threshold_counts,
                     "Detection threshold above the local background [counts].")
      .def_readwrite("faint_sigma_px", &LedPoseConfig::faint_sigma_px,
                     "Matched-filter width for faint spots [px]; 0 turns the faint pass off.")
      .def_readwrite("faint_threshold_counts", &LedPoseConfig::faint_threshold_counts,
                     "Faint-spot threshold on the smoothed background-subtracted image [counts].")
      .def_readwrite("min_area_px", &LedPoseConfig::min_area_px)
      .def_readwrite("max_area_px", &LedPoseConfig::max_area_px)
      .def_readwrite("max_extent_px", &LedPoseConfig::max_extent_px)
      .def_readwrite("max_elongation", &LedPoseConfig::max_elongation)
      .def_readwrite("max_blobs", &LedPoseConfig::max_blobs)
      .def_readwrite("max_reproj_rms_px", &LedPoseConfig::max_reproj_rms_px)
      .def_readwrite("ambiguity_ratio", &LedPoseConfig::ambiguity_ratio)
      .def_readwrite("flip_weight_max", &LedPoseConfig::flip_weight_max,
                     "Planar mirror solution weight above which no pose is reported.")
      .def_readwrite("pixel_sigma_px", &LedPoseConfig::pixel_sigma_px,
                     "Centroid sigma for points given without their own [px].")
      .def_readwrite("read_noise_counts", &LedPoseConfig::read_noise_counts,
                     "Pixel noise model of the centroid variance: read noise [counts].")
      .def_readwrite("shot_gain", &LedPoseConfig::shot_gain, "... and shot-noise variance per count of signal.")
      .def_readwrite("centroid_floor_px", &LedPoseConfig::centroid_floor_px,
                     "Added in quadrature to every blob's centroid sigma [px].")
      .def_readwrite("refine_centroid", &LedPoseConfig::refine_centroid,
                     "Refined centroid (window centred on the spot, ring background plane, signed weights, "
                     "calibrated sigma); False: the component-box centroid with the plain pixel-noise sigma.")
      .def_readwrite("centroid_weight_min_px", &LedPoseConfig::centroid_weight_min_px,
                     "Lower bound of the centroid's Gaussian weight width [px].")
      .def_readwrite("centroid_weight_max_px", &LedPoseConfig::centroid_weight_max_px,
                     "Upper bound of the centroid's Gaussian weight width [px].")
      .def_readwrite("centroid_weight_sat_scale", &LedPoseConfig::centroid_weight_sat_scale,
                     "Factor on the weight width of a spot with saturated pixels.")
      .def_readwrite("centroid_noise_scale", &LedPoseConfig::centroid_noise_scale,
                     "Calibrated factor on the propagated pixel-noise sigma of a refined centroid.")
      .def_readwrite("sat_sigma_px", &LedPoseConfig::sat_sigma_px,
                     "Calibrated saturation term: a spot with n_sat saturated pixels adds "
                     "(sat_sigma_px n_sat / max(width_px, 1)^4)^2 to its centroid variance [px^2].")
      .def_readwrite("merged_id_min_dchi2", &LedPoseConfig::merged_id_min_dchi2,
                     "Merged identifier: the two-spot fit must beat one spot by this chi^2 (0: off).")
      .def_readwrite("merged_id_margin_dchi2", &LedPoseConfig::merged_id_margin_dchi2,
                     "... and every other labelling's two-spot fit by this chi^2.");
}

void bind_measurement(py::module_& m) {
  py::class_<LedPoseMeasurement>(m, "LedPoseMeasurement",
                                 "Pose measurement for NavUkf.update_pose: r_hill_m (inspector relative to host, "
                                 "Hill, m), q_hb [w,x,y,z], R (6x6: position m^2, body attitude error rad^2).")
      .def_property_readonly(
          "status", [](const LedPoseMeasurement& r) { return std::string(to_string(r.status)); },
          "'Ok' | 'TooFewLeds' | 'AmbiguousIdentity' | 'TargetBehindCamera' | "
          "'DegenerateGeometry' | 'SolverFailed' | 'BadInput'")
      .def_property_readonly("ok", [](const LedPoseMeasurement& r) { return r.status == fsw_vision::PoseStatus::Ok; })
      .def_readonly("t_capture_s", &LedPoseMeasurement::t_capture_s)
      .def_property_readonly("r_hill_m", [](const LedPoseMeasurement& r) { return to_numpy(r.r_hill_m); })
      .def_property_readonly("q_hb", [](const LedPoseMeasurement& r) { return quat_to_numpy(r.q_hb); })
      .def_property_readonly("R", [](const LedPoseMeasurement& r) { return to_numpy(r.R); })
      .def_readonly("n_blobs", &LedPoseMeasurement::n_blobs)
      .def_readonly("n_hypotheses", &LedPoseMeasurement::n_hypotheses)
      .def_readonly("reproj_rms_px", &LedPoseMeasurement::reproj_rms_px)
      .def_readonly("flip_weight", &LedPoseMeasurement::flip_weight,
                    "Weight of the planar mirror solution folded into R (0: none).")
      .def_readonly("range_m", &LedPoseMeasurement::range_m, "Camera to pattern centre [m].")
      .def_readonly("identifier_split", &LedPoseMeasurement::identifier_split,
                    "True when the identifier came from a two-spot fit of a blob merged with its corner.")
      .def_property_readonly(
          "blob_of_led",
          [](const LedPoseMeasurement& r) { return std::vector<int>(r.blob_of_led.begin(), r.blob_of_led.end()); })
      .def("__repr__", [](const LedPoseMeasurement& r) {
        return "LedPoseMeasurement(status=" + std::string(to_string(r.status)) +
               ", t_capture_s=" + std::to_string(r.t_capture_s) + ", range_m=" + std::to_string(r.range_m) + ")";
      });
}

void bind_estimator(py::module_& m) {
  py::class_<LedPoseEstimator>(m, "LedPoseEstimator", "Image of the host's LED pattern -> pose measurement.")
      .def(py::init<const LedPoseConfig&>(), py::arg("config") = LedPoseConfig())
      .def_property_readonly("config", &LedPoseEstimator::config)
      .def(
          "estimate",
          [](const LedPoseEstimator& e, const Img& image, double t_capture_s, const Arr& q_h_host) {
            const cv::Mat img = wrap_image(image);
            const Eigen::Quaterniond q = host_quat(q_h_host);
            py::gil_scoped_release release;
            return e.estimate(img, finite(t_capture_s, "t_capture_s"), q);
          },
          py::arg("image"), py::arg("t_capture_s"), py::arg("q_h_host") = identity_wxyz(),
          "Pose from an 8-bit image (height, width). q_h_host: host attitude, host body -> Hill [w,x,y,z].")
      .def(
          "estimate_from_points",
          [](const LedPoseEstimator& e, const Arr& pts, double t_capture_s, const Arr& q_h_host,
             const std::vector<double>& sigma_px) {
            if (pts.ndim() != 2 || pts.shape(1) != 2) throw py::value_error("points_px: expected shape (N, 2)");
            std::vector<cv::Point2d> p;
            for (py::ssize_t i = 0; i < pts.shape(0); ++i) p.emplace_back(pts.at(i, 0), pts.at(i, 1));
            return e.estimate_from_points(p, finite(t_capture_s, "t_capture_s"), host_quat(q_h_host), sigma_px);
          },
          py::arg("points_px"), py::arg("t_capture_s"), py::arg("q_h_host") = identity_wxyz(),
          py::arg("sigma_px") = std::vector<double>(),
          "Identification and pose from blob centres (N, 2) [u, v] px, optional centroid sigma per point [px].")
      .def(
          "detect",
          [](const LedPoseEstimator& e, const Img& image) { return blobs_to_numpy(e.detect(wrap_image(image))); },
          py::arg("image"),
          "Blobs, brightest first: rows [u_px, v_px, flux, area_px, sigma_px, n_saturated, sigma_noise_px, width_px] "
          "(sigma_noise_px: the propagated pixel noise before the calibration's scale and terms; width_px: "
          "the spot's width from its moments).")
      .def(
          "project",
          [](const LedPoseEstimator& e, const Arr& r_hill_m, const Arr& q_hb, const Arr& q_h_host) {
            std::array<cv::Point2d, fsw_vision::kNumLeds> px;
            const bool ok = e.project(vec<3>(r_hill_m, "r_hill_m"), quat(q_hb, "q_hb"), host_quat(q_h_host), px);
            return py::make_tuple(ok, points_to_numpy(px));
          },
          py::arg("r_hill_m"), py::arg("q_hb"), py::arg("q_h_host") = identity_wxyz(),
          "(in_front, (5, 2) pixel coordinates of the LEDs) for an inspector pose, with the configured camera.")
      .def(
          "jacobian",
          [](const LedPoseEstimator& e, const Arr& r_hill_m, const Arr& q_hb, const Arr& q_h_host) {
            Eigen::Matrix<double, 2 * fsw_vision::kNumLeds, 6> J;
            if (!e.jacobian(vec<3>(r_hill_m, "r_hill_m"), quat(q_hb, "q_hb"), host_quat(q_h_host), J))
              throw py::value_error("jacobian: an LED is behind the camera");
            return to_numpy(J);
          },
          py::arg("r_hill_m"), py::arg("q_hb"), py::arg("q_h_host") = identity_wxyz(),
          "d(pixels)/d[r_hill_m, dtheta_b], (10, 6): rows u0, v0, u1, ...");
}

}  // namespace

void bind_vision(py::module_& m) {
  py::class_<LedPoseConfig> config(m, "LedPoseConfig",
                                   "LED pose pipeline configuration: camera (intrinsics, distortion, mount on the "
                                   "inspector), LED pattern (host body frame) and detection / pose thresholds.");
  config.def(py::init<>());
  bind_camera(config);
  bind_pattern(config);
  bind_thresholds(config);
  bind_measurement(m);
  bind_estimator(m);
}
