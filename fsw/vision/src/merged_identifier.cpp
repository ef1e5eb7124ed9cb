// Blur at long range merges the identifier with corner 0 (a quarter of an
// edge apart) into one blob, which leaves the four corners: a square, four
// ways ambiguous. Every corner in turn, towards either neighbour, is taken
// as corner 0 of a labelling; the four corners' homography says where on
// that edge the identifier must be, and a fit of two spots of one width, the
// second held there, is compared with a fit of one spot on the same pixels.
// When one labelling's pair explains the blob by far the best, its corner 0
// and identifier join the other three corners, and the five points go
// through identification and pose like any others.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "led_pose_detail.hpp"

namespace fsw_vision {
namespace {

// Two spots of one width merge into one maximum only within about this
// many widths of each other: the farthest a merged identifier can be from
// its corner, which bounds the fit window.
constexpr double kMergedReachWidths = 3.0;

// A point that takes part in identification and in the reprojection gates
// but carries no weight in the pose covariance [px].
constexpr double kUnweightedSigmaPx = 1e3;

// The four blobs in convex order around their centroid: index and centre.
struct AroundCentre {
  std::array<int, 4> ord{{0, 1, 2, 3}};
  std::array<cv::Point2d, 4> px;
  cv::Point2d at(int k) const { return px[static_cast<size_t>((k + 4) % 4)]; }
};

AroundCentre around_centre(const std::vector<Blob>& blobs) {
  AroundCentre a;
  cv::Point2d centre(0.0, 0.0);
  for (const Blob& b : blobs) centre += cv::Point2d(b.u_px, b.v_px) * 0.25;
  std::sort(a.ord.begin(), a.ord.end(), [&](int x, int y) {
    return std::atan2(blobs[x].v_px - centre.y, blobs[x].u_px - centre.x) <
           std::atan2(blobs[y].v_px - centre.y, blobs[y].u_px - centre.x);
  });
  for (int k = 0; k < 4; ++k) a.px[static_cast<size_t>(k)] = cv::Point2d(blobs[a.ord[k]].u_px, blobs[a.ord[k]].v_px);
  return a;
}

}  // namespace

bool LedPoseEstimator::fit_merged_pair(const detail::MergedFit& fit, std::array<cv::Point2d, 4> corners,
                                       SpotFit& pair) const {
  const Eigen::Vector2d far(corners[1].x, corners[1].y);
  Eigen::Vector2d u0 = fit.one.u0;
  bool ok = true;
  // The fraction depends on corner 0, which the pair fit moves: twice.
  for (int pass = 0; pass < 2 && ok; ++pass) {
    corners[0] = cv::Point2d(u0(0), u0(1));
    const double f = identifier_fraction(corners);
    ok = std::isfinite(f) && f >= cfg_.id_fraction_min && f <= cfg_.id_fraction_max;
    if (!ok) break;
    pair = fit_spots(fit.gray, fit.win, fit.noise, SpotModel::PairOnLine, u0, fit.one.width_px, far, f);
    ok = pair.ok && pair.flux0 > 0.0 && pair.flux1 > 0.0;
    u0 = pair.u0;
  }
  if (!ok) return false;
  const double ratio = pair.flux1 / pair.flux0;
  return !(ratio > cfg_.merged_id_max_flux_ratio || ratio < 1.0 / cfg_.merged_id_max_flux_ratio);
}

void LedPoseEstimator::merged_candidates_at(const cv::Mat& gray, const std::array<cv::Point2d, 4>& around, int k,
                                            double width0, std::array<detail::MergedCandidate, 2>& top) const {
  auto pt = [&](int i) { return around[static_cast<size_t>((i + 4) % 4)]; };
  const cv::Point2d c = pt(k);
  const double e_max = std::max(cv::norm(pt(k + 1) - c), cv::norm(pt(k - 1) - c));
  const int half = std::clamp(
      static_cast<int>(std::ceil(3.0 * width0 + std::min(cfg_.id_fraction_max * e_max, kMergedReachWidths * width0))),
      4, cfg_.merged_id_max_half_window_px);
  const SpotWindow win{static_cast<int>(std::lround(c.y)) - half, static_cast<int>(std::lround(c.y)) + half + 1,
                       static_cast<int>(std::lround(c.x)) - half, static_cast<int>(std::lround(c.x)) + half + 1};
  const PixelNoise noise{cfg_.read_noise_counts, cfg_.shot_gain};
  const SpotFit one = fit_spots(gray, win, noise, SpotModel::One, Eigen::Vector2d(c.x, c.y), width0);
  if (!one.ok) return;
  const detail::MergedFit fit{gray, win, noise, one};
  for (const int dir : {+1, -1}) {
    detail::MergedCandidate cand;
    if (!fit_merged_pair(fit, {{c, pt(k + dir), pt(k + 2 * dir), pt(k + 3 * dir)}}, cand.pair)) continue;
    cand.dchi2 = one.chi2 - cand.pair.chi2;
    cand.k = k;
    if (cand.dchi2 > top[0].dchi2) {
      top[1] = top[0];
      top[0] = cand;
    } else if (cand.dchi2 > top[1].dchi2) {
      top[1] = cand;
    }
  }
}

LedPoseMeasurement LedPoseEstimator::pose_with_merged_identifier(const cv::Mat& gray, const std::vector<Blob>& blobs,
                                                                 double t_capture_s,
                                                                 const Eigen::Quaterniond& q_h_host) const {
  LedPoseMeasurement none;
  none.t_capture_s = t_capture_s;
  none.status = PoseStatus::AmbiguousIdentity;
  none.n_blobs = static_cast<int>(blobs.size());
  if (blobs.size() != 4) return none;
  const AroundCentre around = around_centre(blobs);
  double width0 = std::numeric_limits<double>::infinity();
  for (const Blob& b : blobs) width0 = std::min(width0, b.width_px);
  width0 = std::clamp(width0, 0.8, 4.0);
  std::array<detail::MergedCandidate, 2> top;  // best, second
  for (int k = 0; k < 4; ++k) merged_candidates_at(gray, around.px, k, width0, top);
  const detail::MergedCandidate& best = top[0];
  if (best.k < 0 || !(best.dchi2 >= cfg_.merged_id_min_dchi2) ||
      !(best.dchi2 - top[1].dchi2 >= cfg_.merged_id_margin_dchi2)) {
    return none;
  }
  // Corner 0 from the held fit (its covariance accounts for the identifier
  // beside it). The identifier's own position there is where the other
  // corners put it, so it carries no information of its own: it serves the
  // identification and enters the pose with a sigma that gives it no weight.
  const SpotFit& fit = best.pair;
  const double lmax = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(fit.cov_u0).eigenvalues()(1);
  std::vector<cv::Point2d> pts;
  std::vector<double> sig;
  for (int k = 0; k < 4; ++k) {
    if (k == best.k) {
      pts.emplace_back(fit.u0(0), fit.u0(1));
      sig.push_back(std::sqrt(std::max(lmax, 0.0) + cfg_.centroid_floor_px * cfg_.centroid_floor_px));
    } else {
      pts.emplace_back(blobs[around.ord[k]].u_px, blobs[around.ord[k]].v_px);
      sig.push_back(blobs[around.ord[k]].sigma_px);
    }
  }
  pts.emplace_back(fit.u1(0), fit.u1(1));
  sig.push_back(kUnweightedSigmaPx);
  LedPoseMeasurement m = estimate_from_points(pts, t_capture_s, q_h_host, sig);
  // An Ok pose must use the split as found: the new point as the identifier,
  // the blob it came out of as corner 0. A refusal after the split (most
  // often DegenerateGeometry: at long range the planar mirror pose fits
  // four corners nearly as well) is reported as such.
  if (m.status == PoseStatus::Ok && (m.blob_of_led[kIdentifier] != 4 || m.blob_of_led[0] != best.k)) return none;
  m.n_blobs = static_cast<int>(blobs.size());
  m.identifier_split = true;
  return m;
}

}  // namespace fsw_vision
