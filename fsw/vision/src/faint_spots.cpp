// Faint spots (a blurred or distant LED whose peak stays under the plain
// threshold): the background-subtracted image smoothed by a Gaussian about
// as wide as a spot, a matched filter whose pixel noise is 1 / (2 sqrt(pi)
// sigma) of the raw image's, thresholded lower. Its components that touch
// none of the plain threshold's (not counting plain components smaller than
// min_area_px: a faint spot's noise peaks that poke through the plain
// threshold, which the shape gates drop) are split between their local
// maxima (two blurred LEDs a few pixels apart, the identifier beside its
// corner, join at a low threshold but keep two maxima), each pixel to the
// nearest, and appended after the plain components (labels n, n+1, ...)
// with their stats and centroids; detection then measures them alike
// (over-split fragments of one spot refine to the same centre and are
// merged there).
#include <algorithm>
#include <cstdint>
#include <opencv2/imgproc.hpp>

#include "led_pose_detail.hpp"

namespace fsw_vision {
namespace detail {
namespace {

// A local maximum of the smoothed image: pixel and new label.
struct Peak {
  int r, c, label;
};

// The faint pass's maxima and, per faint component, its maxima's indices.
struct Peaks {
  std::vector<Peak> all;
  std::vector<std::vector<int>> of_comp;
};

// Per faint component: whether it touches a plain component of at least
// min_area_px pixels.
std::vector<char> touching_plain(const cv::Mat& mask, const cv::Mat& flabels, int nf, const Components& plain,
                                 int min_area_px) {
  std::vector<char> touches(static_cast<size_t>(nf), 0);
  for (int r = 0; r < mask.rows; ++r) {
    const uint8_t* m = mask.ptr<uint8_t>(r);
    const int* fl = flabels.ptr<int>(r);
    const int* pl = plain.labels.ptr<int>(r);
    for (int c = 0; c < mask.cols; ++c)
      if (m[c] != 0 && fl[c] != 0 && plain.stats.at<int>(pl[c], cv::CC_STAT_AREA) >= min_area_px)
        touches[static_cast<size_t>(fl[c])] = 1;
  }
  return touches;
}

// Local maxima (3 x 3) of the kept components; one per 2-pixel
// neighbourhood. Labels from first_label on.
Peaks local_maxima(const cv::Mat& smooth, const cv::Mat& dil, const cv::Mat& flabels, const std::vector<char>& touches,
                   int first_label) {
  Peaks peaks;
  peaks.of_comp.resize(touches.size());
  for (int r = 0; r < smooth.rows; ++r) {
    const float* sm = smooth.ptr<float>(r);
    const float* dl = dil.ptr<float>(r);
    const int* fl = flabels.ptr<int>(r);
    for (int c = 0; c < smooth.cols; ++c) {
      const int comp = fl[c];
      if (comp == 0 || touches[static_cast<size_t>(comp)] || sm[c] < dl[c]) continue;
      bool near = false;
      for (int i : peaks.of_comp[static_cast<size_t>(comp)]) {
        const Peak& q = peaks.all[static_cast<size_t>(i)];
        near = near || (std::abs(q.r - r) <= 2 && std::abs(q.c - c) <= 2);
      }
      if (near) continue;
      peaks.of_comp[static_cast<size_t>(comp)].push_back(static_cast<int>(peaks.all.size()));
      peaks.all.push_back(Peak{r, c, first_label + static_cast<int>(peaks.all.size())});
    }
  }
  return peaks;
}

// The nearest of its component's maxima to pixel (r, c).
size_t nearest_peak(const Peaks& peaks, int comp, int r, int c) {
  int best = -1;
  long best_d2 = 0;
  for (int i : peaks.of_comp[static_cast<size_t>(comp)]) {
    const long dr = peaks.all[static_cast<size_t>(i)].r - r, dc = peaks.all[static_cast<size_t>(i)].c - c;
    if (best < 0 || dr * dr + dc * dc < best_d2) best = i, best_d2 = dr * dr + dc * dc;
  }
  return static_cast<size_t>(best);
}

// Each pixel of a kept component to its nearest maximum, relabelled; the
// new components' stats and centroids appended as OpenCV's.
void assign_to_peaks(const cv::Mat& flabels, const Peaks& peaks, Components& comps) {
  const size_t np = peaks.all.size();
  cv::Mat& labels = comps.labels;
  std::vector<int> left(np, labels.cols), top(np, labels.rows), right(np, -1), bottom(np, -1), area(np, 0);
  std::vector<double> sum_c(np, 0.0), sum_r(np, 0.0);
  for (int r = 0; r < labels.rows; ++r) {
    int* lab = labels.ptr<int>(r);
    const int* fl = flabels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) {
      const int comp = fl[c];
      if (comp == 0 || peaks.of_comp[static_cast<size_t>(comp)].empty()) continue;
      const size_t k = nearest_peak(peaks, comp, r, c);
      lab[c] = peaks.all[k].label;
      left[k] = std::min(left[k], c), right[k] = std::max(right[k], c);
      top[k] = std::min(top[k], r), bottom[k] = std::max(bottom[k], r);
      ++area[k];
      sum_c[k] += c, sum_r[k] += r;
    }
  }
  for (size_t k = 0; k < np; ++k) {
    const cv::Mat st =
        (cv::Mat_<int>(1, 5) << left[k], top[k], right[k] - left[k] + 1, bottom[k] - top[k] + 1, area[k]);
    comps.stats.push_back(st);
    const cv::Mat ce = (cv::Mat_<double>(1, 2) << sum_c[k] / area[k], sum_r[k] / area[k]);
    comps.cents.push_back(ce);
  }
  comps.n += static_cast<int>(np);
}

}  // namespace

void append_faint_components(const cv::Mat& diff, const cv::Mat& mask, const FaintPass& pass, Components& comps) {
  thread_local cv::Mat diff_f, smooth, dil, fmask, flabels, fstats, fcents;  // as detect()'s buffers
  diff.convertTo(diff_f, CV_32F);
  cv::GaussianBlur(diff_f, smooth, cv::Size(0, 0), pass.sigma_px, pass.sigma_px, cv::BORDER_REPLICATE);
  cv::compare(smooth, pass.threshold_counts, fmask, cv::CMP_GT);
  const int nf = cv::connectedComponentsWithStats(fmask, flabels, fstats, fcents, 8, CV_32S);
  if (nf <= 1) return;
  const std::vector<char> touches = touching_plain(mask, flabels, nf, comps, pass.min_area_px);
  cv::dilate(smooth, dil, cv::Mat(), cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  const Peaks peaks = local_maxima(smooth, dil, flabels, touches, comps.n);
  if (peaks.all.empty()) return;
  assign_to_peaks(flabels, peaks, comps);
}

}  // namespace detail
}  // namespace fsw_vision
