// LED pose pipeline: detection, identification, PnP, covariance.
// See led_pose.hpp and docs/VISION.md.
#include "fsw_vision/led_pose.hpp"

#include "fsw_vision/spot_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

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

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

double cross2(const cv::Point2d& a, const cv::Point2d& b) { return a.x * b.y - a.y * b.x; }

Eigen::Quaterniond quat_from_R(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

Eigen::Quaterniond exp_q(const Eigen::Vector3d& phi) {
  const double a = phi.norm();
  if (a < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(a, phi / a));
}

// The refined centroid may move this far from the first estimate [px]; a
// refinement that goes further gives up, and the first estimate is then
// known to be at least this far off.
constexpr double kMaxRefineShiftPx = 1.5;

// Faint spots (a blurred or distant LED whose peak stays under the plain
// threshold): the background-subtracted image smoothed by a Gaussian about
// as wide as a spot, a matched filter whose pixel noise is 1 / (2 sqrt(pi)
// sigma) of the raw image's, thresholded lower. Its components that touch
// none of the plain threshold's (not counting plain components smaller than
// min_area_px: a faint spot's noise peaks that poke through the plain
// threshold, which the shape gates drop) are split between their local maxima (two
// blurred LEDs a few pixels apart, the identifier beside its corner, join
// at a low threshold but keep two maxima), each pixel to the nearest, and
// appended after the plain components (labels n, n+1, ...) with their stats
// and centroids; detection then measures them alike (over-split fragments
// of one spot refine to the same centre and are merged there).
// Returns the new label count.
int append_faint_components(const cv::Mat& diff, const cv::Mat& mask, double sigma_px, double threshold_counts,
                            int min_area_px, cv::Mat& labels, cv::Mat& stats, cv::Mat& cents, int n) {
  thread_local cv::Mat diff_f, smooth, dil, fmask, flabels, fstats, fcents;  // see detect()
  diff.convertTo(diff_f, CV_32F);
  cv::GaussianBlur(diff_f, smooth, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::compare(smooth, threshold_counts, fmask, cv::CMP_GT);
  const int nf = cv::connectedComponentsWithStats(fmask, flabels, fstats, fcents, 8, CV_32S);
  if (nf <= 1) return n;
  std::vector<char> touches(static_cast<size_t>(nf), 0);
  for (int r = 0; r < mask.rows; ++r) {
    const uint8_t* m = mask.ptr<uint8_t>(r);
    const int* fl = flabels.ptr<int>(r);
    const int* pl = labels.ptr<int>(r);
    for (int c = 0; c < mask.cols; ++c)
      if (m[c] != 0 && fl[c] != 0 && stats.at<int>(pl[c], cv::CC_STAT_AREA) >= min_area_px)
        touches[static_cast<size_t>(fl[c])] = 1;
  }
  // Local maxima (3 x 3) of the kept components; one per 2-pixel neighbourhood.
  struct Peak {
    int r, c, comp, label;
  };
  std::vector<Peak> peaks;
  std::vector<std::vector<int>> peaks_of(static_cast<size_t>(nf));
  cv::dilate(smooth, dil, cv::Mat(), cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  for (int r = 0; r < smooth.rows; ++r) {
    const float* sm = smooth.ptr<float>(r);
    const float* dl = dil.ptr<float>(r);
    const int* fl = flabels.ptr<int>(r);
    for (int c = 0; c < smooth.cols; ++c) {
      const int comp = fl[c];
      if (comp == 0 || touches[static_cast<size_t>(comp)] || sm[c] < dl[c]) continue;
      bool near = false;
      for (int i : peaks_of[static_cast<size_t>(comp)]) {
        const Peak& q = peaks[static_cast<size_t>(i)];
        near = near || (std::abs(q.r - r) <= 2 && std::abs(q.c - c) <= 2);
      }
      if (near) continue;
      peaks_of[static_cast<size_t>(comp)].push_back(static_cast<int>(peaks.size()));
      peaks.push_back(Peak{r, c, comp, n + static_cast<int>(peaks.size())});
    }
  }
  if (peaks.empty()) return n;
  // Each pixel of a kept component to its nearest maximum; stats as OpenCV's.
  const size_t np = peaks.size();
  std::vector<int> left(np, labels.cols), top(np, labels.rows), right(np, -1), bottom(np, -1), area(np, 0);
  std::vector<double> sum_c(np, 0.0), sum_r(np, 0.0);
  for (int r = 0; r < labels.rows; ++r) {
    int* lab = labels.ptr<int>(r);
    const int* fl = flabels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) {
      const int comp = fl[c];
      if (comp == 0 || peaks_of[static_cast<size_t>(comp)].empty()) continue;
      int best = -1;
      long best_d2 = 0;
      for (int i : peaks_of[static_cast<size_t>(comp)]) {
        const long dr = peaks[static_cast<size_t>(i)].r - r, dc = peaks[static_cast<size_t>(i)].c - c;
        if (best < 0 || dr * dr + dc * dc < best_d2) best = i, best_d2 = dr * dr + dc * dc;
      }
      const size_t k = static_cast<size_t>(best);
      lab[c] = peaks[k].label;
      left[k] = std::min(left[k], c), right[k] = std::max(right[k], c);
      top[k] = std::min(top[k], r), bottom[k] = std::max(bottom[k], r);
      ++area[k];
      sum_c[k] += c, sum_r[k] += r;
    }
  }
  for (size_t k = 0; k < np; ++k) {
    const cv::Mat st =
        (cv::Mat_<int>(1, 5) << left[k], top[k], right[k] - left[k] + 1, bottom[k] - top[k] + 1, area[k]);
    stats.push_back(st);
    const cv::Mat ce = (cv::Mat_<double>(1, 2) << sum_c[k] / area[k], sum_r[k] / area[k]);
    cents.push_back(ce);
  }
  return n + static_cast<int>(np);
}

// A faint-pass spot beside another (two blurred LEDs a few widths apart) is
// pulled towards it: the neighbour's tail inside the Gaussian weight. For
// Gaussian spots (own weight width w, neighbour width s_j, flux ratio rho_j,
// distance d_j) the weighted centroid moves by about
// rho_j d_j (2 w^2 / (w^2 + s_j^2)) exp(-d_j^2 / (2 (w^2 + s_j^2))), the
// factor 2 being the refinement's step; added in quadrature to the spot's
// sigma, since its direction is not corrected.
void add_crowding_sigma(std::vector<Blob>& blobs, const std::vector<char>& faint, double w_min, double w_max) {
  std::vector<double> extra(blobs.size(), 0.0);
  for (size_t i = 0; i < blobs.size(); ++i) {
    if (!faint[i] || !(blobs[i].flux > 0.0)) continue;
    const double w = std::clamp(blobs[i].width_px, w_min, w_max);
    for (size_t j = 0; j < blobs.size(); ++j) {
      if (j == i || !(blobs[j].flux > 0.0)) continue;
      const double sj = std::max(blobs[j].width_px, 0.5);
      const double s2 = w * w + sj * sj;
      const double d = std::hypot(blobs[j].u_px - blobs[i].u_px, blobs[j].v_px - blobs[i].v_px);
      if (d * d > 25.0 * s2) continue;  // beyond 5 combined widths: under 1e-5 rho d
      const double shift = blobs[j].flux / blobs[i].flux * d * (2.0 * w * w / s2) * std::exp(-0.5 * d * d / s2);
      extra[i] += shift * shift;
    }
  }
  for (size_t i = 0; i < blobs.size(); ++i)
    blobs[i].sigma_px = std::sqrt(blobs[i].sigma_px * blobs[i].sigma_px + extra[i]);
}

// Twice the signed area of the quadrilateral q0 q1 q2 q3 if it is convex
// (all turns of one sign), else 0.
double convex_quad_area2(const cv::Point2d* q[4]) {
  double sgn = 0.0;
  for (int i = 0; i < 4; ++i) {
    const cv::Point2d e0 = *q[(i + 1) % 4] - *q[i];
    const cv::Point2d e1 = *q[(i + 2) % 4] - *q[(i + 1) % 4];
    const double c = cross2(e0, e1);
    if (c == 0.0) return 0.0;
    if (sgn == 0.0) sgn = c;
    else if ((c > 0.0) != (sgn > 0.0)) return 0.0;
  }
  double a2 = 0.0;
  for (int i = 0; i < 4; ++i) a2 += cross2(*q[i], *q[(i + 1) % 4]);
  return std::abs(a2);
}

struct Solution {
  Eigen::Matrix3d R_cp;
  Eigen::Vector3d t_cp;
  double ssr = 0.0;   // sum of squared reprojection residuals [px^2]
  double wssr = 0.0;  // ... each divided by its centroid variance
};

struct Hypothesis {
  std::array<int, kNumLeds> idx;
  double score = 0.0;  // identifier's distance from its homography prediction [px]
  double rms = std::numeric_limits<double>::infinity();
  bool behind = false;  // a solution was behind the camera / back-facing
  std::vector<Solution> solutions;  // physical ones, best first
};

}  // namespace

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

// ---------------------------------------------------------------------------
// Geometry.

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
  q_hb = quat_from_R(R_hb);
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
    double h;
    if (k < 3) {
      h = kStepM;
      rp(k) += h;
      rm(k) -= h;
    } else {
      h = kStepRad;
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d(k - 3) = h;
      qp = q_hb * exp_q(d);  // body-frame perturbation, as the filter's dtheta
      qm = q_hb * exp_q(-d);
    }
    if (!project(rp, qp, q_h_host, plus) || !project(rm, qm, q_h_host, minus)) return false;
    for (int i = 0; i < kNumLeds; ++i) {
      J(2 * i, k) = (plus[i].x - minus[i].x) / (2.0 * h);
      J(2 * i + 1, k) = (plus[i].y - minus[i].y) / (2.0 * h);
    }
  }
  return J.allFinite();
}

// ---------------------------------------------------------------------------
// Detection.

// Centroid of one component with its error model: a Gaussian-weighted
// centroid (weight width sigma_w, the spot's width from its moments) iterated
// to its fixed point sum W_i w_i (x_i - x) = 0, which for a symmetric spot is
// its centre whatever the pixel phase; the first estimate, an unweighted
// mean over the thresholded component's box, is pulled towards the pixel
// centre of undersampled spots and towards the box's centre by the tails it
// cuts off. The weights w_i are the signed differences from a background
// plane fitted to a ring around the window (pixels of other components and
// outliers dropped): clipping them at zero, or a background that contains
// the spot's own light, biases the centroid too.
//
// Variance, linearised at the fixed point: pixel noise (ring residual
// variance plus shot noise; saturated pixels none) and the background
// plane's error, scaled by centroid_noise_scale^2, plus the calibrated
// saturation term and the floor (docs/VISION.md, "Centroid error model").
// False (the caller keeps the first estimate) if the window or ring leaves
// the image, the ring has too few pixels, the iteration does not settle
// within 1.5 px of the first estimate, or a denominator is not positive.
bool LedPoseEstimator::refine_centroid(const cv::Mat& gray, const cv::Mat& labels, const cv::Mat& cents, int l,
                                       int first_faint, double u0, double v0, double width_px, double sigma_w,
                                       Blob& out, bool& drifted) const {
  drifted = false;
  constexpr int kRing = 2, kMinRing = 12, kMaxIter = 20;
  const int half = static_cast<int>(std::ceil(3.0 * sigma_w)) + 1;
  const int outer = half + kRing;
  const double inv2s2 = 0.5 / (sigma_w * sigma_w);
  double mu = u0, mv = v0;
  int cu = static_cast<int>(std::lround(mu)), cv0 = static_cast<int>(std::lround(mv));
  Eigen::Vector3d p = Eigen::Vector3d::Zero();  // background plane p0 + p1 (c - cu) + p2 (r - cv0)
  Eigen::Matrix3d AtA_inv = Eigen::Matrix3d::Zero();
  double base_var = 0.0;
  auto fit_background = [&]() {
    if (cu - outer < 0 || cv0 - outer < 0 || cu + outer >= gray.cols || cv0 + outer >= gray.rows) return false;
    std::vector<std::array<double, 3>> ring;  // dc, dr, value
    ring.reserve(static_cast<size_t>(8 * (outer + 1) * kRing));
    for (int r = cv0 - outer; r <= cv0 + outer; ++r) {
      const int* lab = labels.ptr<int>(r);
      const uint8_t* g = gray.ptr<uint8_t>(r);
      const bool row_in = std::abs(r - cv0) <= half;
      for (int c = cu - outer; c <= cu + outer; ++c) {
        if (row_in && std::abs(c - cu) <= half) continue;
        if (lab[c] != 0 || g[c] == 255) continue;
        ring.push_back({double(c - cu), double(r - cv0), double(g[c])});
      }
    }
    std::vector<char> use(ring.size(), 1);
    double ring_var = 0.0;
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
      Eigen::Vector3d Atz = Eigen::Vector3d::Zero();
      int k = 0;
      for (size_t i = 0; i < ring.size(); ++i) {
        if (!use[i]) continue;
        const Eigen::Vector3d a(1.0, ring[i][0], ring[i][1]);
        AtA += a * a.transpose();
        Atz += a * ring[i][2];
        ++k;
      }
      if (k < kMinRing || !(AtA.determinant() > 1e-9)) return false;
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(AtA);
      if (ldlt.info() != Eigen::Success) return false;
      p = ldlt.solve(Atz);
      AtA_inv = ldlt.solve(Eigen::Matrix3d::Identity());
      double ssr = 0.0;
      for (size_t i = 0; i < ring.size(); ++i) {
        if (!use[i]) continue;
        const double res = ring[i][2] - (p(0) + p(1) * ring[i][0] + p(2) * ring[i][1]);
        ssr += res * res;
      }
      ring_var = ssr / std::max(k - 3, 1);
      if (pass == 0) {
        // Drop ring pixels far off the plane (a neighbouring spot's tail, a line).
        const double lim = 3.5 * std::sqrt(std::max(ring_var, cfg_.read_noise_counts * cfg_.read_noise_counts));
        for (size_t i = 0; i < ring.size(); ++i) {
          const double res = ring[i][2] - (p(0) + p(1) * ring[i][0] + p(2) * ring[i][1]);
          if (std::abs(res) > lim) use[i] = 0;
        }
      }
    }
    base_var = std::max(ring_var, 0.5 * cfg_.read_noise_counts * cfg_.read_noise_counts);
    return true;
  };
  // Pixels of another component count as the spot's own when that
  // component's centre is within the weight's reach of this one (a faint
  // spot that the threshold broke into fragments); other objects are left out.
  auto own = [&](int lab) {
    if (lab == 0 || lab == l) return true;
    if (lab >= first_faint) return false;  // another maximum: a distinct spot
    const double dx = cents.at<double>(lab, 0) - u0, dy = cents.at<double>(lab, 1) - v0;
    return dx * dx + dy * dy < (2.0 * sigma_w + 1.5) * (2.0 * sigma_w + 1.5);
  };
  if (!fit_background()) return false;
  // Fixed-point iteration x <- x + 2 sum W w (x_i - x) / sum W w (the factor
  // 2 is exact for a Gaussian spot as wide as the weight).
  double swu = 0.0, swv = 0.0, sw = 0.0;
  bool settled = false;
  for (int it = 0; it < kMaxIter; ++it) {
    swu = swv = sw = 0.0;
    double hu = 0.0, hv = 0.0;
    for (int r = cv0 - half; r <= cv0 + half; ++r) {
      const int* lab = labels.ptr<int>(r);
      const uint8_t* g = gray.ptr<uint8_t>(r);
      const double dr = r - mv;
      for (int c = cu - half; c <= cu + half; ++c) {
        if (!own(lab[c])) continue;
        const double dc = c - mu;
        const double W = std::exp(-(dc * dc + dr * dr) * inv2s2);
        const double wgt = W * (g[c] - (p(0) + p(1) * (c - cu) + p(2) * (r - cv0)));
        sw += wgt;
        swu += wgt * dc;
        swv += wgt * dr;
        hu += wgt * (1.0 - dc * dc * 2.0 * inv2s2);
        hv += wgt * (1.0 - dr * dr * 2.0 * inv2s2);
      }
    }
    if (!(sw > 0.0)) return false;
    // Newton step on F: dx = sum W w dx_i / sum W w (1 - dx_i^2 / sigma_w^2);
    // the factor-2 step where that denominator is not safely positive.
    const double du = hu > 0.1 * sw ? swu / hu : 2.0 * swu / sw;
    const double dv = hv > 0.1 * sw ? swv / hv : 2.0 * swv / sw;
    mu += du;
    mv += dv;
    if (!(std::abs(mu - u0) < kMaxRefineShiftPx && std::abs(mv - v0) < kMaxRefineShiftPx)) {
      drifted = true;
      return false;
    }
    const int ncu = static_cast<int>(std::lround(mu)), ncv = static_cast<int>(std::lround(mv));
    if (ncu != cu || ncv != cv0) {
      cu = ncu;
      cv0 = ncv;
      if (!fit_background()) return false;
      continue;
    }
    if (std::abs(du) < 1e-4 && std::abs(dv) < 1e-4) {
      settled = true;
      break;
    }
  }
  if (!settled) return false;
  // Linearisation at the fixed point F(x) = sum W_i w_i (x_i - x) = 0:
  // dF/dw_i = W_i (x_i - x), dF/dx = sum W_i w_i ((x_i - x)^2 / sigma_w^2 - 1),
  // dF/dp = -sum W_i (x_i - x) a_i.
  double vu = 0.0, vv = 0.0, du_dx = 0.0, dv_dx = 0.0, flux = 0.0;
  int n_sat = 0;
  Eigen::Vector3d Gu = Eigen::Vector3d::Zero(), Gv = Eigen::Vector3d::Zero();
  for (int r = cv0 - half; r <= cv0 + half; ++r) {
    const int* lab = labels.ptr<int>(r);
    const uint8_t* g = gray.ptr<uint8_t>(r);
    const double dr = r - mv;
    for (int c = cu - half; c <= cu + half; ++c) {
      if (!own(lab[c])) continue;
      const double dc = c - mu;
      const double W = std::exp(-(dc * dc + dr * dr) * inv2s2);
      const double wgt = g[c] - (p(0) + p(1) * (c - cu) + p(2) * (r - cv0));
      const double var = g[c] == 255 ? 0.0 : base_var + cfg_.shot_gain * std::max(wgt, 0.0);
      vu += W * W * dc * dc * var;
      vv += W * W * dr * dr * var;
      du_dx += W * wgt * (dc * dc * 2.0 * inv2s2 - 1.0);
      dv_dx += W * wgt * (dr * dr * 2.0 * inv2s2 - 1.0);
      const Eigen::Vector3d a(1.0, double(c - cu), double(r - cv0));
      Gu += W * dc * a;
      Gv += W * dr * a;
      flux += wgt;
      n_sat += g[c] == 255;
    }
  }
  if (!(du_dx < 0.0) || !(dv_dx < 0.0)) return false;
  vu = (vu + base_var * Gu.dot(AtA_inv * Gu)) / (du_dx * du_dx);
  vv = (vv + base_var * Gv.dot(AtA_inv * Gv)) / (dv_dx * dv_dx);
  const double var_noise = std::max(vu, vv);
  const double k = cfg_.centroid_noise_scale;
  // Saturated spot: the plateau's edge is sampled by the pixels, an error
  // the noise leaves out, largest for a large plateau on a narrow spot
  // (a sharp edge): sat_sigma_px n_sat / max(width / 1 px, 1)^4.
  const double w2 = std::max(width_px, 1.0) * std::max(width_px, 1.0);
  const double sat = cfg_.sat_sigma_px * n_sat / (w2 * w2);
  const double var = k * k * var_noise + sat * sat + cfg_.centroid_floor_px * cfg_.centroid_floor_px;
  out.u_px = mu;
  out.v_px = mv;
  out.flux = flux > 0.0 ? flux : sw;
  out.sigma_px = std::sqrt(var);
  out.n_saturated = n_sat;
  out.sigma_noise_px = std::sqrt(var_noise);
  return std::isfinite(out.sigma_px) && out.sigma_px > 0.0 && std::isfinite(mu) && std::isfinite(mv);
}

std::vector<Blob> LedPoseEstimator::detect(const cv::Mat& gray, bool faint_pass) const {
  std::vector<Blob> out;
  if (gray.empty() || gray.type() != CV_8UC1) return out;
  // Frame-sized buffers kept per thread: a fresh one per frame is mostly
  // page faults (docs/perf/vision.md).
  thread_local cv::Mat bg, diff, mask, labels, stats, cents;
  const int k = std::max(3, cfg_.background_kernel_px | 1);
  cv::blur(gray, bg, cv::Size(k, k), cv::Point(-1, -1), cv::BORDER_REPLICATE);
  cv::subtract(gray, bg, diff);  // saturates at 0
  cv::threshold(diff, mask, cfg_.threshold_counts, 255, cv::THRESH_BINARY);
  int n = cv::connectedComponentsWithStats(mask, labels, stats, cents, 8, CV_32S);
  const int first_faint = n;
  std::vector<char> faint;  // per blob in out: found by the faint pass
  if (faint_pass && cfg_.faint_sigma_px > 0.0)
    n = append_faint_components(diff, mask, cfg_.faint_sigma_px, cfg_.faint_threshold_counts, cfg_.min_area_px, labels,
                                stats, cents, n);
  for (int l = 1; l < n; ++l) {
    const int area = stats.at<int>(l, cv::CC_STAT_AREA);
    const int x0 = stats.at<int>(l, cv::CC_STAT_LEFT), y0 = stats.at<int>(l, cv::CC_STAT_TOP);
    const int w = stats.at<int>(l, cv::CC_STAT_WIDTH), h = stats.at<int>(l, cv::CC_STAT_HEIGHT);
    if (area < cfg_.min_area_px || area > cfg_.max_area_px) continue;
    if (w > cfg_.max_extent_px || h > cfg_.max_extent_px) continue;
    // Background-subtracted intensity moments over the component's pixels.
    double s = 0.0, su = 0.0, sv = 0.0, suu = 0.0, svv = 0.0, suv = 0.0;
    double sn = 0.0, snu = 0.0, snv = 0.0, snuu = 0.0, snvv = 0.0;  // pixel-noise moments
    bool any_sat = false;
    // Over the component's box grown by kPad, so that the spot's tails below
    // the threshold count too (a centroid of the thresholded core alone is
    // pulled towards pixel centres); pixels of other components excluded.
    constexpr int kPad = 2;
    const int ra = std::max(y0 - kPad, 0), rb = std::min(y0 + h + kPad, gray.rows);
    const int ca = std::max(x0 - kPad, 0), cb = std::min(x0 + w + kPad, gray.cols);
    for (int r = ra; r < rb; ++r) {
      const int* lab = labels.ptr<int>(r);
      const uint8_t* d = diff.ptr<uint8_t>(r);
      const uint8_t* g = gray.ptr<uint8_t>(r);
      for (int c = ca; c < cb; ++c) {
        if (lab[c] != l && lab[c] != 0) continue;
        const double wgt = d[c];
        s += wgt;
        su += wgt * c;
        sv += wgt * r;
        suu += wgt * c * c;
        svv += wgt * r * r;
        suv += wgt * c * r;
        // A saturated pixel carries no noise (it carries no information either,
        // but its weight is the clipped value, symmetric about the centre).
        any_sat = any_sat || g[c] == 255;
        const double nv = g[c] == 255 ? 0.0 : cfg_.read_noise_counts * cfg_.read_noise_counts + cfg_.shot_gain * wgt;
        sn += nv;
        snu += nv * c;
        snv += nv * r;
        snuu += nv * c * c;
        snvv += nv * r * r;
      }
    }
    if (!(s > 0.0)) continue;
    const double mu = su / s, mv = sv / s;
    // Second moments, plus a pixel's own variance so that tiny blobs are round.
    const double a = suu / s - mu * mu + 1.0 / 12.0;
    const double c = svv / s - mv * mv + 1.0 / 12.0;
    const double b = suv / s - mu * mv;
    const double half_tr = 0.5 * (a + c);
    const double disc = std::sqrt(std::max(0.0, 0.25 * (a - c) * (a - c) + b * b));
    const double lam1 = half_tr + disc, lam2 = std::max(half_tr - disc, 1e-9);
    if (std::sqrt(lam1 / lam2) > cfg_.max_elongation) continue;  // lines, streaks
    // Refined centroid (see refine_centroid): Gaussian-weighted, iterated from
    // this first estimate, on a local background plane, with the calibrated
    // error model; the weight's width is the spot's from its moments.
    Blob blob;
    const double width = std::sqrt(std::max(half_tr - 1.0 / 12.0, 0.0));
    const double sigma_w = std::clamp(width * (any_sat ? cfg_.centroid_weight_sat_scale : 1.0),
                                      cfg_.centroid_weight_min_px, cfg_.centroid_weight_max_px);
    blob.width_px = width;
    bool drifted = false;
    if (cfg_.refine_centroid &&
        refine_centroid(gray, labels, cents, l, first_faint, mu, mv, width, sigma_w, blob, drifted)) {
      blob.area_px = area;
      out.push_back(blob);
      faint.push_back(l >= first_faint);
      continue;
    }
    // Fallback (window or ring cut by the image border, the refinement not
    // settling or drifting; or refinement off):
    // the first estimate with its pixel-noise sigma.
    const double var_u = (snuu - 2.0 * mu * snu + mu * mu * sn) / (s * s);
    const double var_v = (snvv - 2.0 * mv * snv + mv * mv * sn) / (s * s);
    const double sig_noise = std::sqrt(std::max(var_u, var_v) + cfg_.centroid_floor_px * cfg_.centroid_floor_px);
    // A refinement that drifted away says the first estimate is off by that
    // much (a fragment of a wider spot, its window cut): its pixel noise
    // does not.
    const double sig = drifted ? std::max(sig_noise, kMaxRefineShiftPx) : sig_noise;
    out.push_back(Blob{mu, mv, s, area, sig, 0, sig_noise, width});
    faint.push_back(l >= first_faint);
  }
  add_crowding_sigma(out, faint, cfg_.centroid_weight_min_px, cfg_.centroid_weight_max_px);
  std::sort(out.begin(), out.end(), [](const Blob& x, const Blob& y) { return x.flux > y.flux; });
  // Fragments of one spot refine to the same centre: keep the brightest.
  std::vector<Blob> kept;
  for (const Blob& b : out) {
    bool dup = false;
    for (const Blob& k : kept) dup = dup || std::hypot(b.u_px - k.u_px, b.v_px - k.v_px) < 1.0;
    if (!dup) kept.push_back(b);
  }
  out.swap(kept);
  if (static_cast<int>(out.size()) > cfg_.max_blobs) out.resize(cfg_.max_blobs);
  return out;
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
    const LedPoseMeasurement split = pose_with_merged_identifier(gray, blobs, t_capture_s, q_h_host);
    if (split.identifier_split) return split;  // Ok, or why not once the identifier is found
  }
  return m;
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

// Two spots of one width merge into one maximum only within about this
// many widths of each other: the farthest a merged identifier can be from
// its corner, which bounds the fit window.
constexpr double kMergedReachWidths = 3.0;

// A point that takes part in identification and in the reprojection gates
// but carries no weight in the pose covariance [px].
constexpr double kUnweightedSigmaPx = 1e3;

// Blur at long range merges the identifier with corner 0 (a quarter of an
// edge apart) into one blob, which leaves the four corners: a square, four
// ways ambiguous. Every corner in turn, towards either neighbour, is taken
// as corner 0 of a labelling; the four corners' homography says where on
// that edge the identifier must be, and a fit of two spots of one width, the
// second held there, is compared with a fit of one spot on the same pixels.
// When one labelling's pair explains the blob by far the best, its corner 0
// and identifier join the other three corners, and the five points go
// through identification and pose like any others.
LedPoseMeasurement LedPoseEstimator::pose_with_merged_identifier(const cv::Mat& gray, const std::vector<Blob>& blobs,
                                                                 double t_capture_s,
                                                                 const Eigen::Quaterniond& q_h_host) const {
  LedPoseMeasurement none;
  none.t_capture_s = t_capture_s;
  none.status = PoseStatus::AmbiguousIdentity;
  none.n_blobs = static_cast<int>(blobs.size());
  if (blobs.size() != 4) return none;

  // Convex order around the centroid.
  cv::Point2d centre(0.0, 0.0);
  for (const Blob& b : blobs) centre += cv::Point2d(b.u_px, b.v_px) * 0.25;
  std::array<int, 4> ord{{0, 1, 2, 3}};
  std::sort(ord.begin(), ord.end(), [&](int a, int b) {
    return std::atan2(blobs[a].v_px - centre.y, blobs[a].u_px - centre.x) <
           std::atan2(blobs[b].v_px - centre.y, blobs[b].u_px - centre.x);
  });
  auto pt = [&](int k) { return cv::Point2d(blobs[ord[(k + 4) % 4]].u_px, blobs[ord[(k + 4) % 4]].v_px); };
  double width0 = std::numeric_limits<double>::infinity();
  for (const Blob& b : blobs) width0 = std::min(width0, b.width_px);
  width0 = std::clamp(width0, 0.8, 4.0);
  const PixelNoise noise{cfg_.read_noise_counts, cfg_.shot_gain};

  struct Candidate {
    double dchi2 = -std::numeric_limits<double>::infinity();
    int k = -1;
    SpotFit pair;
  };
  Candidate best, second;
  for (int k = 0; k < 4; ++k) {
    const cv::Point2d c = pt(k);
    const double e_max = std::max(cv::norm(pt(k + 1) - c), cv::norm(pt(k - 1) - c));
    const int half = std::clamp(
        static_cast<int>(std::ceil(3.0 * width0 + std::min(cfg_.id_fraction_max * e_max, kMergedReachWidths * width0))),
        4, cfg_.merged_id_max_half_window_px);
    const SpotWindow win{static_cast<int>(std::lround(c.y)) - half, static_cast<int>(std::lround(c.y)) + half + 1,
                         static_cast<int>(std::lround(c.x)) - half, static_cast<int>(std::lround(c.x)) + half + 1};
    const Eigen::Vector2d c_e(c.x, c.y);
    const SpotFit one = fit_spots(gray, win, noise, SpotModel::One, c_e, width0);
    if (!one.ok) continue;
    for (const int dir : {+1, -1}) {
      std::array<cv::Point2d, 4> corners{{c, pt(k + dir), pt(k + 2 * dir), pt(k + 3 * dir)}};
      const Eigen::Vector2d far(corners[1].x, corners[1].y);
      SpotFit pair;
      Eigen::Vector2d u0 = one.u0;
      bool ok = true;
      // The fraction depends on corner 0, which the pair fit moves: twice.
      for (int pass = 0; pass < 2 && ok; ++pass) {
        corners[0] = cv::Point2d(u0(0), u0(1));
        const double f = identifier_fraction(corners);
        ok = std::isfinite(f) && f >= cfg_.id_fraction_min && f <= cfg_.id_fraction_max;
        if (!ok) break;
        pair = fit_spots(gray, win, noise, SpotModel::PairOnLine, u0, one.width_px, far, f);
        ok = pair.ok && pair.flux0 > 0.0 && pair.flux1 > 0.0;
        u0 = pair.u0;
      }
      if (!ok) continue;
      const double ratio = pair.flux1 / pair.flux0;
      if (ratio > cfg_.merged_id_max_flux_ratio || ratio < 1.0 / cfg_.merged_id_max_flux_ratio) continue;
      Candidate cand;
      cand.dchi2 = one.chi2 - pair.chi2;
      cand.k = k;
      cand.pair = pair;
      if (cand.dchi2 > best.dchi2) {
        second = best;
        best = cand;
      } else if (cand.dchi2 > second.dchi2) {
        second = cand;
      }
    }
  }
  if (best.k < 0 || !(best.dchi2 >= cfg_.merged_id_min_dchi2) ||
      !(best.dchi2 - second.dchi2 >= cfg_.merged_id_margin_dchi2)) {
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
      pts.emplace_back(blobs[ord[k]].u_px, blobs[ord[k]].v_px);
      sig.push_back(blobs[ord[k]].sigma_px);
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

// ---------------------------------------------------------------------------
// Identification and pose.

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

LedPoseMeasurement LedPoseEstimator::estimate_from_points(const std::vector<cv::Point2d>& pts_in, double t_capture_s,
                                                          const Eigen::Quaterniond& q_h_host,
                                                          const std::vector<double>& sigma_px) const {
  LedPoseMeasurement m;
  m.t_capture_s = t_capture_s;
  const double qn = q_h_host.norm();
  if (!std::isfinite(t_capture_s) || !(std::abs(qn - 1.0) < 1e-3)) {
    m.status = PoseStatus::BadInput;
    return m;
  }
  std::vector<cv::Point2d> pts;
  std::vector<double> sig;  // centroid sigma per point [px]
  for (size_t i = 0; i < pts_in.size(); ++i) {
    const cv::Point2d& p = pts_in[i];
    const double si = i < sigma_px.size() ? sigma_px[i] : cfg_.pixel_sigma_px;
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !(si > 0.0) || !std::isfinite(si)) continue;
    pts.push_back(p);
    sig.push_back(si);
    if (static_cast<int>(pts.size()) >= cfg_.max_blobs) break;
  }
  const int n = static_cast<int>(pts.size());
  m.n_blobs = n;
  if (n < 4) {
    m.status = PoseStatus::TooFewLeds;
    return m;
  }

  // Degenerate spread: all points (nearly) on a line or a tiny hull.
  {
    std::vector<cv::Point2f> pf(pts.begin(), pts.end()), hull;
    cv::convexHull(pf, hull);
    if (cv::contourArea(hull) < 0.5 * cfg_.min_quad_area_px2) {
      m.status = PoseStatus::DegenerateGeometry;
      return m;
    }
  }

  auto on_edge = [&](const cv::Point2d& a, const cv::Point2d& b, const cv::Point2d& p, double& t) {
    const cv::Point2d e = b - a;
    const double L = std::sqrt(e.dot(e));
    if (L < 2.0) return false;
    const double dist = std::abs(cross2(e, p - a)) / L;
    t = e.dot(p - a) / (L * L);
    return dist <= cfg_.line_tol_px + cfg_.line_tol_rel * L;
  };

  // Labellings: identifier k on edge (i -> j) at fraction t in the accepted
  // range, and i, j, c2, c3 a convex quadrilateral in that order. Each is
  // scored by where the plane homography of its four corners puts the
  // identifier (exact under projection for the planar pattern).
  std::vector<Hypothesis> hyps;
  bool any_collinear_triple = false;
  constexpr int kMaxCandidates = 2000;  // bounds the work on a cluttered frame
  int candidates = 0;
  std::array<cv::Point2f, 4> quad_px;
  for (int i = 0; i < n && candidates < kMaxCandidates; ++i) {
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      for (int k = 0; k < n; ++k) {
        if (k == i || k == j) continue;
        double t = 0.0;
        if (!on_edge(pts[i], pts[j], pts[k], t)) continue;
        if (t > 0.0 && t < 1.0) any_collinear_triple = true;
        if (t < cfg_.id_fraction_min || t > cfg_.id_fraction_max) continue;
        const cv::Point2d e = pts[j] - pts[i];
        const double tol = cfg_.line_tol_px + cfg_.line_tol_rel * std::sqrt(e.dot(e));
        for (int c2 = 0; c2 < n; ++c2) {
          if (c2 == i || c2 == j || c2 == k) continue;
          for (int c3 = 0; c3 < n; ++c3) {
            if (c3 == i || c3 == j || c3 == k || c3 == c2) continue;
            const cv::Point2d* q[4] = {&pts[i], &pts[j], &pts[c2], &pts[c3]};
            if (0.5 * convex_quad_area2(q) < cfg_.min_quad_area_px2) continue;
            ++candidates;
            for (int c = 0; c < 4; ++c) quad_px[c] = cv::Point2f(float(q[c]->x), float(q[c]->y));
            cv::Point2d mapped;
            if (!identifier_in_image(quad_px, mapped)) continue;
            const cv::Point2d dd = mapped - pts[k];
            const double score = std::sqrt(dd.dot(dd));
            if (!(score <= tol)) continue;
            Hypothesis h;
            h.idx = {{i, j, c2, c3, k}};
            h.score = score;
            hyps.push_back(h);
          }
        }
      }
    }
  }
  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score < b.score; });
  if (static_cast<int>(hyps.size()) > cfg_.max_hypotheses) hyps.resize(cfg_.max_hypotheses);
  m.n_hypotheses = static_cast<int>(hyps.size());

  if (hyps.empty()) {
    if (n == 4) {
      // Four points: a corner missing (identifier on an edge of three) or the
      // identifier missing (a bare square, four-fold symmetric).
      const cv::Point2d* q[4] = {&pts[0], &pts[1], &pts[2], &pts[3]};
      bool convex = false;
      const int orders[3][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 1, 3, 2}};
      for (const auto& o : orders) {
        const cv::Point2d* qo[4] = {q[o[0]], q[o[1]], q[o[2]], q[o[3]]};
        if (0.5 * convex_quad_area2(qo) >= cfg_.min_quad_area_px2) convex = true;
      }
      m.status = (convex && !any_collinear_triple) ? PoseStatus::AmbiguousIdentity : PoseStatus::TooFewLeds;
    } else {
      m.status = PoseStatus::TooFewLeds;
    }
    return m;
  }

  // Pose per labelling: IPPE (both planar solutions) and the consensus
  // gate's solution when it found one, each refined by Levenberg-Marquardt;
  // the physical ones are kept and the labelling's best is the one with the
  // smallest reprojection error.
  const Eigen::Vector3d centre_p = [&] {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int i = 0; i < 4; ++i) c += cfg_.pattern.p_host_m[i];
    return Eigen::Vector3d(c / 4.0);
  }();
  auto to_eigen = [](const cv::Mat& rvec, const cv::Mat& tvec, Eigen::Matrix3d& R, Eigen::Vector3d& t) {
    cv::Mat Rcv;
    cv::Rodrigues(rvec, Rcv);
    for (int r = 0; r < 3; ++r) {
      t(r) = tvec.at<double>(r);
      for (int c = 0; c < 3; ++c) R(r, c) = Rcv.at<double>(r, c);
    }
  };
  auto physical = [&](const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
    for (int i = 0; i < kNumLeds; ++i) {
      if ((R * cfg_.pattern.p_host_m[i] + t).z() <= cfg_.min_depth_m) return false;
    }
    // The LEDs shine from the face's outer side only.
    return (R * cfg_.pattern.normal_host).dot(R * centre_p + t) < 0.0;
  };

  // Largest single-LED reprojection error [px] of a pose.
  auto worst_residual = [&](const std::vector<cv::Point2d>& img, const cv::Mat& rv, const cv::Mat& tv) {
    std::vector<cv::Point2d> rep;
    cv::projectPoints(obj_, rv, tv, K_, dist_, rep);
    double worst = 0.0;
    for (int l = 0; l < kNumLeds; ++l) worst = std::max(worst, cv::norm(rep[l] - img[l]));
    return worst;
  };

  try {
    for (Hypothesis& h : hyps) {
      std::vector<cv::Point2d> img(kNumLeds);
      for (int l = 0; l < kNumLeds; ++l) img[l] = pts[h.idx[l]];
      std::vector<cv::Mat> rvecs, tvecs;
      cv::solvePnPGeneric(obj_, img, K_, dist_, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
      // Robust gate: every LED must be within the threshold of a fit. An IPPE
      // solution with every LED within it is that fit (the consensus of all
      // five); otherwise the consensus is searched over the five minimal sets
      // (see consensus_without_one).
      double best_worst = std::numeric_limits<double>::infinity();
      for (size_t s = 0; s < rvecs.size(); ++s)
        best_worst = std::min(best_worst, worst_residual(img, rvecs[s], tvecs[s]));
      if (!(best_worst <= cfg_.ransac_threshold_px)) {
        cv::Mat rv, tv;
        const int consensus = consensus_without_one(img, rv, tv);
        if (consensus == kNumLeds - 1) continue;  // four agree, one LED is an outlier: not this labelling
        if (consensus == kNumLeds) {
          rvecs.push_back(rv);
          tvecs.push_back(tv);
        }
      }
      for (size_t s = 0; s < rvecs.size(); ++s) {
        cv::Mat rv = rvecs[s].clone(), tv = tvecs[s].clone();
        rv.convertTo(rv, CV_64F);
        tv.convertTo(tv, CV_64F);
        cv::solvePnPRefineLM(obj_, img, K_, dist_, rv, tv);
        Solution sol;
        to_eigen(rv, tv, sol.R_cp, sol.t_cp);
        if (!sol.R_cp.allFinite() || !sol.t_cp.allFinite() || !physical(sol.R_cp, sol.t_cp)) {
          h.behind = true;
          continue;
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
      std::sort(h.solutions.begin(), h.solutions.end(),
                [](const Solution& a, const Solution& b) { return a.ssr < b.ssr; });
    }
  } catch (const cv::Exception&) {
    m.status = PoseStatus::SolverFailed;
    return m;
  }

  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.rms < b.rms; });
  const Hypothesis& best = hyps.front();
  if (best.solutions.empty()) {
    bool behind = false;
    for (const Hypothesis& h : hyps) behind = behind || h.behind;
    m.status = behind ? PoseStatus::TargetBehindCamera : PoseStatus::SolverFailed;
    return m;
  }
  m.reproj_rms_px = best.rms;
  if (best.rms > cfg_.max_reproj_rms_px) {
    m.status = PoseStatus::SolverFailed;
    return m;
  }
  if (hyps.size() > 1) {
    const Hypothesis& second = hyps[1];
    if (second.rms <= cfg_.max_reproj_rms_px &&
        second.rms < cfg_.ambiguity_ratio * std::max(best.rms, sig[best.idx[0]])) {
      m.status = PoseStatus::AmbiguousIdentity;
      return m;
    }
  }

  // Camera-frame pose -> navigation measurement.
  const Solution& sb = best.solutions.front();
  m.R_cp = sb.R_cp;
  m.t_cp_m = sb.t_cp;
  m.blob_of_led = best.idx;
  m.range_m = (m.R_cp * centre_p + m.t_cp_m).norm();
  nav_from_camera(m.R_cp, m.t_cp_m, q_h_host, m.r_hill_m, m.q_hb);

  // Covariance: (J^T W J)^-1 in [r_hill_m, dtheta_b], W the inverse centroid
  // variances (sigma^2 (J^T J)^-1 when all are equal).
  Eigen::Matrix<double, 2 * kNumLeds, 1> inv_sig;
  for (int l = 0; l < kNumLeds; ++l) inv_sig(2 * l) = inv_sig(2 * l + 1) = 1.0 / sig[best.idx[l]];
  auto covariance = [&](const Eigen::Vector3d& r, const Eigen::Quaterniond& q, Mat6& C, Mat6& info) {
    Eigen::Matrix<double, 2 * kNumLeds, 6> J;
    if (!jacobian(r, q, q_h_host, J)) return false;
    J = inv_sig.asDiagonal() * J;  // whitened: J^T W J, W = diag(1 / sigma^2)
    const Mat6 JtJ = J.transpose() * J;
    const Eigen::SelfAdjointEigenSolver<Mat6> es(JtJ);
    const double lmin = es.eigenvalues()(0), lmax = es.eigenvalues()(5);
    if (!(lmin > 0.0) || lmax / lmin > cfg_.max_condition) return false;
    C = es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
    info = JtJ;
    return true;
  };
  Mat6 R, info;
  if (!covariance(m.r_hill_m, m.q_hb, R, info)) {
    m.status = PoseStatus::DegenerateGeometry;
    return m;
  }

  // Planar pose ambiguity: a distinct second solution of the same labelling
  // (the tilt mirrored about the line of sight) that fits nearly as well.
  // Its posterior weight w (from the residual difference) decides: above
  // flip_weight_max the pose is withheld (DegenerateGeometry); below it the
  // covariance about the chosen solution becomes the two-component mixture's,
  // (1 - w) R + w (R_other + d d^T).
  for (size_t s = 1; s < best.solutions.size(); ++s) {
    const Solution& so = best.solutions[s];
    Eigen::Vector3d r_o;
    Eigen::Quaterniond q_o;
    nav_from_camera(so.R_cp, so.t_cp, q_h_host, r_o, q_o);
    Vec6 d;
    d.head<3>() = r_o - m.r_hill_m;
    const Eigen::AngleAxisd aa(m.q_hb.conjugate() * q_o);
    d.tail<3>() = aa.angle() * aa.axis();
    if (d.dot(info * d) < 1.0) continue;  // the same minimum
    const double x = 0.5 * (so.wssr - sb.wssr);
    const double w = x > 50.0 ? 0.0 : 1.0 / (1.0 + std::exp(x));
    m.flip_weight = w;
    if (w > cfg_.flip_weight_max) {
      m.status = PoseStatus::DegenerateGeometry;
      return m;
    }
    Mat6 R_o, info_o;
    if (w > 0.0 && covariance(r_o, q_o, R_o, info_o)) R = (1.0 - w) * R + w * (R_o + d * d.transpose());
    break;
  }
  m.R = 0.5 * (R + R.transpose());
  m.status = PoseStatus::Ok;
  return m;
}

}  // namespace fsw_vision
