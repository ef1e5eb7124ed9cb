// Gaussian spot fits: one spot's position and its Fisher covariance against
// a Monte Carlo of pixel noise, the two-spot fit's evidence for a second
// spot (large when there is one, never past the split's threshold when
// there is not), and bad input.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <vector>

#include "fsw_vision/spot_fit.hpp"
#include "spot_image.hpp"

using fsw_vision::fit_spots;
using fsw_vision::PixelNoise;
using fsw_vision::SpotFit;
using fsw_vision::SpotModel;
using fsw_vision::SpotWindow;

namespace {

// A 64 x 64 image of the bench's blurred spots (spot_image.hpp).
cv::Mat spots_image(const std::vector<Eigen::Vector2d>& centres, double sigma, double flux, uint64_t seed) {
  std::vector<cv::Point2d> pts;
  for (const auto& c : centres) pts.emplace_back(c.x(), c.y());
  return noisy_spots_image(64, 64, pts, sigma, flux, seed);
}

const SpotWindow kWindow{20, 45, 20, 45};
const PixelNoise kNoise{};

}  // namespace

// 300 seeds: the position error whitened by the fit's covariance has mean
// square 2 (two degrees of freedom) within its Monte Carlo band, and the
// width and flux come back.
TEST(SpotFit, OneSpotPositionMatchesItsCovariance) {
  const Eigen::Vector2d truth(32.3, 31.6);
  double z2 = 0.0, width = 0.0, flux = 0.0, background = 0.0;
  const int n = 300;
  for (int seed = 1; seed <= n; ++seed) {
    const cv::Mat img = spots_image({truth}, 2.0, 300.0, seed);
    const SpotFit f = fit_spots(img, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 1.5);
    ASSERT_TRUE(f.ok) << "seed " << seed;
    const Eigen::Vector2d e = f.u0 - truth;
    z2 += e.dot(f.cov_u0.ldlt().solve(e));
    width += f.width_px;
    flux += f.flux0;
    background += f.background;
  }
  z2 /= n;
  // Mean of chi^2(2) over 300 runs: 2 +- 0.16 (1 sigma); 8-bit rounding adds a little.
  EXPECT_GT(z2, 1.6);
  EXPECT_LT(z2, 2.6);
  // The fit's Gaussian is point-sampled: its width includes the pixel's (1/12 px^2).
  EXPECT_NEAR(width / n, std::sqrt(4.0 + 1.0 / 12.0), 0.05);
  EXPECT_NEAR(flux / n, 300.0, 10.0);
  EXPECT_NEAR(background / n, 6.0, 0.2);  // the 8-bit conversion rounds, which leaves 6 on average
}

// Two spots 5 px apart (2.3 widths: one blob): the pair held on the line
// to a far point at the right fraction fits far better than one spot, and
// finds both; a single spot gives the pair no such evidence.
TEST(SpotFit, PairOnLineFindsTheSecondSpotAndOnlyWhenThereIsOne) {
  const Eigen::Vector2d a(30.4, 32.2), far(50.4, 32.2);
  const double f = 0.25;  // the second spot at a + f (far - a): 5 px
  const Eigen::Vector2d b = (1.0 - f) * a + f * far;
  int null_large = 0;
  for (int seed = 1; seed <= 40; ++seed) {
    const cv::Mat two = spots_image({a, b}, 2.15, 300.0, seed);
    const SpotFit one2 = fit_spots(two, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0);
    const SpotFit pair = fit_spots(two, kWindow, kNoise, SpotModel::PairOnLine, one2.u0, 2.0, far, f);
    ASSERT_TRUE(one2.ok && pair.ok) << "seed " << seed;
    EXPECT_GT(one2.chi2 - pair.chi2, 25.0) << "seed " << seed;
    EXPECT_LT((pair.u0 - a).norm(), 4.0 * std::sqrt(pair.cov_u0.trace())) << "seed " << seed;
    EXPECT_NEAR(pair.flux1 / pair.flux0, 1.0, 0.5) << "seed " << seed;

    const cv::Mat single = spots_image({a}, 2.15, 600.0, seed);
    const SpotFit one1 = fit_spots(single, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0);
    const SpotFit pair1 = fit_spots(single, kWindow, kNoise, SpotModel::PairOnLine, one1.u0, 2.0, far, f);
    ASSERT_TRUE(one1.ok) << "seed " << seed;
    if (pair1.ok && one1.chi2 - pair1.chi2 > 25.0) ++null_large;
  }
  EXPECT_EQ(null_large, 0);
}

TEST(SpotFit, BadInputIsNotOk) {
  const cv::Mat img = spots_image({Eigen::Vector2d(32, 32)}, 2.0, 300.0, 1);
  EXPECT_FALSE(fit_spots(cv::Mat(), kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0).ok);
  cv::Mat f32;
  img.convertTo(f32, CV_32F);
  EXPECT_FALSE(fit_spots(f32, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0).ok);
  EXPECT_FALSE(fit_spots(img, SpotWindow{30, 31, 30, 31}, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0).ok);
  EXPECT_FALSE(fit_spots(img, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 0.0).ok);
  const cv::Mat flat(64, 64, CV_8U, cv::Scalar(6));
  EXPECT_FALSE(fit_spots(flat, kWindow, kNoise, SpotModel::One, Eigen::Vector2d(32, 32), 2.0).ok);
}
