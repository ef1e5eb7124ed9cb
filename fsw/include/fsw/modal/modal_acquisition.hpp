// Frequency acquisition for the modal filter: a global search over each
// mode's a priori frequency interval, on a bounded history of images.
//
// Why: the modal UKF (modal_ukf.hpp) refines frequencies locally around its
// estimate. From a priori frequencies up to 10 % off, with 50 modes seen in
// a quarter of the structure, the likelihood in a mode's frequency has many
// local maxima and the filter locks some high modes onto wrong ones in the
// first period (docs/perf/modal.md). A search over the whole interval needs
// the whole history, which a Gaussian summary cannot hold.
//
// Model: image k at time t_k gives the coarse amplitudes a_k (eq. 3) with
// covariance C_k (eq. 4); a_k = q(t_k) + e_k, e_k ~ N(0, C_k), each mode
// an undamped sinusoid q_i(t) = c_i cos(w_i t) + s_i sin(w_i t). Stored per
// image: t_k, a_k, the information J_k = C_k^-1 (packed lower triangle),
// b_k = J_k a_k and diag(C_k); with the search's tables, H (M (M + 1) / 2
// + 5 M + 1) + 8 M^2 scalars: sizeof is 3.4 MB at M = 50, H = 256 in double
// (1.7 MB float), 0.24 MB at M = 10. Construct once (statically or at
// start-up); nothing below allocates.
//
// Search (RELAX, Li and Stoica 1996, with the coupled weights):
//  1. Start: per mode, the frequency on the grid that best explains its own
//     coarse series alone, weighted by diag(C_k) (modes treated as uncoupled).
//  2. Cycles over the modes: mode i, the others held at their current fit,
//     gets the grid frequency that best explains what they leave, with the
//     exact weights: g_k = (J_k (a_k - q_k))_i with q_k,i = 0, h_k = J_k(i,i),
//       N(w) = sum_k h_k [cc cs; cs ss],  r(w) = sum_k g_k [c; s]
//       gain(w) = r^T N^-1 r - ((w - w_prior,i) / sigma_i)^2,
//     then every mode's (c, s) is re-solved jointly at the current
//     frequencies (2M weighted linear least squares over all images).
//  Conditioned on the other modes, a mode's noise is that of the information
//  diagonal, often 10-30 times smaller than its own coarse variance when
//  M_Y is ill-conditioned; that is what the coupled weights buy.
//  The grid spans +-grid_sigmas a priori sigmas in G points. Work: per mode
//  search O(H (M + G) + M^3) (the amplitudes' normal equations are kept and
//  only the searched mode's rows refreshed); search_step() does one, so a
//  caller can spread the cycles * M searches over idle time.
//
// Then a filter is replayed over the history from the acquired frequencies
// (replay_into): it ends at the last image with the information of every
// image, as if it had started from those frequencies.
//
// The bench's numpy version (bench/campaigns/modal_batch_ml.py: _grid_start,
// _relax_start) is the reference this is checked against.
// Real-time core: fixed-size Eigen only, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <cstdint>

#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_ukf.hpp"

namespace fsw {

enum class AcquisitionStatus : std::uint8_t {
  Ok = 0,
  HistoryFull = 1,    // add(): the history holds H images; not stored
  NotUsable = 2,      // add(): the image's decomposition was not Ok; not stored
  NonFinite = 3,      // add(): non-finite time, amplitude or covariance; not stored
  NotPosDef = 4,      // add(): the covariance did not factor; not stored
  NotIncreasing = 5,  // add(): time not after the last stored image's; not stored
  TooFewImages = 6,   // search(): fewer than min_images stored
  BadConfig = 7,      // a priori frequency or sigma not finite and > 0, or bad grid / cycles
  Searching = 8,      // search_step(): more mode searches remain
  NoSuchImage = 9,    // coarse(): index outside the stored images
  NotStarted = 10,    // search_step(): no start_search() since the last image was stored
};

constexpr const char* to_string(AcquisitionStatus s) {
  switch (s) {
    case AcquisitionStatus::Ok: return "ok";
    case AcquisitionStatus::HistoryFull: return "history_full";
    case AcquisitionStatus::NotUsable: return "not_usable";
    case AcquisitionStatus::NonFinite: return "non_finite";
    case AcquisitionStatus::NotPosDef: return "not_pos_def";
    case AcquisitionStatus::NotIncreasing: return "not_increasing";
    case AcquisitionStatus::TooFewImages: return "too_few_images";
    case AcquisitionStatus::BadConfig: return "bad_config";
    case AcquisitionStatus::Searching: return "searching";
    case AcquisitionStatus::NoSuchImage: return "no_such_image";
    case AcquisitionStatus::NotStarted: return "not_started";
  }
  return "unknown";
}

template <typename S, int M>
struct ModalAcquisitionConfig {
  S omega_prior_radps[M] = {};  // a priori frequencies (eq. 7's omega_exp)
  S sigma_omega_radps[M] = {};  // their 1-sigma: the grid's scale and the penalty's
  S grid_sigmas = S(3);         // grid spans +- this many sigma
  int cycles = 3;               // RELAX cycles over all modes
  int min_images = 3;
};

template <typename S, int M>
inline bool acquisition_config_ok(const ModalAcquisitionConfig<S, M>& c) {
  for (int i = 0; i < M; ++i) {
    if (!(std::isfinite(c.omega_prior_radps[i]) && c.omega_prior_radps[i] > S(0))) return false;
    if (!(std::isfinite(c.sigma_omega_radps[i]) && c.sigma_omega_radps[i] > S(0))) return false;
  }
  return std::isfinite(c.grid_sigmas) && c.grid_sigmas > S(0) && c.cycles >= 1 && c.cycles <= 100 && c.min_images >= 3;
}

template <typename S, int M, int H, int G = 201>
class ModalAcquisition {
  static_assert(M >= 1 && H >= 3 && G >= 2, "modes, history and grid sizes");

 public:
  using Config = ModalAcquisitionConfig<S, M>;
  using Decomp = ModalDecompositionRecord<S, M>;
  using VecM = Eigen::Matrix<S, M, 1>;
  using MatM = Eigen::Matrix<S, M, M>;
  static constexpr int kModes = M;
  static constexpr int kHistory = H;
  static constexpr int kGrid = G;
  static constexpr int kPacked = M * (M + 1) / 2;

  // cppcheck-suppress uninitMemberVar ; reset() sets every member
  explicit ModalAcquisition(const Config& cfg = Config()) { reset(cfg); }

  // Empties the history and takes a new configuration.
  AcquisitionStatus reset(const Config& cfg);

  // Stores one image's decomposition taken at t_s (times increasing).
  AcquisitionStatus add(S t_s, const Decomp& meas);

  // Full search: start_search() then search_step() until done.
  AcquisitionStatus search();
  // Grid start (step 1). Then search_step() runs one mode search of step 2
  // per call and returns Searching until the last, then Ok. A stored image
  // makes the search stale: search_step() then wants start_search() again.
  AcquisitionStatus start_search();
  AcquisitionStatus search_step();

  int images() const { return n_; }
  S time(int k) const { return t_[k]; }
  bool done() const { return done_; }
  const Config& config() const { return cfg_; }
  // Current fit (final after search() returned Ok).
  S omega(int i) const { return w_[i]; }
  S cos_amp(int i) const { return c_[i]; }
  S sin_amp(int i) const { return s_[i]; }
  // q_i(t) of the fit.
  S amplitude_at(int i, S t_s) const { return c_[i] * std::cos(w_[i] * t_s) + s_[i] * std::sin(w_[i] * t_s); }

  // Image k's coarse estimate and covariance rebuilt from the stored
  // information (status Ok), into out.
  AcquisitionStatus coarse(int k, Decomp& out);

  // Filter configuration: base with each mode's expected frequency set to
  // the acquired one and its initial 1-sigma to sigma_rel of it.
  void apply(ModalFilterConfig<S, M>& cfg, S sigma_rel) const {
    for (int i = 0; i < M; ++i) {
      cfg.mode[i].omega_radps = w_[i];
      cfg.mode[i].sigma_omega0_radps = sigma_rel * w_[i];
    }
  }

  // Resets the filter to cfg and steps it over every stored image (the
  // first initialises it, eq. 7). Returns how many images it fused.
  template <typename Filter>
  int replay_into(Filter& filter, const ModalFilterConfig<S, M>& cfg, typename Filter::Record& rec);

 private:
  S packed(int k, int i, int j) const {
    return i >= j ? info_[k * kPacked + i * (i + 1) / 2 + j] : info_[k * kPacked + j * (j + 1) / 2 + i];
  }
  S grid_omega(int i, int g) const {
    return cfg_.omega_prior_radps[i] + cfg_.sigma_omega_radps[i] * cfg_.grid_sigmas * (S(2 * g) / S(G - 1) - S(1));
  }
  // Best grid frequency for mode i from its series: information-weighted
  // residual g_[k] and information h_[k] per image.
  void grid_search(int i);
  void set_trig(int i);
  void update_normal(int i);
  bool solve_amplitudes();

  Config cfg_;
  bool config_ok_ = false;
  int n_ = 0;
  S t_[H];
  alignas(64) S info_[H * kPacked];  // J_k packed, lower triangle by rows
  alignas(64) S a_[H * M];           // a_k
  alignas(64) S b_[H * M];           // J_k a_k
  alignas(64) S var_[H * M];         // diag(C_k)
  // Search state.
  bool done_ = false;
  bool started_ = false;  // start_search() ran on the images stored now
  int next_ = 0;          // next mode search: cycle = next_ / M, mode = next_ % M
  S w_[M], c_[M], s_[M];
  alignas(64) S cw_[H * M];  // cos(w_j t_k)
  alignas(64) S sw_[H * M];  // sin(w_j t_k)
  S g_[H], h_[H];            // one mode's series and weights
  S ncc_[G], ncs_[G], nss_[G], bc_[G], bs_[G];
  modal_detail::Store<S, 2 * M, 2 * M> normal_, fact_;
  Eigen::Matrix<S, 2 * M, 1> rhs_keep_, rhs_;
  MatM work_;
  Eigen::LLT<MatM> llt_;
  Decomp meas_;  // replay's rebuilt image
};

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::reset(const Config& cfg) {
  cfg_ = cfg;
  config_ok_ = acquisition_config_ok(cfg);
  n_ = 0;
  done_ = false;
  started_ = false;
  next_ = 0;
  for (int i = 0; i < M; ++i) {
    w_[i] = cfg_.omega_prior_radps[i];
    c_[i] = s_[i] = S(0);
  }
  return config_ok_ ? AcquisitionStatus::Ok : AcquisitionStatus::BadConfig;
}

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::add(S t_s, const Decomp& meas) {
  if (!meas.ok()) return AcquisitionStatus::NotUsable;
  if (n_ >= H) return AcquisitionStatus::HistoryFull;
  if (!std::isfinite(t_s) || !meas.a_coarse.allFinite() || !meas.cov_a.allFinite()) return AcquisitionStatus::NonFinite;
  if (n_ > 0 && !(t_s > t_[n_ - 1])) return AcquisitionStatus::NotIncreasing;
  llt_.compute(meas.cov_a);
  if (llt_.info() != Eigen::Success) return AcquisitionStatus::NotPosDef;
  work_.setIdentity();
  llt_.solveInPlace(work_);  // J = C^-1
  if (!work_.allFinite()) return AcquisitionStatus::NotPosDef;
  const int k = n_;
  S* jk = info_ + k * kPacked;
  for (int i = 0; i < M; ++i)
    for (int j = 0; j <= i; ++j) jk[i * (i + 1) / 2 + j] = S(0.5) * (work_(i, j) + work_(j, i));
  Eigen::Map<VecM>(a_ + k * M) = meas.a_coarse;
  Eigen::Map<VecM>(b_ + k * M) = work_ * meas.a_coarse;
  for (int i = 0; i < M; ++i) var_[k * M + i] = meas.cov_a(i, i);
  t_[k] = t_s;
  ++n_;
  done_ = false;
  started_ = false;
  return AcquisitionStatus::Ok;
}

template <typename S, int M, int H, int G>
void ModalAcquisition<S, M, H, G>::set_trig(int i) {
  for (int k = 0; k < n_; ++k) {
    cw_[k * M + i] = std::cos(w_[i] * t_[k]);
    sw_[k * M + i] = std::sin(w_[i] * t_[k]);
  }
}

template <typename S, int M, int H, int G>
void ModalAcquisition<S, M, H, G>::grid_search(int i) {
  for (int g = 0; g < G; ++g) ncc_[g] = ncs_[g] = nss_[g] = bc_[g] = bs_[g] = S(0);
  const S w0 = grid_omega(i, 0);
  const S dw = grid_omega(i, 1) - w0;
  for (int k = 0; k < n_; ++k) {
    // cos / sin over the grid by rotation: one sincos per image, not per point
    const S cd = std::cos(dw * t_[k]), sd = std::sin(dw * t_[k]);
    S c = std::cos(w0 * t_[k]), s = std::sin(w0 * t_[k]);
    const S h = h_[k], y = g_[k];
    for (int g = 0; g < G; ++g) {
      ncc_[g] += h * c * c;
      ncs_[g] += h * c * s;
      nss_[g] += h * s * s;
      bc_[g] += y * c;
      bs_[g] += y * s;
      const S cn = c * cd - s * sd;
      s = s * cd + c * sd;
      c = cn;
    }
  }
  int best = -1;
  S best_gain = S(0);
  for (int g = 0; g < G; ++g) {
    const S det = ncc_[g] * nss_[g] - ncs_[g] * ncs_[g];
    if (!(det > S(0))) continue;
    const S pen = (grid_omega(i, g) - cfg_.omega_prior_radps[i]) / cfg_.sigma_omega_radps[i];
    const S gain =
        (nss_[g] * bc_[g] * bc_[g] - S(2) * ncs_[g] * bc_[g] * bs_[g] + ncc_[g] * bs_[g] * bs_[g]) / det - pen * pen;
    if (best < 0 || gain > best_gain) {
      best = g;
      best_gain = gain;
    }
  }
  if (best < 0) return;  // no grid frequency is identifiable from these times: keep the current fit
  const S det = ncc_[best] * nss_[best] - ncs_[best] * ncs_[best];
  w_[i] = grid_omega(i, best);
  c_[i] = (nss_[best] * bc_[best] - ncs_[best] * bs_[best]) / det;
  s_[i] = (ncc_[best] * bs_[best] - ncs_[best] * bc_[best]) / det;
}

template <typename S, int M, int H, int G>
void ModalAcquisition<S, M, H, G>::update_normal(int i) {
  // Normal equations of x = [c; s]: sum_k D_k^T J_k D_k x = sum_k D_k^T b_k,
  // D_k = [diag(cos w t_k), diag(sin w t_k)]. Mode i's frequency enters only
  // its own rows and columns: refreshed in O(H M) after mode i's search.
  S cc[M], ss[M], sc[M], cs[M];
  for (int j = 0; j < M; ++j) cc[j] = ss[j] = sc[j] = cs[j] = S(0);
  S rc = S(0), rs = S(0);
  for (int k = 0; k < n_; ++k) {
    const S* ck = cw_ + k * M;
    const S* sk = sw_ + k * M;
    const S ci = ck[i], si = sk[i];
    for (int j = 0; j < M; ++j) {
      const S jij = packed(k, i, j);
      cc[j] += jij * ci * ck[j];
      ss[j] += jij * si * sk[j];
      sc[j] += jij * si * ck[j];
      cs[j] += jij * ci * sk[j];
    }
    rc += ci * b_[k * M + i];
    rs += si * b_[k * M + i];
  }
  auto N = normal_.m();
  for (int j = 0; j < M; ++j) {
    N(i, j) = N(j, i) = cc[j];
    N(M + i, M + j) = N(M + j, M + i) = ss[j];
    N(M + i, j) = N(j, M + i) = sc[j];
    N(i, M + j) = N(M + j, i) = cs[j];
  }
  rhs_keep_(i) = rc;
  rhs_keep_(M + i) = rs;
}

template <typename S, int M, int H, int G>
bool ModalAcquisition<S, M, H, G>::solve_amplitudes() {
  auto F = fact_.m();
  // cppcheck-suppress redundantInitialization ; F is a view: this copies into the factor storage
  F = normal_.m();  // factorised in place: the normal matrix is kept for the next update
  rhs_ = rhs_keep_;
  Eigen::LLT<Eigen::Ref<Eigen::Matrix<S, 2 * M, 2 * M>>> llt(F);
  if (llt.info() != Eigen::Success) return false;
  llt.solveInPlace(rhs_);
  if (!rhs_.allFinite()) return false;
  for (int i = 0; i < M; ++i) {
    c_[i] = rhs_(i);
    s_[i] = rhs_(M + i);
  }
  return true;
}

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::start_search() {
  if (!config_ok_) return AcquisitionStatus::BadConfig;
  if (n_ < cfg_.min_images) return AcquisitionStatus::TooFewImages;
  done_ = false;
  next_ = 0;
  // Step 1: each mode's own coarse series, weighted by 1 / diag(C_k).
  for (int i = 0; i < M; ++i) {
    w_[i] = cfg_.omega_prior_radps[i];
    for (int k = 0; k < n_; ++k) {
      h_[k] = S(1) / var_[k * M + i];
      g_[k] = a_[k * M + i] * h_[k];
    }
    grid_search(i);
  }
  for (int i = 0; i < M; ++i) {
    c_[i] = s_[i] = S(0);
    set_trig(i);
  }
  for (int i = 0; i < M; ++i) update_normal(i);
  started_ = true;
  return AcquisitionStatus::Searching;
}

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::search_step() {
  if (done_) return AcquisitionStatus::Ok;
  if (!config_ok_) return AcquisitionStatus::BadConfig;
  if (n_ < cfg_.min_images) return AcquisitionStatus::TooFewImages;
  if (!started_) return AcquisitionStatus::NotStarted;  // its tables do not cover every stored image
  const int i = next_ % M;
  // Step 2 for mode i: what the other modes' fit leaves, exact weights.
  for (int k = 0; k < n_; ++k) {
    const S* ck = cw_ + k * M;
    const S* sk = sw_ + k * M;
    S r = b_[k * M + i];
    for (int j = 0; j < M; ++j) {
      if (j == i) continue;
      r -= packed(k, i, j) * (c_[j] * ck[j] + s_[j] * sk[j]);
    }
    g_[k] = r;
    h_[k] = packed(k, i, i);
  }
  grid_search(i);
  set_trig(i);
  update_normal(i);
  solve_amplitudes();  // on failure (rank-deficient) the per-mode fit stands
  ++next_;
  if (next_ >= cfg_.cycles * M) {
    done_ = true;
    return AcquisitionStatus::Ok;
  }
  return AcquisitionStatus::Searching;
}

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::search() {
  AcquisitionStatus st = start_search();
  // bounded: cycles * M steps (cycles <= 100 by the configuration check)
  for (int n = 0; st == AcquisitionStatus::Searching && n < cfg_.cycles * M; ++n) st = search_step();
  return st;
}

template <typename S, int M, int H, int G>
AcquisitionStatus ModalAcquisition<S, M, H, G>::coarse(int k, Decomp& out) {
  if (k < 0 || k >= n_) return AcquisitionStatus::NoSuchImage;
  for (int i = 0; i < M; ++i)
    for (int j = 0; j <= i; ++j) work_(i, j) = work_(j, i) = packed(k, i, j);
  llt_.compute(work_);
  if (llt_.info() != Eigen::Success) return AcquisitionStatus::NotPosDef;
  out.cov_a.setIdentity();
  llt_.solveInPlace(out.cov_a);
  out.cov_a = (S(0.5) * (out.cov_a + out.cov_a.transpose())).eval();
  out.a_coarse = Eigen::Map<const VecM>(a_ + k * M);
  out.status = ModalStatus::Ok;
  return AcquisitionStatus::Ok;
}

template <typename S, int M, int H, int G>
template <typename Filter>
int ModalAcquisition<S, M, H, G>::replay_into(Filter& filter, const ModalFilterConfig<S, M>& cfg,
                                              typename Filter::Record& rec) {
  filter.reset(cfg);
  int fused = 0;
  for (int k = 0; k < n_; ++k) {
    if (coarse(k, meas_) != AcquisitionStatus::Ok) continue;
    const S dt = k == 0 ? S(1) : t_[k] - t_[k - 1];  // the first image initialises: dt unused
    if (filter.step(dt, meas_, rec) == StepStatus::Ok && rec.fused) ++fused;
  }
  return fused;
}

// Compiled once, in fsw_core (instantiate_modal_acquisition.cpp).
#ifndef FSW_IMPLICIT_INSTANTIATION
#define FSW_EXTERN_ACQUISITION(S, M) extern template class ModalAcquisition<S, M, 256>;
FSW_MODAL_INSTANCES(FSW_EXTERN_ACQUISITION)
#undef FSW_EXTERN_ACQUISITION
#endif

}  // namespace fsw
