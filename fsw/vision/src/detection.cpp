// Blob detection: local-background subtraction, threshold, connected
// components (plus the faint pass's, faint_spots.cpp), shape gates, and each
// blob's centroid (centroid.cpp) with its sigma.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>

#include "led_pose_detail.hpp"

namespace fsw_vision {
namespace detail {

// For Gaussian spots (own weight width w, neighbour width s_j, flux ratio
// rho_j, distance d_j) the weighted centroid moves by about
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

namespace {

// The frame as detection sees it: gray levels, the background-subtracted
// image, and the components.
struct DetectionImage {
  const cv::Mat& gray;
  const cv::Mat& diff;
  const cv::Mat& labels;
  const cv::Mat& stats;
  const cv::Mat& cents;
};

// Background-subtracted intensity moments of one component and the same
// moments of its pixel noise.
struct Moments {
  double s = 0.0, su = 0.0, sv = 0.0, suu = 0.0, svv = 0.0, suv = 0.0;
  double sn = 0.0, snu = 0.0, snv = 0.0, snuu = 0.0, snvv = 0.0;
  bool any_sat = false;
};

// Over the component's box grown by kPad, so that the spot's tails below
// the threshold count too (a centroid of the thresholded core alone is
// pulled towards pixel centres); pixels of other components excluded.
Moments component_moments(const DetectionImage& im, int l, const LedPoseConfig& cfg) {
  constexpr int kPad = 2;
  const int x0 = im.stats.at<int>(l, cv::CC_STAT_LEFT), y0 = im.stats.at<int>(l, cv::CC_STAT_TOP);
  const int w = im.stats.at<int>(l, cv::CC_STAT_WIDTH), h = im.stats.at<int>(l, cv::CC_STAT_HEIGHT);
  const int ra = std::max(y0 - kPad, 0), rb = std::min(y0 + h + kPad, im.gray.rows);
  const int ca = std::max(x0 - kPad, 0), cb = std::min(x0 + w + kPad, im.gray.cols);
  Moments m;
  for (int r = ra; r < rb; ++r) {
    const int* lab = im.labels.ptr<int>(r);
    const uint8_t* d = im.diff.ptr<uint8_t>(r);
    const uint8_t* g = im.gray.ptr<uint8_t>(r);
    for (int c = ca; c < cb; ++c) {
      if (lab[c] != l && lab[c] != 0) continue;
      const double wgt = d[c];
      m.s += wgt;
      m.su += wgt * c;
      m.sv += wgt * r;
      m.suu += wgt * c * c;
      m.svv += wgt * r * r;
      m.suv += wgt * c * r;
      // A saturated pixel carries no noise (it carries no information either,
      // but its weight is the clipped value, symmetric about the centre).
      m.any_sat = m.any_sat || g[c] == 255;
      const double nv = g[c] == 255 ? 0.0 : cfg.read_noise_counts * cfg.read_noise_counts + cfg.shot_gain * wgt;
      m.sn += nv;
      m.snu += nv * c;
      m.snv += nv * r;
      m.snuu += nv * c * c;
      m.snvv += nv * r * r;
    }
  }
  return m;
}

// The blob of component l, or false when a shape gate drops it. Refined
// centroid (the weight's width the spot's, from its moments) when it
// settles; else the first estimate with its pixel-noise sigma.
bool measure_blob(const DetectionImage& im, int l, int first_faint, const LedPoseConfig& cfg, Blob& blob) {
  const int area = im.stats.at<int>(l, cv::CC_STAT_AREA);
  const int w = im.stats.at<int>(l, cv::CC_STAT_WIDTH), h = im.stats.at<int>(l, cv::CC_STAT_HEIGHT);
  if (area < cfg.min_area_px || area > cfg.max_area_px) return false;
  if (w > cfg.max_extent_px || h > cfg.max_extent_px) return false;
  const Moments mo = component_moments(im, l, cfg);
  if (!(mo.s > 0.0)) return false;
  const double s = mo.s, mu = mo.su / s, mv = mo.sv / s;
  // Second moments, plus a pixel's own variance so that tiny blobs are round.
  const double a = mo.suu / s - mu * mu + 1.0 / 12.0;
  const double c = mo.svv / s - mv * mv + 1.0 / 12.0;
  const double b = mo.suv / s - mu * mv;
  const double half_tr = 0.5 * (a + c);
  const double disc = std::sqrt(std::max(0.0, 0.25 * (a - c) * (a - c) + b * b));
  const double lam1 = half_tr + disc, lam2 = std::max(half_tr - disc, 1e-9);
  if (std::sqrt(lam1 / lam2) > cfg.max_elongation) return false;  // lines, streaks
  const double width = std::sqrt(std::max(half_tr - 1.0 / 12.0, 0.0));
  const double sigma_w = std::clamp(width * (mo.any_sat ? cfg.centroid_weight_sat_scale : 1.0),
                                    cfg.centroid_weight_min_px, cfg.centroid_weight_max_px);
  Blob refined;
  refined.width_px = width;
  bool drifted = false;
  if (cfg.refine_centroid &&
      refine_centroid(CentroidImage{im.gray, im.labels, im.cents}, CentroidSeed{l, first_faint, mu, mv, width, sigma_w},
                      cfg, refined, drifted)) {
    refined.area_px = area;
    blob = refined;
    return true;
  }
  // Fallback (window or ring cut by the image border, the refinement not
  // settling or drifting; or refinement off): the first estimate with its
  // pixel-noise sigma.
  const double var_u = (mo.snuu - 2.0 * mu * mo.snu + mu * mu * mo.sn) / (s * s);
  const double var_v = (mo.snvv - 2.0 * mv * mo.snv + mv * mv * mo.sn) / (s * s);
  const double sig_noise = std::sqrt(std::max(var_u, var_v) + cfg.centroid_floor_px * cfg.centroid_floor_px);
  // A refinement that drifted away says the first estimate is off by that
  // much (a fragment of a wider spot, its window cut): its pixel noise
  // does not.
  const double sig = drifted ? std::max(sig_noise, kMaxRefineShiftPx) : sig_noise;
  blob = Blob{mu, mv, s, area, sig, 0, sig_noise, width};
  return true;
}

// Fragments of one spot refine to the same centre: keep the brightest
// (blobs brightest first).
void keep_distinct(std::vector<Blob>& blobs) {
  std::vector<Blob> kept;
  for (const Blob& b : blobs) {
    bool dup = false;
    for (const Blob& k : kept) dup = dup || std::hypot(b.u_px - k.u_px, b.v_px - k.v_px) < 1.0;
    if (!dup) kept.push_back(b);
  }
  blobs.swap(kept);
}

}  // namespace
}  // namespace detail

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
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, cents, 8, CV_32S);
  detail::Components comps{labels, stats, cents, n};
  const int first_faint = comps.n;
  if (faint_pass && cfg_.faint_sigma_px > 0.0)
    detail::append_faint_components(
        diff, mask, detail::FaintPass{cfg_.faint_sigma_px, cfg_.faint_threshold_counts, cfg_.min_area_px}, comps);
  const detail::DetectionImage im{gray, diff, labels, stats, cents};
  std::vector<char> faint;  // per blob in out: found by the faint pass
  for (int l = 1; l < comps.n; ++l) {
    Blob blob;
    if (!detail::measure_blob(im, l, first_faint, cfg_, blob)) continue;
    out.push_back(blob);
    faint.push_back(static_cast<char>(l >= first_faint));
  }
  detail::add_crowding_sigma(out, faint, cfg_.centroid_weight_min_px, cfg_.centroid_weight_max_px);
  std::sort(out.begin(), out.end(), [](const Blob& x, const Blob& y) { return x.flux > y.flux; });
  detail::keep_distinct(out);
  if (static_cast<int>(out.size()) > cfg_.max_blobs) out.resize(cfg_.max_blobs);
  return out;
}

}  // namespace fsw_vision
