// Gaussian spot fits on a pixel window: one spot, or two spots of a common
// width with the second held on a line through the first, by weighted
// Levenberg-Marquardt with the pixel-noise model of the detector. Used to
// split the identifier LED from its corner when blur has merged them into
// one blob (docs/VISION.md, "Merged identifier").
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace fsw_vision {

// Pixels of an 8-bit image inside [r0, r1) x [c0, c1); saturated pixels
// (255) are left out of every fit.
struct SpotWindow {
  int r0 = 0, r1 = 0, c0 = 0, c1 = 0;
};

// Pixel noise: variance read_noise_counts^2 + shot_gain * (signal above the
// background), as LedPoseConfig.
struct PixelNoise {
  double read_noise_counts = 1.5;
  double shot_gain = 0.05;
};

enum class SpotModel {
  One,         // [u, v, width, flux, background]
  PairOnLine,  // [u0, v0, width, flux0, flux1, background]; spot 1 at (1 - f) u0 + f p
};

struct SpotFit {
  bool ok = false;                                   // converged to a finite minimum with positive width
  double chi2 = 0.0;                                 // weighted residual sum of squares at the minimum
  Eigen::Vector2d u0 = Eigen::Vector2d::Zero();      // first spot (column, row) [px]
  Eigen::Vector2d u1 = Eigen::Vector2d::Zero();      // second spot (PairOnLine)
  double width_px = 0.0;                             // Gaussian sigma of both spots
  double flux0 = 0.0, flux1 = 0.0;                   // total counts of each spot
  double background = 0.0;                           // counts per pixel
  Eigen::Matrix2d cov_u0 = Eigen::Matrix2d::Zero();  // u0's covariance from the Fisher information [px^2]
};

// line_p, line_f: for PairOnLine, the far point p and the fraction f that
// place the second spot at (1 - f) u0 + f p; ignored for One. Starts: u0_init,
// width_init_px, the fluxes from the window's sum over its edge median.
SpotFit fit_spots(const cv::Mat& gray, const SpotWindow& w, const PixelNoise& noise, SpotModel model,
                  const Eigen::Vector2d& u0_init, double width_init_px,
                  const Eigen::Vector2d& line_p = Eigen::Vector2d::Zero(), double line_f = 0.0);

}  // namespace fsw_vision
