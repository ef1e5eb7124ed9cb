// LED pose: the inspector's 1 Hz relative pose from a camera image of the
// host's LED pattern (docs/VISION.md).
//
// Pipeline: blob detection (local-background subtraction, threshold,
// connected components, shape gates; a matched-filter pass for faint spots
// when those blobs give no pose) -> identification of the five pattern
// LEDs (four square corners plus an identifier on one edge, a quarter of the
// way from corner 0 to corner 1; collinearity survives projection, so the
// identifier marks the edge and its off-centre position the direction) ->
// pose by cv::solvePnP (IPPE, both planar solutions), a consistency gate
// (every LED within 4 px of one fit, searched over the five leave-one-out
// fits) and Levenberg-Marquardt refinement (cv::solvePnPRefineLM) ->
// covariance from the
// reprojection Jacobian, (J^T W J)^-1 with W the inverse centroid variances
// (from the calibrated centroid error model per blob), taken directly with respect
// to the navigation filter's measurement coordinates.
//
// Frames: host body (pattern coordinates, origin at the host's centre of
// mass), Hill (docs/CONVENTIONS.md), inspector body b, camera c (OpenCV: x right,
// y down, z along the optical axis). Quaternions rotate body vectors into the
// frame named first: q_hb takes inspector body to Hill, q_h_host takes host
// body to Hill. Boundary arrays are scalar-first [w, x, y, z].
//
// Vision layer: runs at 1 Hz, may allocate, uses OpenCV; never part of the
// real-time core. Bad input and every failure give a status, never a crash.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

namespace fsw_vision {

struct SpotFit;
namespace detail {  // internals of the pipeline (fsw/vision/src/led_pose_detail.hpp)
struct Hypothesis;
struct MergedCandidate;
struct MergedFit;
}  // namespace detail

enum class PoseStatus : int {
  Ok = 0,
  TooFewLeds,          // fewer than the five pattern LEDs found
  AmbiguousIdentity,   // identifier not seen (square symmetry) or several labellings fit
  TargetBehindCamera,  // solution has an LED behind the camera or shows the pattern's back side
  DegenerateGeometry,  // LEDs (nearly) collinear, J^T J ill-conditioned, or planar mirror pose not excluded
  SolverFailed,        // PnP failed, or no labelling reprojects within the gate
  BadInput,            // image not 8-bit single channel, or wrong size
};
const char* to_string(PoseStatus s);

constexpr int kNumLeds = 5;  // corners 0..3, identifier 4
constexpr int kIdentifier = 4;

// Pinhole camera with OpenCV's radial-tangential distortion and its mount on
// the inspector. Defaults: 640 x 480, 60 degree horizontal field of view
// (fx = 320 / tan 30 deg), principal point at the image centre (pixel centres
// at integer coordinates), no distortion; boresight along inspector body +x,
// image right along body -y, image down along body -z; camera centre at
// [0.10, 0.02, -0.03] m from the inspector's centre of mass.
struct CameraModel {
  int width = 640;
  int height = 480;
  double fx_px = 554.2562584220407;
  double fy_px = 554.2562584220407;
  double cx_px = 319.5;
  double cy_px = 239.5;
  std::array<double, 5> dist{{0.0, 0.0, 0.0, 0.0, 0.0}};  // k1, k2, p1, p2, k3
  Eigen::Matrix3d R_bc = default_R_bc();                  // camera -> inspector body
  Eigen::Vector3d p_cam_b_m{0.10, 0.02, -0.03};           // camera centre, body frame [m]

  static Eigen::Matrix3d default_R_bc() {
    Eigen::Matrix3d R;
    // Columns: camera x, y, z axes expressed in the inspector body frame.
    R << 0.0, 0.0, 1.0,  //
        -1.0, 0.0, 0.0,  //
        0.0, -1.0, 0.0;
    return R;
  }
};

// LED positions in the host body frame [m] and the outward normal of the
// face that carries them. Default: a 0.16 m square on the host's +x face
// (x = 0.15 m); corners 0..3 at (y, z) = (-a,-a), (a,-a), (a,a), (-a,a) with
// a = 0.08 m; identifier at (-a/2, -a), on edge 0-1 a quarter of the way.
struct LedPattern {
  std::array<Eigen::Vector3d, kNumLeds> p_host_m;
  Eigen::Vector3d normal_host{1.0, 0.0, 0.0};
  double id_fraction = 0.25;  // identifier position along edge 0 -> 1
};
LedPattern default_pattern(double half_side_m = 0.08, double face_offset_m = 0.15);

struct LedPoseConfig {
  CameraModel camera;
  LedPattern pattern = default_pattern();
  // Detection.
  int background_kernel_px = 31;  // box filter for the local background
  int threshold_counts = 20;      // above local background
  // Faint spots: the background-subtracted image smoothed by a Gaussian of
  // faint_sigma_px (0: off), split at its local maxima above
  // faint_threshold_counts where it touches no component of the plain
  // threshold (docs/VISION.md "Faint spots"). Smoothed pixel noise is about
  // 0.2 counts over a 0.6-count floor (the clipped difference), so 3 counts
  // is over 10 sigma.
  double faint_sigma_px = 1.5;
  double faint_threshold_counts = 3.0;
  int min_area_px = 2;
  int max_area_px = 2500;
  int max_extent_px = 80;       // bounding-box side
  double max_elongation = 4.0;  // ratio of second-moment eigenvalues
  int max_blobs = 16;           // brightest kept for identification
  // Identification.
  double line_tol_px = 1.5;       // identifier off the edge: absolute part
  double line_tol_rel = 0.04;     // ... and relative to the edge length
  double id_fraction_min = 0.08;  // accepted image fraction along edge 0 -> 1
  double id_fraction_max = 0.45;
  double min_quad_area_px2 = 30.0;
  int max_hypotheses = 8;  // best-scored labellings solved
  // Pose.
  double ransac_threshold_px = 4.0;
  double max_reproj_rms_px = 2.0;  // a labelling must reproject within this
  double ambiguity_ratio = 3.0;    // runner-up labelling closer than this in rms -> ambiguous
  double min_depth_m = 0.02;
  double pixel_sigma_px = 0.25;  // centroid noise for points given without their own sigma
  // Centroid (docs/VISION.md, "Centroid error model"): a first estimate over
  // the component's box, refined by a Gaussian-weighted centroid on a ring
  // background plane. sigma^2 = centroid_noise_scale^2 sigma_noise^2
  // + (sat_sigma_px n_sat / max(width / 1 px, 1)^4)^2 (n_sat saturated pixels)
  // + centroid_floor_px^2; the three constants are fitted by
  // `python -m bench.campaigns.centroid_calibration`.
  double read_noise_counts = 1.5;       // pixel noise: read noise [counts] (the refined centroid measures its own
  double shot_gain = 0.05;              //   from the ring) and shot-noise variance per count of signal [counts]
  double centroid_floor_px = 0.003;     // calibrated, added in quadrature to each blob's sigma [px]
  bool refine_centroid = true;          // false: the first estimate (component box + 2 px, clipped weights)
  double centroid_weight_min_px = 1.0;  // bounds of the Gaussian weight's width (the spot's, from its moments)
  double centroid_weight_max_px = 6.0;
  double centroid_weight_sat_scale = 4.0;  // weight width factor for a spot with saturated pixels
  double centroid_noise_scale = 0.96;      // calibrated factor on the propagated pixel noise
  double sat_sigma_px = 0.0047;            // calibrated saturation term [px per saturated pixel]
  // Merged identifier (docs/VISION.md): four blobs and no identifier after
  // both passes; each corner is tried as the identifier's corner by a
  // two-spot fit with the identifier on the edge where the four corners'
  // homography puts it. Accepted when the best pair fits better than one
  // spot by merged_id_min_dchi2 (0: off) and better than every other
  // labelling's pair by merged_id_margin_dchi2, with the two fluxes within
  // a factor merged_id_max_flux_ratio.
  double merged_id_min_dchi2 = 25.0;
  double merged_id_margin_dchi2 = 10.0;
  double merged_id_max_flux_ratio = 4.0;
  int merged_id_max_half_window_px = 20;  // fit window half-size bound
  double max_condition = 1e12;            // of J^T J
  double flip_weight_max = 0.01;          // planar mirror solution more likely than this -> no pose
};

struct Blob {
  double u_px = 0;  // column, pixel centres at integers
  double v_px = 0;  // row
  double flux = 0;  // background-subtracted sum [counts]
  int area_px = 0;
  double sigma_px = 0;        // centroid standard deviation from the calibrated error model
  int n_saturated = 0;        // pixels at 255 in the centroid window
  double sigma_noise_px = 0;  // pixel-noise part of sigma_px, before the calibration's scale and terms
  double width_px = 0;        // spot width (rms radius per axis) from the component's moments
};

// A pose measurement ready for the navigation update (NavUkf::update_pose):
// r_hill_m of the inspector relative to the host, q_hb, and R over
// [position (Hill) m^2, body-frame attitude error rad^2] with
// q_true = q_hb * Exp(dtheta).
struct LedPoseMeasurement {
  PoseStatus status = PoseStatus::SolverFailed;
  double t_capture_s = 0.0;
  Eigen::Vector3d r_hill_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_hb = Eigen::Quaterniond::Identity();
  Eigen::Matrix<double, 6, 6> R = Eigen::Matrix<double, 6, 6>::Zero();
  // Diagnostics.
  int n_blobs = 0;       // blobs passing the shape gates
  int n_hypotheses = 0;  // labellings tried
  double reproj_rms_px = 0.0;
  double flip_weight = 0.0;       // weight of the planar mirror solution folded into R
  double range_m = 0.0;           // camera to pattern centre
  bool identifier_split = false;  // the identifier came from a merged blob's two-spot fit
  std::array<int, kNumLeds> blob_of_led{{-1, -1, -1, -1, -1}};
  Eigen::Matrix3d R_cp = Eigen::Matrix3d::Identity();  // host body -> camera
  Eigen::Vector3d t_cp_m = Eigen::Vector3d::Zero();    // host origin in camera frame
};

class LedPoseEstimator {
 public:
  explicit LedPoseEstimator(const LedPoseConfig& cfg = LedPoseConfig());

  const LedPoseConfig& config() const { return cfg_; }

  // Blobs of an 8-bit single-channel image, brightest first; with the
  // faint-spot pass when faint_sigma_px > 0 (the two-argument form chooses).
  std::vector<Blob> detect(const cv::Mat& gray) const { return detect(gray, cfg_.faint_sigma_px > 0.0); }
  std::vector<Blob> detect(const cv::Mat& gray, bool faint_pass) const;

  // Full pipeline. q_h_host: host attitude (host body -> Hill). The faint
  // pass (a matched filter over the frame) runs only when the plain
  // threshold's blobs give no pose for want of an LED (TooFewLeds or
  // AmbiguousIdentity); when it finds more blobs, its result is the answer.
  // Four blobs still ambiguous then: the merged-identifier fit
  // (pose_with_merged_identifier) decides.
  LedPoseMeasurement estimate(const cv::Mat& gray, double t_capture_s,
                              const Eigen::Quaterniond& q_h_host = Eigen::Quaterniond::Identity()) const;

  // Identification and pose from blob centres (pixels), for tests and for
  // detectors other than detect().
  // sigma_px: centroid standard deviation per point (pixel_sigma_px where
  // not given).
  LedPoseMeasurement estimate_from_points(const std::vector<cv::Point2d>& pts, double t_capture_s,
                                          const Eigen::Quaterniond& q_h_host = Eigen::Quaterniond::Identity(),
                                          const std::vector<double>& sigma_px = {}) const;

  // The pattern's pixel coordinates for an inspector pose (r_hill_m, q_hb)
  // with the configured camera (including distortion). Returns false if an
  // LED is at depth <= 0 (its coordinates are then meaningless).
  bool project(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb, const Eigen::Quaterniond& q_h_host,
               std::array<cv::Point2d, kNumLeds>& px) const;

  // Camera-frame pose of the host (R_cp, t_cp) from the inspector pose and back.
  void camera_from_nav(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb,
                       const Eigen::Quaterniond& q_h_host, Eigen::Matrix3d& R_cp, Eigen::Vector3d& t_cp_m) const;
  void nav_from_camera(const Eigen::Matrix3d& R_cp, const Eigen::Vector3d& t_cp_m, const Eigen::Quaterniond& q_h_host,
                       Eigen::Vector3d& r_hill_m, Eigen::Quaterniond& q_hb) const;

  // d(pixels)/d[r_hill_m, dtheta_b] (10 x 6), central differences through
  // project(); the covariance is (J^T W J)^-1, W = diag(1 / sigma_px^2).
  bool jacobian(const Eigen::Vector3d& r_hill_m, const Eigen::Quaterniond& q_hb, const Eigen::Quaterniond& q_h_host,
                Eigen::Matrix<double, 2 * kNumLeds, 6>& J) const;

 private:
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  // What weights the pose covariance: the host attitude and the whitening
  // 1 / sigma per image coordinate of the chosen labelling's LEDs.
  struct PoseWeights {
    Eigen::Quaterniond q_h_host;
    Eigen::Matrix<double, 2 * kNumLeds, 1> inv_sig;
  };

  // Identification (identification.cpp). The finite points with positive
  // sigma, at most max_blobs; true when at least four.
  bool usable_points(const std::vector<cv::Point2d>& pts_in, const std::vector<double>& sigma_px,
                     std::vector<cv::Point2d>& pts, std::vector<double>& sig) const;
  // All points (nearly) on a line or inside a tiny hull.
  bool spread_degenerate(const std::vector<cv::Point2d>& pts) const;
  // p within the line tolerance of edge a -> b, at fraction t along it.
  bool on_edge(const cv::Point2d& a, const cv::Point2d& b, const cv::Point2d& p, double& t) const;
  // The labellings with identifier ijk[2] on edge ijk[0] -> ijk[1], scored.
  void corner_labellings(const std::vector<cv::Point2d>& pts, const std::array<int, 3>& ijk, int& candidates,
                         std::vector<detail::Hypothesis>& hyps) const;
  // Every labelling, best-scored first, at most max_hypotheses; true when
  // some three points are collinear with the middle one between the others.
  bool labellings(const std::vector<cv::Point2d>& pts, std::vector<detail::Hypothesis>& hyps) const;
  // Why no labelling: a bare square is AmbiguousIdentity, else TooFewLeds.
  PoseStatus no_labelling_status(const std::vector<cv::Point2d>& pts, bool any_collinear_triple) const;

  // Pose (pose_solution.cpp).
  Eigen::Vector3d pattern_centre() const;
  // Every LED in front of the camera and the pattern's face towards it.
  bool physical(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) const;
  // Largest single-LED reprojection error [px] of a pose.
  double worst_residual(const std::vector<cv::Point2d>& img, const cv::Mat& rv, const cv::Mat& tv) const;
  // One solution of labelling h refined (Levenberg-Marquardt) and kept if physical.
  void refine_solution(detail::Hypothesis& h, const std::vector<cv::Point2d>& img, const std::vector<double>& sig,
                       const cv::Mat& rv0, const cv::Mat& tv0) const;
  // The labelling's solutions, best first (may throw cv::Exception).
  void solve_labelling(detail::Hypothesis& h, const std::vector<cv::Point2d>& pts,
                       const std::vector<double>& sig) const;
  // Labellings sorted by reprojection rms; Ok when the best stands out.
  PoseStatus choose_labelling(std::vector<detail::Hypothesis>& hyps, const std::vector<double>& sig,
                              LedPoseMeasurement& m) const;
  bool pose_covariance(const Eigen::Vector3d& r, const Eigen::Quaterniond& q, const PoseWeights& weights, Mat6& C,
                       Mat6& info) const;
  // The planar mirror solution folded into R; false when it is too likely.
  bool fold_mirror_solution(const detail::Hypothesis& best, const PoseWeights& weights, const Mat6& info,
                            LedPoseMeasurement& m, Mat6& R) const;
  // The robust gate's consensus over the five leave-one-out fits of a
  // labelling: the most LEDs within ransac_threshold_px of one pose.
  int consensus_without_one(const std::vector<cv::Point2d>& img, cv::Mat& rv, cv::Mat& tv) const;

  // Merged identifier (merged_identifier.cpp). The pose when the identifier
  // is merged into its corner's blob (four blobs, AmbiguousIdentity), with
  // identifier_split set; AmbiguousIdentity (identifier_split false) when no
  // labelling's two-spot fit stands out (merged_id_* settings).
  LedPoseMeasurement pose_with_merged_identifier(const cv::Mat& gray, const std::vector<Blob>& blobs,
                                                 double t_capture_s, const Eigen::Quaterniond& q_h_host) const;
  // The two labellings (towards either neighbour) of corner k of the four
  // blobs (around: convex order) merged with the identifier, into top
  // (best, second) when they improve on it.
  void merged_candidates_at(const cv::Mat& gray, const std::array<cv::Point2d, 4>& around, int k, double width0,
                            std::array<detail::MergedCandidate, 2>& top) const;
  // The two-spot fit with the identifier where corners' homography puts it;
  // false when it fails or the two fluxes are too unequal.
  bool fit_merged_pair(const detail::MergedFit& fit, std::array<cv::Point2d, 4> corners, SpotFit& pair) const;

  // Geometry (geometry.cpp). Where the homography of four image corners (in
  // label order) puts the identifier; false when degenerate.
  bool identifier_in_image(const std::array<cv::Point2f, 4>& quad, cv::Point2d& id_px) const;
  // The identifier's image fraction along edge 0 -> 1 under that
  // homography; NaN when degenerate.
  double identifier_fraction(const std::array<cv::Point2d, 4>& corners) const;

  LedPoseConfig cfg_;
  cv::Mat K_;
  cv::Mat dist_;
  std::vector<cv::Point3d> obj_;
  std::vector<cv::Point2f> plane_uv_;
};

}  // namespace fsw_vision
