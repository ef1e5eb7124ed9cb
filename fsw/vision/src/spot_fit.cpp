// Gaussian spot fits by weighted Levenberg-Marquardt (see spot_fit.hpp).
#include "fsw_vision/spot_fit.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace fsw_vision {

namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr int kMaxIter = 60;
constexpr double kMinWidthPx = 0.3;
constexpr double kMaxWidthPx = 20.0;

struct Pixel {
  // cppcheck-suppress unusedStructMember ; read in the fit's template, which cppcheck does not follow
  double x, y, z, w;  // column, row, counts, weight 1 / variance
};

int n_params(SpotModel m) { return m == SpotModel::One ? 5 : 6; }

// One spot's value and its derivatives by (u, v, width, flux).
struct SpotTerm {
  // cppcheck-suppress unusedStructMember ; read in model_at, a template cppcheck does not follow
  double value, du, dv, ds, dflux;
};
SpotTerm spot_term(double x, double y, double u, double v, double s, double flux) {
  const double dx = x - u, dy = y - v, s2 = s * s, d2 = dx * dx + dy * dy;
  const double shape = std::exp(-0.5 * d2 / s2) / (kTwoPi * s2);
  const double val = flux * shape;
  return {val, val * dx / s2, val * dy / s2, val * (d2 / (s2 * s) - 2.0 / s), shape};
}

// Model value at a pixel and its gradient over the parameters (N = 5: One,
// N = 6: PairOnLine).
template <int N>
double model_at(const Eigen::Matrix<double, N, 1>& p, const Eigen::Vector2d& line_p, double f, double x, double y,
                Eigen::Matrix<double, N, 1>& grad) {
  if constexpr (N == 5) {
    const SpotTerm t = spot_term(x, y, p(0), p(1), p(2), p(3));
    grad << t.du, t.dv, t.ds, t.dflux, 1.0;
    return t.value + p(4);
  } else {
    // PairOnLine: spot 1 at (1 - f) u0 + f p moves with u0 by (1 - f).
    const double s = p(2);
    const SpotTerm a = spot_term(x, y, p(0), p(1), s, p(3));
    const SpotTerm b = spot_term(x, y, (1.0 - f) * p(0) + f * line_p(0), (1.0 - f) * p(1) + f * line_p(1), s, p(4));
    grad << a.du + (1.0 - f) * b.du, a.dv + (1.0 - f) * b.dv, a.ds + b.ds, a.dflux, b.dflux, 1.0;
    return a.value + b.value + p(5);
  }
}

// Levenberg-Marquardt from p; false unless it settles at a finite minimum.
// Fixed-size normal equations (5 or 6 parameters) over every pixel.
template <int N>
bool minimise(const std::vector<Pixel>& px, const Eigen::Vector2d& line_p, double f, Eigen::Matrix<double, N, 1>& p,
              double& chi2, Eigen::Matrix<double, N, N>& cov) {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  auto normal_equations = [&](const Vec& q, Mat& H, Vec& g) {
    H.setZero();
    g.setZero();
    Vec grad;
    double c2 = 0.0;
    for (const Pixel& k : px) {
      const double res = k.z - model_at<N>(q, line_p, f, k.x, k.y, grad);
      c2 += k.w * res * res;
      H.noalias() += (k.w * grad) * grad.transpose();
      g += (k.w * res) * grad;
    }
    return c2;
  };
  Mat H;
  Vec g;
  chi2 = normal_equations(p, H, g);
  double lambda = 1e-3;
  bool converged = false;
  for (int it = 0; it < kMaxIter && std::isfinite(chi2); ++it) {
    Mat A = H;
    A.diagonal() *= 1.0 + lambda;
    const Vec step = A.ldlt().solve(g);
    const Vec q = p + step;
    Mat Hq = Mat::Zero();
    Vec gq = Vec::Zero();
    const double chi2_q =
        (q(2) > kMinWidthPx && q(2) < kMaxWidthPx && step.allFinite()) ? normal_equations(q, Hq, gq) : INFINITY;
    if (chi2_q < chi2) {
      const double gain = chi2 - chi2_q;
      p = q;
      H = Hq;
      g = gq;
      chi2 = chi2_q;
      lambda = std::max(lambda / 3.0, 1e-9);
      if (gain < 1e-7 * (1.0 + chi2)) {
        converged = true;
        break;
      }
    } else {
      lambda *= 4.0;
      if (lambda > 1e8) {  // no downhill step left: at the minimum
        converged = true;
        break;
      }
    }
  }
  if (!converged || !std::isfinite(chi2)) return false;
  const Eigen::LDLT<Mat> ldlt(H);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return false;
  cov = ldlt.solve(Mat::Identity());
  return cov.allFinite();
}

}  // namespace

SpotFit fit_spots(const cv::Mat& gray, const SpotWindow& w, const PixelNoise& noise, SpotModel model,
                  const Eigen::Vector2d& u0_init, double width_init_px, const Eigen::Vector2d& line_p, double line_f) {
  SpotFit out;
  if (gray.empty() || gray.type() != CV_8UC1) return out;
  const int r0 = std::max(w.r0, 0), r1 = std::min(w.r1, gray.rows);
  const int c0 = std::max(w.c0, 0), c1 = std::min(w.c1, gray.cols);
  const int np = n_params(model);
  if (r1 - r0 < 3 || c1 - c0 < 3 || !(width_init_px > 0.0)) return out;

  // Background start: the median of the window's edge pixels.
  std::vector<double> edge;
  for (int r = r0; r < r1; ++r)
    for (int c = c0; c < c1; ++c)
      if (r == r0 || r == r1 - 1 || c == c0 || c == c1 - 1) edge.push_back(gray.at<uint8_t>(r, c));
  std::nth_element(edge.begin(), edge.begin() + static_cast<std::ptrdiff_t>(edge.size() / 2), edge.end());
  const double b0 = edge[edge.size() / 2];

  std::vector<Pixel> px;
  double flux_sum = 0.0;
  for (int r = r0; r < r1; ++r) {
    const uint8_t* g = gray.ptr<uint8_t>(r);
    for (int c = c0; c < c1; ++c) {
      if (g[c] == 255) continue;
      const double sig = std::max(g[c] - b0, 0.0);
      flux_sum += sig;
      px.push_back({double(c), double(r), double(g[c]),
                    1.0 / (noise.read_noise_counts * noise.read_noise_counts + noise.shot_gain * sig)});
    }
  }
  if (static_cast<int>(px.size()) <= np || !(flux_sum > 0.0)) return out;

  if (model == SpotModel::One) {
    Eigen::Matrix<double, 5, 1> p;
    p << u0_init(0), u0_init(1), width_init_px, flux_sum, b0;
    Eigen::Matrix<double, 5, 5> cov;
    out.ok = minimise<5>(px, line_p, line_f, p, out.chi2, cov);
    out.u0 = p.head<2>();
    out.cov_u0 = cov.topLeftCorner<2, 2>();
    out.width_px = p(2);
    out.flux0 = p(3);
    out.background = p(4);
  } else {
    Eigen::Matrix<double, 6, 1> p;
    p << u0_init(0), u0_init(1), width_init_px, 0.5 * flux_sum, 0.5 * flux_sum, b0;
    Eigen::Matrix<double, 6, 6> cov;
    out.ok = minimise<6>(px, line_p, line_f, p, out.chi2, cov);
    out.u0 = p.head<2>();
    out.cov_u0 = cov.topLeftCorner<2, 2>();
    out.width_px = p(2);
    out.u1 = (1.0 - line_f) * out.u0 + line_f * line_p;
    out.flux0 = p(3);
    out.flux1 = p(4);
    out.background = p(5);
  }
  return out;
}

}  // namespace fsw_vision
