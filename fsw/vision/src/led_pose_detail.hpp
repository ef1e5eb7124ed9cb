// Internals of the LED pose pipeline shared by its stages (fsw/vision/src/,
// not installed): small geometry helpers, the labelling and solution
// records, and the detection stages that need no estimator state.
//   detection.cpp          blobs: threshold, components, moments, shape gates
//   faint_spots.cpp        the matched-filter pass for faint spots
//   centroid.cpp           the refined centroid and its error model
//   geometry.cpp           camera <-> navigation frames, projection, Jacobian
//   identification.cpp     labellings of the points as the five LEDs
//   pose_solution.cpp      PnP per labelling, choice, covariance
//   merged_identifier.cpp  the identifier merged into its corner's blob
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "fsw_vision/led_pose.hpp"
#include "fsw_vision/spot_fit.hpp"

namespace fsw_vision {
namespace detail {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

inline double cross2(const cv::Point2d& a, const cv::Point2d& b) { return a.x * b.y - a.y * b.x; }

inline Eigen::Quaterniond quat_from_R(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

inline Eigen::Quaterniond exp_q(const Eigen::Vector3d& phi) {
  const double a = phi.norm();
  if (a < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(a, phi / a));
}

// m with status s.
inline LedPoseMeasurement with_status(LedPoseMeasurement m, PoseStatus s) {
  m.status = s;
  return m;
}

// The refined centroid may move this far from the first estimate [px]; a
// refinement that goes further gives up, and the first estimate is then
// known to be at least this far off.
constexpr double kMaxRefineShiftPx = 1.5;

// Twice the signed area of the quadrilateral q0 q1 q2 q3 if it is convex
// (all turns of one sign), else 0.
double convex_quad_area2(const cv::Point2d* q[4]);

// One pose of a labelling, host in the camera frame.
struct Solution {
  Eigen::Matrix3d R_cp;
  Eigen::Vector3d t_cp;
  double ssr = 0.0;   // sum of squared reprojection residuals [px^2]
  double wssr = 0.0;  // ... each divided by its centroid variance
};

// One labelling of the points as the five LEDs (idx: point per LED).
struct Hypothesis {
  std::array<int, kNumLeds> idx{};
  double score = 0.0;  // identifier's distance from its homography prediction [px]
  double rms = std::numeric_limits<double>::infinity();
  bool behind = false;              // a solution was behind the camera / back-facing
  std::vector<Solution> solutions;  // physical ones, best first
};

// A corner blob's one-spot fit and what a two-spot fit on its window
// needs (merged_identifier.cpp).
struct MergedFit {
  const cv::Mat& gray;
  SpotWindow win;
  PixelNoise noise;
  SpotFit one;
};

// One labelling's two-spot fit of a merged identifier: its chi-square gain
// over one spot, the corner it splits, and the fit.
struct MergedCandidate {
  double dchi2 = -std::numeric_limits<double>::infinity();
  int k = -1;
  SpotFit pair;
};

// Connected components as OpenCV gives them (label 0 the background) and
// their count n (labels 0 .. n-1).
struct Components {
  cv::Mat& labels;
  cv::Mat& stats;
  cv::Mat& cents;
  int n;
};

// The faint pass's settings (LedPoseConfig faint_*, min_area_px).
struct FaintPass {
  double sigma_px;
  double threshold_counts;
  int min_area_px;
};

// Faint spots (faint_spots.cpp): appends the matched filter's components
// that the plain threshold missed to comps, one per local maximum, as labels
// comps.n, comps.n + 1, ... with their stats and centroids; updates comps.n.
void append_faint_components(const cv::Mat& diff, const cv::Mat& mask, const FaintPass& pass, Components& comps);

// A faint-pass spot beside another is pulled towards it: that shift's
// size, added in quadrature to its sigma (detection.cpp).
void add_crowding_sigma(std::vector<Blob>& blobs, const std::vector<char>& faint, double w_min, double w_max);

// The image a centroid is refined on: gray levels, component labels and
// the components' first centroids.
struct CentroidImage {
  const cv::Mat& gray;
  const cv::Mat& labels;
  const cv::Mat& cents;
};

// One component to refine: its label, the first faint-pass label (labels
// from there on are distinct maxima, never fragments of this spot), its
// first estimate (u0, v0), its width from the moments and the Gaussian
// weight's width sigma_w [px].
struct CentroidSeed {
  int label;
  int first_faint;
  double u0, v0;
  double width_px;
  double sigma_w;
};

// The refined centroid with its error model (centroid.cpp). False (the
// caller keeps the first estimate) if the window or ring leaves the image,
// the ring has too few pixels, the iteration does not settle within
// kMaxRefineShiftPx of the first estimate (drifted set), or a denominator
// is not positive.
bool refine_centroid(const CentroidImage& image, const CentroidSeed& seed, const LedPoseConfig& cfg, Blob& out,
                     bool& drifted);

}  // namespace detail
}  // namespace fsw_vision
