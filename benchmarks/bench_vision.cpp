// Image to pose for a 640 x 480 frame (detection, identification, PnP,
// covariance): the LED pose pipeline's per-frame cost (1 Hz budget; target
// at most 5 ms median).
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "fsw_vision/led_pose.hpp"

namespace {

// A frame of the pattern: the inspector range_m from it on the host's +x
// side (the LED face), boresight towards -x Hill, tilted by tilt_rad about
// tilt_axis; Gaussian spots (sigma_px, peak amp counts, drawn within
// half_px) plus clutter_spots LED-like spots on a noisy background.
struct FrameSpec {
  double range_m, tilt_rad;
  Eigen::Vector3d tilt_axis;
  double sigma_px, amp;
  int half_px, clutter_spots;
  uint64_t seed;
};

cv::Mat make_frame(const fsw_vision::LedPoseEstimator& est, const FrameSpec& f) {
  const Eigen::Quaterniond q_hb = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ())) *
                                  Eigen::Quaterniond(Eigen::AngleAxisd(f.tilt_rad, f.tilt_axis.normalized()));
  const Eigen::Vector3d r_hill = q_hb * Eigen::Vector3d(-f.range_m, 0.05, 0.02);
  std::array<cv::Point2d, fsw_vision::kNumLeds> px;
  est.project(r_hill, q_hb, Eigen::Quaterniond::Identity(), px);
  cv::Mat img(480, 640, CV_32F, cv::Scalar(6.0));
  cv::RNG rng(f.seed);
  auto spot = [&](double u, double v, double sigma, double amp) {
    for (int r = int(v) - f.half_px; r <= int(v) + f.half_px; ++r)
      for (int c = int(u) - f.half_px; c <= int(u) + f.half_px; ++c)
        if (r >= 0 && r < 480 && c >= 0 && c < 640)
          img.at<float>(r, c) +=
              float(amp * std::exp(-0.5 * ((c - u) * (c - u) + (r - v) * (r - v)) / (sigma * sigma)));
  };
  for (const auto& p : px) spot(p.x, p.y, f.sigma_px, f.amp);
  for (int k = 0; k < f.clutter_spots; ++k) spot(rng.uniform(0.0, 640.0), rng.uniform(0.0, 480.0), 1.0, 150.0);
  cv::Mat noise(480, 640, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.5);
  img += noise;
  cv::Mat out;
  img.convertTo(out, CV_8U);
  return out;
}

// The pattern 1.6 m away, tilted, bright 1.2 px spots.
cv::Mat make_frame(const fsw_vision::LedPoseEstimator& est, int clutter_spots) {
  return make_frame(est, {1.6, 0.3, Eigen::Vector3d(0.2, 0.9, 0.1), 1.2, 200.0, 6, clutter_spots, 1});
}

void BM_ImageToPose(benchmark::State& state) {
  const fsw_vision::LedPoseEstimator est;
  const cv::Mat img = make_frame(est, static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const auto m = est.estimate(img, 0.0);
    if (m.status != fsw_vision::PoseStatus::Ok) state.SkipWithError("no pose");
    benchmark::DoNotOptimize(m.r_hill_m);
  }
}
BENCHMARK(BM_ImageToPose)->Arg(0)->Arg(6)->Unit(benchmark::kMillisecond);

// A blurred (2.15 px), faint (about 10 counts at the peak) frame at long
// range, tilted, with the identifier a few px from corner 0 in one blob.
cv::Mat far_blurred_frame(const fsw_vision::LedPoseEstimator& est, double range_m, double tilt_rad) {
  const double sigma = 2.15;
  return make_frame(
      est, {range_m, tilt_rad, Eigen::Vector3d(0.3, 0.9, 0.1), sigma, 300.0 / (2.0 * M_PI * sigma * sigma), 10, 0, 2});
}

// Image to pose when the identifier is merged into its corner's blob (the
// first range from 4 m, in 0.1 m steps, where the split gives a pose).
// Arg 1: the split on (the default); 0: off, the same frame then ends
// AmbiguousIdentity after both passes. The difference is the split's cost.
void BM_ImageToPoseMergedIdentifier(benchmark::State& state) {
  const fsw_vision::LedPoseEstimator with_split;
  fsw_vision::LedPoseConfig off;
  off.merged_id_min_dchi2 = 0.0;
  const fsw_vision::LedPoseEstimator without(off);
  cv::Mat frame;
  for (double range = 4.0; range <= 5.0 && frame.empty(); range += 0.1) {
    const cv::Mat f = far_blurred_frame(with_split, range, 0.7);
    const auto m = with_split.estimate(f, 0.0);
    if (m.status == fsw_vision::PoseStatus::Ok && m.identifier_split) frame = f;
  }
  if (frame.empty()) {
    state.SkipWithError("no merged-identifier frame");
    return;
  }
  const fsw_vision::LedPoseEstimator& est = state.range(0) ? with_split : without;
  state.SetLabel(fsw_vision::to_string(est.estimate(frame, 0.0).status));
  for (auto _ : state) benchmark::DoNotOptimize(est.estimate(frame, 0.0).status);
}
BENCHMARK(BM_ImageToPoseMergedIdentifier)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Arg: 1 with the faint-spot pass (the default), 0 without it.
void BM_Detect(benchmark::State& state) {
  fsw_vision::LedPoseConfig cfg;
  if (state.range(0) == 0) cfg.faint_sigma_px = 0.0;
  const fsw_vision::LedPoseEstimator est(cfg);
  const cv::Mat img = make_frame(est, 0);
  for (auto _ : state) benchmark::DoNotOptimize(est.detect(img));
}
BENCHMARK(BM_Detect)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
