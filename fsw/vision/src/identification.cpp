// Identification: which points are the five LEDs. The usable points, the
// spread check, and the labellings: identifier k on edge (i -> j) at a
// fraction in the accepted range, i, j, c2, c3 a convex quadrilateral in
// that order, each scored by where the plane homography of its four corners
// puts the identifier (exact under projection for the planar pattern).
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "led_pose_detail.hpp"

namespace fsw_vision {

bool LedPoseEstimator::usable_points(const std::vector<cv::Point2d>& pts_in, const std::vector<double>& sigma_px,
                                     std::vector<cv::Point2d>& pts, std::vector<double>& sig) const {
  for (size_t i = 0; i < pts_in.size(); ++i) {
    const cv::Point2d& p = pts_in[i];
    const double si = i < sigma_px.size() ? sigma_px[i] : cfg_.pixel_sigma_px;
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !(si > 0.0) || !std::isfinite(si)) continue;
    pts.push_back(p);
    sig.push_back(si);
    if (static_cast<int>(pts.size()) >= cfg_.max_blobs) break;
  }
  return pts.size() >= 4;
}

bool LedPoseEstimator::spread_degenerate(const std::vector<cv::Point2d>& pts) const {
  std::vector<cv::Point2f> pf(pts.begin(), pts.end()), hull;
  cv::convexHull(pf, hull);
  return cv::contourArea(hull) < 0.5 * cfg_.min_quad_area_px2;
}

bool LedPoseEstimator::on_edge(const cv::Point2d& a, const cv::Point2d& b, const cv::Point2d& p, double& t) const {
  const cv::Point2d e = b - a;
  const double L = std::sqrt(e.dot(e));
  if (L < 2.0) return false;
  const double dist = std::abs(detail::cross2(e, p - a)) / L;
  t = e.dot(p - a) / (L * L);
  return dist <= cfg_.line_tol_px + cfg_.line_tol_rel * L;
}

void LedPoseEstimator::corner_labellings(const std::vector<cv::Point2d>& pts, const std::array<int, 3>& ijk,
                                         int& candidates, std::vector<detail::Hypothesis>& hyps) const {
  const int n = static_cast<int>(pts.size());
  const int i = ijk[0], j = ijk[1], k = ijk[2];
  const cv::Point2d e = pts[j] - pts[i];
  const double tol = cfg_.line_tol_px + cfg_.line_tol_rel * std::sqrt(e.dot(e));
  std::array<cv::Point2f, 4> quad_px;
  for (int c2 = 0; c2 < n; ++c2) {
    if (c2 == i || c2 == j || c2 == k) continue;
    for (int c3 = 0; c3 < n; ++c3) {
      if (c3 == i || c3 == j || c3 == k || c3 == c2) continue;
      const cv::Point2d* q[4] = {&pts[i], &pts[j], &pts[c2], &pts[c3]};
      if (0.5 * detail::convex_quad_area2(q) < cfg_.min_quad_area_px2) continue;
      ++candidates;
      for (int c = 0; c < 4; ++c) quad_px[c] = cv::Point2f(float(q[c]->x), float(q[c]->y));
      cv::Point2d mapped;
      if (!identifier_in_image(quad_px, mapped)) continue;
      const cv::Point2d dd = mapped - pts[k];
      const double score = std::sqrt(dd.dot(dd));
      if (!(score <= tol)) continue;
      detail::Hypothesis h;
      h.idx = {{i, j, c2, c3, k}};
      h.score = score;
      hyps.push_back(h);
    }
  }
}

bool LedPoseEstimator::labellings(const std::vector<cv::Point2d>& pts, std::vector<detail::Hypothesis>& hyps) const {
  const int n = static_cast<int>(pts.size());
  bool any_collinear_triple = false;
  constexpr int kMaxCandidates = 2000;  // bounds the work on a cluttered frame
  int candidates = 0;
  for (int i = 0; i < n && candidates < kMaxCandidates; ++i) {
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      for (int k = 0; k < n; ++k) {
        if (k == i || k == j) continue;
        double t = 0.0;
        if (!on_edge(pts[i], pts[j], pts[k], t)) continue;
        if (t > 0.0 && t < 1.0) any_collinear_triple = true;
        if (t < cfg_.id_fraction_min || t > cfg_.id_fraction_max) continue;
        corner_labellings(pts, {{i, j, k}}, candidates, hyps);
      }
    }
  }
  std::sort(hyps.begin(), hyps.end(),
            [](const detail::Hypothesis& a, const detail::Hypothesis& b) { return a.score < b.score; });
  if (static_cast<int>(hyps.size()) > cfg_.max_hypotheses) hyps.resize(cfg_.max_hypotheses);
  return any_collinear_triple;
}

PoseStatus LedPoseEstimator::no_labelling_status(const std::vector<cv::Point2d>& pts, bool any_collinear_triple) const {
  if (pts.size() != 4) return PoseStatus::TooFewLeds;
  // Four points: a corner missing (identifier on an edge of three) or the
  // identifier missing (a bare square, four-fold symmetric).
  const cv::Point2d* q[4] = {&pts[0], &pts[1], &pts[2], &pts[3]};
  bool convex = false;
  const int orders[3][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 1, 3, 2}};
  for (const auto& o : orders) {
    const cv::Point2d* qo[4] = {q[o[0]], q[o[1]], q[o[2]], q[o[3]]};
    if (0.5 * detail::convex_quad_area2(qo) >= cfg_.min_quad_area_px2) convex = true;
  }
  return (convex && !any_collinear_triple) ? PoseStatus::AmbiguousIdentity : PoseStatus::TooFewLeds;
}

namespace detail {

double convex_quad_area2(const cv::Point2d* q[4]) {
  double sgn = 0.0;
  for (int i = 0; i < 4; ++i) {
    const cv::Point2d e0 = *q[(i + 1) % 4] - *q[i];
    const cv::Point2d e1 = *q[(i + 2) % 4] - *q[(i + 1) % 4];
    const double c = cross2(e0, e1);
    if (c == 0.0) return 0.0;
    if (sgn == 0.0)
      sgn = c;
    else if ((c > 0.0) != (sgn > 0.0))
      return 0.0;
  }
  double a2 = 0.0;
  for (int i = 0; i < 4; ++i) a2 += cross2(*q[i], *q[(i + 1) % 4]);
  return std::abs(a2);
}

}  // namespace detail
}  // namespace fsw_vision
