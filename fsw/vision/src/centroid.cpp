// The refined centroid of one component with its error model.
//
// A Gaussian-weighted centroid (weight width sigma_w, the spot's width from
// its moments) iterated to its fixed point sum W_i w_i (x_i - x) = 0, which
// for a symmetric spot is its centre whatever the pixel phase; the first
// estimate, an unweighted mean over the thresholded component's box, is
// pulled towards the pixel centre of undersampled spots and towards the
// box's centre by the tails it cuts off. The weights w_i are the signed
// differences from a background plane fitted to a ring around the window
// (pixels of other components and outliers dropped): clipping them at zero,
// or a background that contains the spot's own light, biases the centroid
// too.
//
// Variance, linearised at the fixed point: pixel noise (ring residual
// variance plus shot noise; saturated pixels none) and the background
// plane's error, scaled by centroid_noise_scale^2, plus the calibrated
// saturation term and the floor (docs/VISION.md, "Centroid error model").
#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "led_pose_detail.hpp"

namespace fsw_vision {
namespace detail {
namespace {

constexpr int kRing = 2, kMinRing = 12, kMaxIter = 20;

// The weighted window around pixel (cu, cv) of half-size half, and the
// background ring's outer half-size.
struct Window {
  int cu, cv;
  int half, outer;
};

// Background plane p0 + p1 (c - cu) + p2 (r - cv) fitted to the ring, the
// inverse of its normal matrix and the pixel variance from its residuals.
struct Plane {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Matrix3d AtA_inv = Eigen::Matrix3d::Zero();
  double base_var = 0.0;
};

using RingPixel = std::array<double, 3>;  // dc, dr, value

double ring_residual(const RingPixel& px, const Eigen::Vector3d& p) {
  return px[2] - (p(0) + p(1) * px[0] + p(2) * px[1]);
}

// The ring's background pixels: in no component, not saturated. False when
// the ring leaves the image.
bool collect_ring(const CentroidImage& im, const Window& w, std::vector<RingPixel>& ring) {
  if (w.cu - w.outer < 0 || w.cv - w.outer < 0 || w.cu + w.outer >= im.gray.cols || w.cv + w.outer >= im.gray.rows)
    return false;
  ring.reserve(8 * static_cast<size_t>(w.outer + 1) * kRing);
  for (int r = w.cv - w.outer; r <= w.cv + w.outer; ++r) {
    const int* lab = im.labels.ptr<int>(r);
    const uint8_t* g = im.gray.ptr<uint8_t>(r);
    const bool row_in = std::abs(r - w.cv) <= w.half;
    for (int c = w.cu - w.outer; c <= w.cu + w.outer; ++c) {
      if (row_in && std::abs(c - w.cu) <= w.half) continue;
      if (lab[c] != 0 || g[c] == 255) continue;
      ring.push_back({double(c - w.cu), double(r - w.cv), double(g[c])});
    }
  }
  return true;
}

// One least-squares fit of the plane to the ring pixels in use; false with
// too few of them or a singular normal matrix.
bool fit_plane_once(const std::vector<RingPixel>& ring, const std::vector<char>& use, Plane& pl, double& ring_var) {
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
  pl.p = ldlt.solve(Atz);
  pl.AtA_inv = ldlt.solve(Eigen::Matrix3d::Identity());
  double ssr = 0.0;
  for (size_t i = 0; i < ring.size(); ++i) {
    if (!use[i]) continue;
    const double res = ring_residual(ring[i], pl.p);
    ssr += res * res;
  }
  ring_var = ssr / std::max(k - 3, 1);
  return true;
}

// The background plane around window w: a fit, ring pixels far off it
// dropped (a neighbouring spot's tail, a line), and a second fit.
bool fit_background(const CentroidImage& im, const Window& w, double read_noise, Plane& pl) {
  std::vector<RingPixel> ring;
  if (!collect_ring(im, w, ring)) return false;
  std::vector<char> use(ring.size(), 1);
  double ring_var = 0.0;
  if (!fit_plane_once(ring, use, pl, ring_var)) return false;
  const double lim = 3.5 * std::sqrt(std::max(ring_var, read_noise * read_noise));
  for (size_t i = 0; i < ring.size(); ++i) {
    if (std::abs(ring_residual(ring[i], pl.p)) > lim) use[i] = 0;
  }
  if (!fit_plane_once(ring, use, pl, ring_var)) return false;
  pl.base_var = std::max(ring_var, 0.5 * read_noise * read_noise);
  return true;
}

// Pixels of another component count as the spot's own when that
// component's centre is within the weight's reach of this one (a faint
// spot that the threshold broke into fragments); other objects are left out.
struct OwnPixels {
  const CentroidImage& im;
  const CentroidSeed& seed;
  bool operator()(int lab) const {
    if (lab == 0 || lab == seed.label) return true;
    if (lab >= seed.first_faint) return false;  // another maximum: a distinct spot
    const double dx = im.cents.at<double>(lab, 0) - seed.u0, dy = im.cents.at<double>(lab, 1) - seed.v0;
    return dx * dx + dy * dy < (2.0 * seed.sigma_w + 1.5) * (2.0 * seed.sigma_w + 1.5);
  }
};

// Where the iteration stands: the centroid, its window and background, and
// the last iteration's sum of weights.
struct State {
  double mu = 0.0, mv = 0.0;
  Window w{};
  Plane plane;
  double sw = 0.0;
};

// Weighted sums of one iteration: sum W w, its first moments about the
// centroid and the Newton denominators.
struct Sums {
  double sw = 0.0, swu = 0.0, swv = 0.0, hu = 0.0, hv = 0.0;
};

Sums weighted_sums(const CentroidImage& im, const OwnPixels& own, const State& st, double inv2s2) {
  Sums s;
  const Window& w = st.w;
  const Eigen::Vector3d& p = st.plane.p;
  for (int r = w.cv - w.half; r <= w.cv + w.half; ++r) {
    const int* lab = im.labels.ptr<int>(r);
    const uint8_t* g = im.gray.ptr<uint8_t>(r);
    const double dr = r - st.mv;
    for (int c = w.cu - w.half; c <= w.cu + w.half; ++c) {
      if (!own(lab[c])) continue;
      const double dc = c - st.mu;
      const double W = std::exp(-(dc * dc + dr * dr) * inv2s2);
      const double wgt = W * (g[c] - (p(0) + p(1) * (c - w.cu) + p(2) * (r - w.cv)));
      s.sw += wgt;
      s.swu += wgt * dc;
      s.swv += wgt * dr;
      s.hu += wgt * (1.0 - dc * dc * 2.0 * inv2s2);
      s.hv += wgt * (1.0 - dr * dr * 2.0 * inv2s2);
    }
  }
  return s;
}

enum class Iteration { Settled, Failed, Drifted };

// Fixed-point iteration x <- x + 2 sum W w (x_i - x) / sum W w (the factor
// 2 is exact for a Gaussian spot as wide as the weight), as a Newton step
// where its denominator is safely positive; the background is fitted again
// whenever the centre pixel changes.
Iteration iterate(const CentroidImage& im, const CentroidSeed& seed, double read_noise, State& st) {
  const OwnPixels own{im, seed};
  const double inv2s2 = 0.5 / (seed.sigma_w * seed.sigma_w);
  for (int it = 0; it < kMaxIter; ++it) {
    const Sums s = weighted_sums(im, own, st, inv2s2);
    st.sw = s.sw;
    if (!(s.sw > 0.0)) return Iteration::Failed;
    // Newton step on F: dx = sum W w dx_i / sum W w (1 - dx_i^2 / sigma_w^2);
    // the factor-2 step where that denominator is not safely positive.
    const double du = s.hu > 0.1 * s.sw ? s.swu / s.hu : 2.0 * s.swu / s.sw;
    const double dv = s.hv > 0.1 * s.sw ? s.swv / s.hv : 2.0 * s.swv / s.sw;
    st.mu += du;
    st.mv += dv;
    if (!(std::abs(st.mu - seed.u0) < kMaxRefineShiftPx && std::abs(st.mv - seed.v0) < kMaxRefineShiftPx))
      return Iteration::Drifted;
    const int ncu = static_cast<int>(std::lround(st.mu)), ncv = static_cast<int>(std::lround(st.mv));
    if (ncu != st.w.cu || ncv != st.w.cv) {
      st.w.cu = ncu;
      st.w.cv = ncv;
      if (!fit_background(im, st.w, read_noise, st.plane)) return Iteration::Failed;
      continue;
    }
    if (std::abs(du) < 1e-4 && std::abs(dv) < 1e-4) return Iteration::Settled;
  }
  return Iteration::Failed;
}

// The centroid's pixel-noise variance (the larger axis), the window's flux
// and its saturated pixels.
struct Noise {
  double var = 0.0;
  double flux = 0.0;
  int n_sat = 0;
};

// Linearisation at the fixed point F(x) = sum W_i w_i (x_i - x) = 0:
// dF/dw_i = W_i (x_i - x), dF/dx = sum W_i w_i ((x_i - x)^2 / sigma_w^2 - 1),
// dF/dp = -sum W_i (x_i - x) a_i. False unless dF/dx < 0 on both axes.
bool linearised_noise(const CentroidImage& im, const CentroidSeed& seed, const State& st, double shot_gain,
                      Noise& out) {
  const OwnPixels own{im, seed};
  const double inv2s2 = 0.5 / (seed.sigma_w * seed.sigma_w);
  const Window& w = st.w;
  const Eigen::Vector3d& p = st.plane.p;
  double vu = 0.0, vv = 0.0, du_dx = 0.0, dv_dx = 0.0;
  Eigen::Vector3d Gu = Eigen::Vector3d::Zero(), Gv = Eigen::Vector3d::Zero();
  for (int r = w.cv - w.half; r <= w.cv + w.half; ++r) {
    const int* lab = im.labels.ptr<int>(r);
    const uint8_t* g = im.gray.ptr<uint8_t>(r);
    const double dr = r - st.mv;
    for (int c = w.cu - w.half; c <= w.cu + w.half; ++c) {
      if (!own(lab[c])) continue;
      const double dc = c - st.mu;
      const double W = std::exp(-(dc * dc + dr * dr) * inv2s2);
      const double wgt = g[c] - (p(0) + p(1) * (c - w.cu) + p(2) * (r - w.cv));
      const double var = g[c] == 255 ? 0.0 : st.plane.base_var + shot_gain * std::max(wgt, 0.0);
      vu += W * W * dc * dc * var;
      vv += W * W * dr * dr * var;
      du_dx += W * wgt * (dc * dc * 2.0 * inv2s2 - 1.0);
      dv_dx += W * wgt * (dr * dr * 2.0 * inv2s2 - 1.0);
      const Eigen::Vector3d a(1.0, double(c - w.cu), double(r - w.cv));
      Gu += W * dc * a;
      Gv += W * dr * a;
      out.flux += wgt;
      out.n_sat += g[c] == 255;
    }
  }
  if (!(du_dx < 0.0) || !(dv_dx < 0.0)) return false;
  vu = (vu + st.plane.base_var * Gu.dot(st.plane.AtA_inv * Gu)) / (du_dx * du_dx);
  vv = (vv + st.plane.base_var * Gv.dot(st.plane.AtA_inv * Gv)) / (dv_dx * dv_dx);
  out.var = std::max(vu, vv);
  return true;
}

}  // namespace

bool refine_centroid(const CentroidImage& image, const CentroidSeed& seed, const LedPoseConfig& cfg, Blob& out,
                     bool& drifted) {
  drifted = false;
  State st;
  st.mu = seed.u0;
  st.mv = seed.v0;
  st.w.half = static_cast<int>(std::ceil(3.0 * seed.sigma_w)) + 1;
  st.w.outer = st.w.half + kRing;
  st.w.cu = static_cast<int>(std::lround(st.mu));
  st.w.cv = static_cast<int>(std::lround(st.mv));
  if (!fit_background(image, st.w, cfg.read_noise_counts, st.plane)) return false;
  const Iteration it = iterate(image, seed, cfg.read_noise_counts, st);
  drifted = it == Iteration::Drifted;
  if (it != Iteration::Settled) return false;
  Noise noise;
  if (!linearised_noise(image, seed, st, cfg.shot_gain, noise)) return false;
  const double k = cfg.centroid_noise_scale;
  // Saturated spot: the plateau's edge is sampled by the pixels, an error
  // the noise leaves out, largest for a large plateau on a narrow spot
  // (a sharp edge): sat_sigma_px n_sat / max(width / 1 px, 1)^4.
  const double w2 = std::max(seed.width_px, 1.0) * std::max(seed.width_px, 1.0);
  const double sat = cfg.sat_sigma_px * noise.n_sat / (w2 * w2);
  const double var = k * k * noise.var + sat * sat + cfg.centroid_floor_px * cfg.centroid_floor_px;
  out.u_px = st.mu;
  out.v_px = st.mv;
  out.flux = noise.flux > 0.0 ? noise.flux : st.sw;
  out.sigma_px = std::sqrt(var);
  out.n_saturated = noise.n_sat;
  out.sigma_noise_px = std::sqrt(noise.var);
  return std::isfinite(out.sigma_px) && out.sigma_px > 0.0 && std::isfinite(st.mu) && std::isfinite(st.mv);
}

}  // namespace detail
}  // namespace fsw_vision
