// Test images of blurred spots as the bench renders them: pixel-integrated
// Gaussians of one flux on the bench's background (6 counts), read noise
// 1.5 counts and shot variance 0.05 per count of signal, seeded, 8-bit.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

inline cv::Mat noisy_spots_image(int rows, int cols, const std::vector<cv::Point2d>& centres, double sigma, double flux,
                                 uint64_t seed) {
  cv::Mat img(rows, cols, CV_64F, cv::Scalar(6.0));
  const double s = std::sqrt(2.0) * sigma;
  for (const auto& p : centres)
    for (int r = std::max(int(p.y) - 14, 0); r <= std::min(int(p.y) + 14, rows - 1); ++r)
      for (int c = std::max(int(p.x) - 14, 0); c <= std::min(int(p.x) + 14, cols - 1); ++c) {
        const double gx = 0.5 * (std::erf((c + 0.5 - p.x) / s) - std::erf((c - 0.5 - p.x) / s));
        const double gy = 0.5 * (std::erf((r + 0.5 - p.y) / s) - std::erf((r - 0.5 - p.y) / s));
        img.at<double>(r, c) += flux * gx * gy;
      }
  cv::RNG rng(seed);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      double& v = img.at<double>(r, c);
      v += rng.gaussian(std::sqrt(1.5 * 1.5 + 0.05 * std::max(v - 6.0, 0.0)));
    }
  cv::Mat img8;
  img.convertTo(img8, CV_8U);
  return img8;
}
