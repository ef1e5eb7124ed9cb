// Geometry of the pipeline: the camera-frame pose of the host from the
// inspector's navigation pose and back, the projection of the pattern with
// its Jacobian, and where four corners' plane homography puts the
// identifier.
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "led_pose_detail.hpp"

namespace fsw_vision {

void LedPoseEstimator::camera_from_nav(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb,
                                       const Eigen::Quaterniond& q_h_host, Eigen::Matrix3d& R_cp,
                                       Eigen::Vector3d& t_cp_m) const {
  const Eigen::Matrix3d R_hb = q_hb.normalized().toRotationMatrix();
  const Eigen::Matrix3d R_hp = q_h_host.normalized().toRotationMatrix();
  const Eigen::Matrix3d& R_bc = cfg_.camera.R_bc;
  const Eigen::Vector3d p_host_b = -R_hb.transpose() * r_hill_m;  // host origin, inspector body
  t_cp_m = R_bc.transpose() * (p_host_b - cfg_.camera.p_cam_b_m);
  R_cp = R_bc.transpose() * R_hb.transpose() * R_hp;
}

void LedPoseEstimator::nav_from_camera(const Eigen::Matrix3d& R_cp, const Eigen::Vector3d& t_cp_m,
                                       const Eigen::Quaterniond& q_h_host, Eigen::Vector3d& r_hill_m,
                                       Eigen::Quaterniond& q_hb) const {
  const Eigen::Matrix3d R_hp = q_h_host.normalized().toRotationMatrix();
  const Eigen::Matrix3d& R_bc = cfg_.camera.R_bc;
  const Eigen::Matrix3d R_hb = R_hp * R_cp.transpose() * R_bc.transpose();
  const Eigen::Vector3d p_host_b = R_bc * t_cp_m + cfg_.camera.p_cam_b_m;
  r_hill_m = -R_hb * p_host_b;
  q_hb = detail::quat_from_R(R_hb);
}

bool LedPoseEstimator::project(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb,
                               const Eigen::Quaterniond& q_h_host, std::array<cv::Point2d, kNumLeds>& px) const {
  Eigen::Matrix3d R_cp;
  Eigen::Vector3d t;
  camera_from_nav(r_hill_m, q_hb, q_h_host, R_cp, t);
  const CameraModel& c = cfg_.camera;
  const double k1 = c.dist[0], k2 = c.dist[1], p1 = c.dist[2], p2 = c.dist[3], k3 = c.dist[4];
  bool ok = true;
  for (int i = 0; i < kNumLeds; ++i) {
    const Eigen::Vector3d X = R_cp * cfg_.pattern.p_host_m[i] + t;
    if (!(X.z() > 0.0)) {
      ok = false;
      px[i] = cv::Point2d(0.0, 0.0);
      continue;
    }
    // OpenCV's radial-tangential model (k4..k6 = 0).
    const double x = X.x() / X.z(), y = X.y() / X.z();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    const double yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    px[i] = cv::Point2d(c.fx_px * xd + c.cx_px, c.fy_px * yd + c.cy_px);
  }
  return ok;
}

bool LedPoseEstimator::jacobian(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb,
                                const Eigen::Quaterniond& q_h_host, Eigen::Matrix<double, 2 * kNumLeds, 6>& J) const {
  constexpr double kStepM = 1e-6;
  constexpr double kStepRad = 1e-6;
  std::array<cv::Point2d, kNumLeds> plus, minus;
  for (int k = 0; k < 6; ++k) {
    Eigen::Vector3d rp = r_hill_m, rm = r_hill_m;
    Eigen::Quaterniond qp = q_hb, qm = q_hb;
    double h = 0.0;
    if (k < 3) {
      h = kStepM;
      rp(k) += h;
      rm(k) -= h;
    } else {
      h = kStepRad;
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d(k - 3) = h;
      qp = q_hb * detail::exp_q(d);  // body-frame perturbation, as the filter's dtheta
      qm = q_hb * detail::exp_q(-d);
    }
    if (!project(rp, qp, q_h_host, plus) || !project(rm, qm, q_h_host, minus)) return false;
    for (int i = 0; i < kNumLeds; ++i) {
      J(2L * i, k) = (plus[i].x - minus[i].x) / (2.0 * h);
      J(2L * i + 1, k) = (plus[i].y - minus[i].y) / (2.0 * h);
    }
  }
  return J.allFinite();
}

bool LedPoseEstimator::identifier_in_image(const std::array<cv::Point2f, 4>& quad, cv::Point2d& id_px) const {
  const cv::Mat H = cv::getPerspectiveTransform(plane_uv_.data(), quad.data());
  const cv::Point2f& id = plane_uv_[kIdentifier];
  const double w = H.at<double>(2, 0) * id.x + H.at<double>(2, 1) * id.y + H.at<double>(2, 2);
  if (!(std::abs(w) > 1e-12)) return false;
  id_px = cv::Point2d((H.at<double>(0, 0) * id.x + H.at<double>(0, 1) * id.y + H.at<double>(0, 2)) / w,
                      (H.at<double>(1, 0) * id.x + H.at<double>(1, 1) * id.y + H.at<double>(1, 2)) / w);
  return true;
}

double LedPoseEstimator::identifier_fraction(const std::array<cv::Point2d, 4>& corners) const {
  std::array<cv::Point2f, 4> quad;
  for (int c = 0; c < 4; ++c) quad[c] = cv::Point2f(float(corners[c].x), float(corners[c].y));
  cv::Point2d p;
  const cv::Point2d e = corners[1] - corners[0];
  const double L2 = e.dot(e);
  if (!identifier_in_image(quad, p) || !(L2 > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return e.dot(p - corners[0]) / L2;
}

}  // namespace fsw_vision
