// LED pose pipeline: detection, identification, PnP, covariance; its
// stages are in the files led_pose_detail.hpp lists. See led_pose.hpp and
// docs/VISION.md.
#include "fsw_vision/led_pose.hpp"

#include "led_pose_detail.hpp"

namespace fsw_vision {

const char* to_string(PoseStatus s) {
  switch (s) {
    case PoseStatus::Ok: return "Ok";
    case PoseStatus::TooFewLeds: return "TooFewLeds";
    case PoseStatus::AmbiguousIdentity: return "AmbiguousIdentity";
    case PoseStatus::TargetBehindCamera: return "TargetBehindCamera";
    case PoseStatus::DegenerateGeometry: return "DegenerateGeometry";
    case PoseStatus::SolverFailed: return "SolverFailed";
    case PoseStatus::BadInput: return "BadInput";
  }
  return "Unknown";
}

LedPattern default_pattern(double a, double face) {
  LedPattern p;
  p.p_host_m[0] = Eigen::Vector3d(face, -a, -a);
  p.p_host_m[1] = Eigen::Vector3d(face, a, -a);
  p.p_host_m[2] = Eigen::Vector3d(face, a, a);
  p.p_host_m[3] = Eigen::Vector3d(face, -a, a);
  p.p_host_m[kIdentifier] = p.p_host_m[0] + p.id_fraction * (p.p_host_m[1] - p.p_host_m[0]);
  p.normal_host = Eigen::Vector3d(1.0, 0.0, 0.0);
  return p;
}

LedPoseEstimator::LedPoseEstimator(const LedPoseConfig& cfg) : cfg_(cfg) {
  const CameraModel& c = cfg_.camera;
  K_ = (cv::Mat_<double>(3, 3) << c.fx_px, 0.0, c.cx_px, 0.0, c.fy_px, c.cy_px, 0.0, 0.0, 1.0);
  dist_ = (cv::Mat_<double>(1, 5) << c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]);
  // In-plane coordinates of the LEDs (origin corner 0, axes along edge 0-1
  // and normal x edge), for the identification homography.
  const Eigen::Vector3d& c0 = cfg_.pattern.p_host_m[0];
  const Eigen::Vector3d ax = (cfg_.pattern.p_host_m[1] - c0).normalized();
  const Eigen::Vector3d ay = cfg_.pattern.normal_host.normalized().cross(ax);
  for (int i = 0; i < kNumLeds; ++i) {
    const Eigen::Vector3d& p = cfg_.pattern.p_host_m[i];
    obj_.emplace_back(p.x(), p.y(), p.z());
    plane_uv_.emplace_back(float((p - c0).dot(ax)), float((p - c0).dot(ay)));
  }
}

LedPoseMeasurement LedPoseEstimator::estimate(const cv::Mat& gray, double t_capture_s,
                                              const Eigen::Quaterniond& q_h_host) const {
  if (gray.empty() || gray.type() != CV_8UC1 || gray.cols != cfg_.camera.width || gray.rows != cfg_.camera.height) {
    LedPoseMeasurement m;
    m.t_capture_s = t_capture_s;
    m.status = PoseStatus::BadInput;
    return m;
  }
  auto from_blobs = [&](const std::vector<Blob>& blobs) {
    std::vector<cv::Point2d> pts;
    std::vector<double> sig;
    for (const Blob& b : blobs) {
      pts.emplace_back(b.u_px, b.v_px);
      sig.push_back(b.sigma_px);
    }
    return estimate_from_points(pts, t_capture_s, q_h_host, sig);
  };
  std::vector<Blob> blobs = detect(gray, false);
  LedPoseMeasurement m = from_blobs(blobs);
  if (cfg_.faint_sigma_px > 0.0 && (m.status == PoseStatus::TooFewLeds || m.status == PoseStatus::AmbiguousIdentity)) {
    std::vector<Blob> all = detect(gray, true);
    if (all.size() > blobs.size()) {  // Ok, or why not with every spot seen
      blobs.swap(all);
      m = from_blobs(blobs);
    }
  }
  if (m.status == PoseStatus::AmbiguousIdentity && blobs.size() == kNumLeds - 1 && cfg_.merged_id_min_dchi2 > 0.0) {
    LedPoseMeasurement split = pose_with_merged_identifier(gray, blobs, t_capture_s, q_h_host);
    if (split.identifier_split) return split;  // Ok, or why not once the identifier is found
  }
  return m;
}

}  // namespace fsw_vision
