// Pose from identified points: per labelling IPPE (both planar solutions)
// and the consensus gate's solution when it found one, each refined by
// Levenberg-Marquardt; the physical ones are kept and the labelling's best
// is the one with the smallest reprojection error. Then the choice between
// labellings, the navigation measurement and its covariance.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "led_pose_detail.hpp"

namespace fsw_vision {

using detail::Hypothesis;
using detail::Mat6;
using detail::Solution;
using detail::Vec6;
using detail::with_status;

// The robust gate's consensus search, exhaustive and deterministic: each
// LED left out in turn, IPPE on the other four (both planar solutions), and
// every LED checked against each of those poses. Five correspondences have
// only five minimal sets for a planar four-point solver, so this is what a
// RANSAC over them would find, without its random draws, and cheaper than
// cv::solvePnPRansac's 50 AP3P draws (docs/perf/vision.md). Returns the
// largest number of LEDs within ransac_threshold_px of one pose (0 when no
// pose could be computed); rv, tv get a pose with every LED within it.
int LedPoseEstimator::consensus_without_one(const std::vector<cv::Point2d>& img, cv::Mat& rv, cv::Mat& tv) const {
  std::vector<cv::Point3d> obj4(kNumLeds - 1);
  std::vector<cv::Point2d> img4(kNumLeds - 1), rep;
  std::vector<cv::Mat> rvecs, tvecs;
  int best = 0;
  for (int out = 0; out < kNumLeds; ++out) {
    for (int l = 0, c = 0; l < kNumLeds; ++l) {
      if (l == out) continue;
      obj4[c] = obj_[l];
      img4[c++] = img[l];
    }
    cv::solvePnPGeneric(obj4, img4, K_, dist_, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
    for (size_t s = 0; s < rvecs.size(); ++s) {
      cv::projectPoints(obj_, rvecs[s], tvecs[s], K_, dist_, rep);
      int inliers = 0;
      for (int l = 0; l < kNumLeds; ++l) inliers += cv::norm(rep[l] - img[l]) <= cfg_.ransac_threshold_px;
      if (inliers > best) {
        best = inliers;
        if (inliers == kNumLeds) {
          rv = rvecs[s].clone();
          tv = tvecs[s].clone();
          return best;
        }
      }
    }
  }
  return best;
}

Eigen::Vector3d LedPoseEstimator::pattern_centre() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) c += cfg_.pattern.p_host_m[i];
  return Eigen::Vector3d(c / 4.0);
}

bool LedPoseEstimator::physical(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) const {
  for (int i = 0; i < kNumLeds; ++i) {
    if ((R * cfg_.pattern.p_host_m[i] + t).z() <= cfg_.min_depth_m) return false;
  }
  // The LEDs shine from the face's outer side only.
  return (R * cfg_.pattern.normal_host).dot(R * pattern_centre() + t) < 0.0;
}

double LedPoseEstimator::worst_residual(const std::vector<cv::Point2d>& img, const cv::Mat& rv,
                                        const cv::Mat& tv) const {
  std::vector<cv::Point2d> rep;
  cv::projectPoints(obj_, rv, tv, K_, dist_, rep);
  double worst = 0.0;
  for (int l = 0; l < kNumLeds; ++l) worst = std::max(worst, cv::norm(rep[l] - img[l]));
  return worst;
}

void LedPoseEstimator::refine_solution(Hypothesis& h, const std::vector<cv::Point2d>& img,
                                       const std::vector<double>& sig, const cv::Mat& rv0, const cv::Mat& tv0) const {
  cv::Mat rv = rv0.clone(), tv = tv0.clone();
  rv.convertTo(rv, CV_64F);
  tv.convertTo(tv, CV_64F);
  cv::solvePnPRefineLM(obj_, img, K_, dist_, rv, tv);
  Solution sol;
  cv::Mat Rcv;
  cv::Rodrigues(rv, Rcv);
  for (int r = 0; r < 3; ++r) {
    sol.t_cp(r) = tv.at<double>(r);
    for (int c = 0; c < 3; ++c) sol.R_cp(r, c) = Rcv.at<double>(r, c);
  }
  if (!sol.R_cp.allFinite() || !sol.t_cp.allFinite() || !physical(sol.R_cp, sol.t_cp)) {
    h.behind = true;
    return;
  }
  std::vector<cv::Point2d> rep;
  cv::projectPoints(obj_, rv, tv, K_, dist_, rep);
  sol.ssr = 0.0;
  for (int l = 0; l < kNumLeds; ++l) {
    const cv::Point2d d = rep[l] - img[l];
    sol.ssr += d.dot(d);
    sol.wssr += d.dot(d) / (sig[h.idx[l]] * sig[h.idx[l]]);
  }
  h.solutions.push_back(sol);
  h.rms = std::min(h.rms, std::sqrt(sol.ssr / kNumLeds));
}

void LedPoseEstimator::solve_labelling(Hypothesis& h, const std::vector<cv::Point2d>& pts,
                                       const std::vector<double>& sig) const {
  std::vector<cv::Point2d> img(kNumLeds);
  for (int l = 0; l < kNumLeds; ++l) img[l] = pts[h.idx[l]];
  std::vector<cv::Mat> rvecs, tvecs;
  cv::solvePnPGeneric(obj_, img, K_, dist_, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
  // Robust gate: every LED must be within the threshold of a fit. An IPPE
  // solution with every LED within it is that fit (the consensus of all
  // five); otherwise the consensus is searched over the five minimal sets
  // (see consensus_without_one).
  double best_worst = std::numeric_limits<double>::infinity();
  for (size_t s = 0; s < rvecs.size(); ++s) best_worst = std::min(best_worst, worst_residual(img, rvecs[s], tvecs[s]));
  if (!(best_worst <= cfg_.ransac_threshold_px)) {
    cv::Mat rv, tv;
    const int consensus = consensus_without_one(img, rv, tv);
    if (consensus == kNumLeds - 1) return;  // four agree, one LED is an outlier: not this labelling
    if (consensus == kNumLeds) {
      rvecs.push_back(rv);
      tvecs.push_back(tv);
    }
  }
  for (size_t s = 0; s < rvecs.size(); ++s) refine_solution(h, img, sig, rvecs[s], tvecs[s]);
  std::sort(h.solutions.begin(), h.solutions.end(), [](const Solution& a, const Solution& b) { return a.ssr < b.ssr; });
}

PoseStatus LedPoseEstimator::choose_labelling(std::vector<Hypothesis>& hyps, const std::vector<double>& sig,
                                              LedPoseMeasurement& m) const {
  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.rms < b.rms; });
  const Hypothesis& best = hyps.front();
  if (best.solutions.empty()) {
    bool behind = false;
    for (const Hypothesis& h : hyps) behind = behind || h.behind;
    return behind ? PoseStatus::TargetBehindCamera : PoseStatus::SolverFailed;
  }
  m.reproj_rms_px = best.rms;
  if (best.rms > cfg_.max_reproj_rms_px) return PoseStatus::SolverFailed;
  if (hyps.size() > 1) {
    const Hypothesis& second = hyps[1];
    if (second.rms <= cfg_.max_reproj_rms_px &&
        second.rms < cfg_.ambiguity_ratio * std::max(best.rms, sig[best.idx[0]])) {
      return PoseStatus::AmbiguousIdentity;
    }
  }
  return PoseStatus::Ok;
}

// (J^T W J)^-1 in [r_hill_m, dtheta_b] at the pose (r, q), W the inverse
// centroid variances (sigma^2 (J^T J)^-1 when all are equal); info gets
// J^T W J. False when J^T W J is not positive or too ill-conditioned.
bool LedPoseEstimator::pose_covariance(const Eigen::Vector3d& r, const Eigen::Quaterniond& q,
                                       const PoseWeights& weights, Mat6& C, Mat6& info) const {
  Eigen::Matrix<double, 2 * kNumLeds, 6> J;
  if (!jacobian(r, q, weights.q_h_host, J)) return false;
  J = weights.inv_sig.asDiagonal() * J;  // whitened: J^T W J, W = diag(1 / sigma^2)
  const Mat6 JtJ = J.transpose() * J;
  const Eigen::SelfAdjointEigenSolver<Mat6> es(JtJ);
  const double lmin = es.eigenvalues()(0), lmax = es.eigenvalues()(5);
  if (!(lmin > 0.0) || lmax / lmin > cfg_.max_condition) return false;
  C = es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
  info = JtJ;
  return true;
}

// Planar pose ambiguity: a distinct second solution of the same labelling
// (the tilt mirrored about the line of sight) that fits nearly as well.
// Its posterior weight w (from the residual difference) decides: above
// flip_weight_max the pose is withheld (false: DegenerateGeometry); below
// it the covariance R about the chosen solution becomes the two-component
// mixture's, (1 - w) R + w (R_other + d d^T).
bool LedPoseEstimator::fold_mirror_solution(const Hypothesis& best, const PoseWeights& weights, const Mat6& info,
                                            LedPoseMeasurement& m, Mat6& R) const {
  const Solution& sb = best.solutions.front();
  for (size_t s = 1; s < best.solutions.size(); ++s) {
    const Solution& so = best.solutions[s];
    Eigen::Vector3d r_o;
    Eigen::Quaterniond q_o;
    nav_from_camera(so.R_cp, so.t_cp, weights.q_h_host, r_o, q_o);
    Vec6 d;
    d.head<3>() = r_o - m.r_hill_m;
    const Eigen::AngleAxisd aa(m.q_hb.conjugate() * q_o);
    d.tail<3>() = aa.angle() * aa.axis();
    if (d.dot(info * d) < 1.0) continue;  // the same minimum
    const double x = 0.5 * (so.wssr - sb.wssr);
    const double w = x > 50.0 ? 0.0 : 1.0 / (1.0 + std::exp(x));
    m.flip_weight = w;
    if (w > cfg_.flip_weight_max) return false;
    Mat6 R_o, info_o;
    if (w > 0.0 && pose_covariance(r_o, q_o, weights, R_o, info_o)) R = (1.0 - w) * R + w * (R_o + d * d.transpose());
    break;
  }
  return true;
}

LedPoseMeasurement LedPoseEstimator::estimate_from_points(const std::vector<cv::Point2d>& pts_in, double t_capture_s,
                                                          const Eigen::Quaterniond& q_h_host,
                                                          const std::vector<double>& sigma_px) const {
  LedPoseMeasurement m;
  m.t_capture_s = t_capture_s;
  if (!std::isfinite(t_capture_s) || !(std::abs(q_h_host.norm() - 1.0) < 1e-3))
    return with_status(m, PoseStatus::BadInput);
  std::vector<cv::Point2d> pts;
  std::vector<double> sig;  // centroid sigma per point [px]
  const bool enough = usable_points(pts_in, sigma_px, pts, sig);
  m.n_blobs = static_cast<int>(pts.size());
  if (!enough) return with_status(m, PoseStatus::TooFewLeds);
  // Degenerate spread: all points (nearly) on a line or a tiny hull.
  if (spread_degenerate(pts)) return with_status(m, PoseStatus::DegenerateGeometry);
  std::vector<Hypothesis> hyps;
  const bool any_collinear_triple = labellings(pts, hyps);
  m.n_hypotheses = static_cast<int>(hyps.size());
  if (hyps.empty()) return with_status(m, no_labelling_status(pts, any_collinear_triple));
  try {
    for (Hypothesis& h : hyps) solve_labelling(h, pts, sig);
  } catch (const cv::Exception&) {
    return with_status(m, PoseStatus::SolverFailed);
  }
  const PoseStatus chosen = choose_labelling(hyps, sig, m);
  if (chosen != PoseStatus::Ok) return with_status(m, chosen);
  // Camera-frame pose -> navigation measurement.
  const Hypothesis& best = hyps.front();
  m.R_cp = best.solutions.front().R_cp;
  m.t_cp_m = best.solutions.front().t_cp;
  m.blob_of_led = best.idx;
  m.range_m = (m.R_cp * pattern_centre() + m.t_cp_m).norm();
  nav_from_camera(m.R_cp, m.t_cp_m, q_h_host, m.r_hill_m, m.q_hb);
  PoseWeights weights{q_h_host, {}};
  for (int l = 0; l < kNumLeds; ++l) weights.inv_sig(2L * l) = weights.inv_sig(2L * l + 1) = 1.0 / sig[best.idx[l]];
  Mat6 R, info;
  if (!pose_covariance(m.r_hill_m, m.q_hb, weights, R, info)) return with_status(m, PoseStatus::DegenerateGeometry);
  if (!fold_mirror_solution(best, weights, info, m, R)) return with_status(m, PoseStatus::DegenerateGeometry);
  m.R = 0.5 * (R + R.transpose());
  return with_status(m, PoseStatus::Ok);
}

}  // namespace fsw_vision
