// The flight app's modal estimator: range-image segments in, one modal
// filter step per image out (the estimator of
// "Shape, Motion, and Parameter Estimation of Large Flexible Space
// Structures using Range Images" (Lichter and Dubowsky), as run on board).
//
// An image arrives as segments (ModalSegment; the flight app adapts the
// link's range-image segments of up to 24 points, docs/LINK.md); each
// segment's points go straight into the streaming decomposition (eqs. 2-4)
// with the plate model's mode shapes at the point (PlateModes), so a lost
// segment loses only its points. The image closes at its last segment, or
// when a segment of another image arrives first (its last segment was
// lost); then M_Y is solved and the modal filter predicts to the image time
// and fuses the coarse amplitudes. The first well-conditioned image
// initialises it (eq. 7).
//
// The filter is the joint one by default (ModalUkfJoint: the exact coupled
// covariance of the coarse amplitudes). A partial view makes M_Y
// non-diagonal and the decoupled bank, which drops that coupling, left a
// well-excited mode more than 1 % off its frequency about twice as often
// (30 seeded plates: 15 vs 8 runs after 3 periods of the lowest mode, 7 vs
// 2 after 4.5; test_modal_tracker.cpp); at 10 modes the joint step costs
// tens of microseconds, nothing at one image a minute.
//
// Frequency acquisition (modal_acquisition.hpp): the fused images are also
// stored, and once they span acquire_after_periods of the model's lowest
// mode (or the history is full) a search over the stored history gives new
// a priori frequencies and the filter is replayed over every stored image
// from them; once per reset. Without it the joint filter can lock a high
// mode onto a wrong frequency in the first period and keep it
// (docs/perf/modal.md). At 10 modes the search and the replay take a few
// milliseconds, inside the image step that triggers them.
//
// Point: p_m = [x, y, z] in the structure frame, z the measured deflection;
// sigma_m its 1-sigma [m] (eq. 4a), or 0 for "not given" (eq. 4b with the
// residual variance; an image must not mix the two). Points off the plate
// are skipped and counted. An image no later than the last one stepped is
// stale: counted and dropped whole.
// Real-time core: fixed-size, no heap, no exceptions, no I/O.
#pragma once

#include <cmath>
#include <cstdint>

#include "fsw/math/so3.hpp"
#include "fsw/modal/modal_acquisition.hpp"
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_ukf.hpp"
#include "fsw/modal/plate_modes.hpp"

namespace fsw {

// One measured point of the structure: p_m = [x, y, z] in the structure
// frame, z the deflection; sigma_m its 1-sigma [m], 0 for "not given".
template <typename S>
struct ModalPoint {
  Vec3<S> p_m = Vec3<S>::Zero();
  S sigma_m{};
};

// One segment of a range image: the tracker's input, free of the wire
// format (the flight app adapts the link message, app/range_segment.hpp).
template <typename S>
struct ModalSegment {
  std::uint32_t image_id = 0;
  bool last = false;  // the image's last segment (or its only one): closes it
  const ModalPoint<S>* points = nullptr;
  int n_points = 0;
};

struct ModalTrackerConfig {
  PlateModelConfig plate;
  // 1-sigma of the a priori frequencies as a fraction of the model's (eq. 7;
  // the paper bounds the a priori error at about 20 %).
  double prior_omega_frac = 0.1;
  // 1-sigma of the initial amplitude rate as a fraction of the mode's
  // frequency (a unit amplitude's peak rate).
  double prior_rate_frac = 1.0;
  // Frequency acquisition once the stored images span this many periods of
  // the lowest mode (0: none).
  double acquire_after_periods = 2.0;
  // Half-width of the search's frequency interval, a fraction of the
  // model's frequencies: the paper bounds the a priori error at about 20 %.
  double acquire_span_frac = 0.2;
  // 1-sigma of the replayed filter's a priori frequencies, as a fraction
  // of the acquired ones (five of the search's grid steps, 0.2 % each at
  // +-20 % in 201 points).
  double acquire_omega_frac = 0.01;
};

inline const char* modal_tracker_config_invalid_field(const ModalTrackerConfig& c) {
  if (const char* f = plate_config_invalid_field(c.plate)) return f;
  if (!(std::isfinite(c.prior_omega_frac) && c.prior_omega_frac > 0.0 && c.prior_omega_frac < 1.0))
    return "prior_omega_frac";
  if (!(std::isfinite(c.prior_rate_frac) && c.prior_rate_frac > 0.0)) return "prior_rate_frac";
  if (!(std::isfinite(c.acquire_after_periods) && c.acquire_after_periods >= 0.0)) return "acquire_after_periods";
  if (!(std::isfinite(c.acquire_omega_frac) && c.acquire_omega_frac > 0.0 && c.acquire_omega_frac < 1.0))
    return "acquire_omega_frac";
  if (!(std::isfinite(c.acquire_span_frac) && c.acquire_span_frac > 0.0 && c.acquire_span_frac < 1.0))
    return "acquire_span_frac";
  return nullptr;
}

// What one closed image did.
template <typename S, int M>
struct ModalImageReport {
  std::uint32_t image_id = 0;
  double t_s = 0.0;
  int n_outside = 0;      // points off the plate, skipped
  bool acquired = false;  // this image completed the history: search done and the filter replayed
  AcquisitionStatus acquisition = AcquisitionStatus::Ok;  // of the search, when acquired
  ModalDecompositionRecord<S, M> decomposition;
  ModalStepRecord<S, M> step;
};

template <typename S, int M, typename F = ModalUkfJoint<S, M>, int H = 256>
class ModalTracker {
 public:
  using Filter = F;                               // ModalUkfJoint (default) or ModalUkfBank
  using Acquisition = ModalAcquisition<S, M, H>;  // H: images it can hold
  using Decomposition = ModalDecomposition<S, M>;
  using Report = ModalImageReport<S, M>;
  static constexpr int kModes = M;

  struct Counters {
    std::uint32_t segments = 0;
    std::uint32_t segments_stale = 0;  // of an image no later than the last one stepped
    std::uint32_t images = 0;          // closed and stepped
    std::uint32_t images_fused = 0;
    std::uint32_t images_incomplete = 0;  // closed by another image's segment (last segment lost)
    std::uint32_t points_outside = 0;
    std::uint32_t acquisitions = 0;         // searches done and filters replayed
    std::uint32_t acquisitions_failed = 0;  // searches that gave no frequencies (filter kept)
    // Fused images the acquisition could not store (left out of the replay).
    // Only fused images reach it (decomposition Ok, finite, times
    // increasing) and it runs once H are stored, so this stays 0 unless a
    // covariance that the filter took fails to factor there.
    std::uint32_t acquisition_refused = 0;
  };

  ModalTracker() { configure(ModalTrackerConfig()); }

  // Applies a configuration and restarts the filter; false (nothing changed)
  // for an invalid one.
  bool configure(const ModalTrackerConfig& cfg);

  // The filter's a priori knowledge (eq. 7) from the model: expected
  // frequencies the model's, no damping (a space structure's is tiny and
  // unknown), no process noise (the model is exact but for its parameters).
  static ModalFilterConfig<S, M> filter_config(const PlateModes<S, M>& model, const ModalTrackerConfig& cfg);

  // Forgets the filter and any open image (cmd_reset bit 2); the counters
  // run on, as the app's do across resets.
  void reset();

  // Closes the open image if seg_image_id is another image's; true with
  // its report in out.
  bool close_other(std::uint32_t seg_image_id, Report& out);

  // One segment. True when it completes its image (the report in out).
  bool add(const ModalSegment<S>& m, double t_s, Report& out);

  const Filter& filter() const { return filter_; }
  const Acquisition& acquisition() const { return acq_; }
  const PlateModes<S, M>& model() const { return model_; }
  const ModalTrackerConfig& config() const { return cfg_; }
  const Counters& counters() const { return counters_; }
  bool image_open() const { return open_; }

 private:
  // Solves the open image and steps the filter to its time.
  void close(Report& out);
  // Stores a fused image; runs the search and the replay when due.
  void acquire(Report& out);
  ModalAcquisitionConfig<S, M> acquisition_config() const;

  ModalTrackerConfig cfg_;
  PlateModes<S, M> model_;
  Decomposition dec_;
  Filter filter_;
  Acquisition acq_;
  typename Filter::Record replay_rec_;
  bool acquiring_ = false;  // storing images for an acquisition still to come
  Counters counters_;
  bool open_ = false;
  std::uint32_t image_id_ = 0;
  double image_t_s_ = 0.0;
  int n_outside_ = 0;
  bool have_last_ = false;
  double last_t_s_ = 0.0;
};

template <typename S, int M, typename F, int H>
bool ModalTracker<S, M, F, H>::configure(const ModalTrackerConfig& cfg) {
  if (modal_tracker_config_invalid_field(cfg) != nullptr) return false;
  cfg_ = cfg;
  model_.configure(cfg.plate);
  reset();
  return true;
}

template <typename S, int M, typename F, int H>
auto ModalTracker<S, M, F, H>::filter_config(const PlateModes<S, M>& model, const ModalTrackerConfig& cfg)
    -> ModalFilterConfig<S, M> {
  ModalFilterConfig<S, M> f;
  for (int i = 0; i < M; ++i) {
    ModalModeConfig<S>& m = f.mode[i];
    const S w = model.omega_radps(i);
    m.omega_radps = w;
    m.alpha_ps = S(0);
    m.sigma_v0_ps = S(cfg.prior_rate_frac) * w;
    m.sigma_omega0_radps = S(cfg.prior_omega_frac) * w;
    m.sigma_alpha0_ps = S(1e-6);
  }
  return f;
}

template <typename S, int M, typename F, int H>
auto ModalTracker<S, M, F, H>::acquisition_config() const -> ModalAcquisitionConfig<S, M> {
  ModalAcquisitionConfig<S, M> a;
  for (int i = 0; i < M; ++i) {
    a.omega_prior_radps[i] = model_.omega_radps(i);
    a.sigma_omega_radps[i] = S(cfg_.prior_omega_frac) * model_.omega_radps(i);
  }
  a.grid_sigmas = S(cfg_.acquire_span_frac / cfg_.prior_omega_frac);
  return a;
}

template <typename S, int M, typename F, int H>
void ModalTracker<S, M, F, H>::reset() {
  filter_.reset(filter_config(model_, cfg_));
  acq_.reset(acquisition_config());
  acquiring_ = cfg_.acquire_after_periods > 0.0;
  open_ = false;
  have_last_ = false;
}

template <typename S, int M, typename F, int H>
bool ModalTracker<S, M, F, H>::close_other(std::uint32_t seg_image_id, Report& out) {
  if (!open_ || seg_image_id == image_id_) return false;
  ++counters_.images_incomplete;
  close(out);
  return true;
}

template <typename S, int M, typename F, int H>
bool ModalTracker<S, M, F, H>::add(const ModalSegment<S>& m, double t_s, Report& out) {
  ++counters_.segments;
  if (!open_) {
    if (have_last_ && !(t_s > last_t_s_)) {
      ++counters_.segments_stale;
      return false;
    }
    open_ = true;
    image_id_ = m.image_id;
    image_t_s_ = t_s;
    n_outside_ = 0;
    dec_.reset();
  }
  S phi[M];
  for (int k = 0; k < m.n_points; ++k) {
    const ModalPoint<S>& pt = m.points[k];
    if (!model_.phi(pt.p_m.x(), pt.p_m.y(), phi)) {
      ++n_outside_;
      continue;
    }
    const S var = pt.sigma_m > S(0) ? pt.sigma_m * pt.sigma_m : S(-1);
    dec_.add_point(phi, pt.p_m.z(), var);
  }
  if (m.last) {
    close(out);
    return true;
  }
  return false;
}

template <typename S, int M, typename F, int H>
inline void ModalTracker<S, M, F, H>::close(Report& out) {
  open_ = false;
  out = Report();
  out.image_id = image_id_;
  out.t_s = image_t_s_;
  out.n_outside = n_outside_;
  counters_.points_outside += std::uint32_t(n_outside_);
  ++counters_.images;
  dec_.solve(out.decomposition);
  out.step.decomposition = out.decomposition.status;
  bool moved = false;  // the filter's time is the image's once it initialised or predicted
  if (!filter_.initialized()) {
    out.step.status = filter_.initialize(out.decomposition);
    out.step.fused = out.step.status == StepStatus::Ok;
    moved = out.step.fused;
  } else {
    const StepStatus sp = filter_.predict(S(image_t_s_ - last_t_s_));
    if (sp != StepStatus::Ok) {
      out.step.status = sp;
      out.step.detail = sp == StepStatus::NotPosDef ? StepDetail::PriorCholesky : StepDetail::None;
    } else {
      moved = true;
      filter_.update(out.decomposition, out.step);
    }
  }
  if (moved) {
    last_t_s_ = image_t_s_;
    have_last_ = true;
  }
  if (out.step.fused) {
    ++counters_.images_fused;
    if (acquiring_) acquire(out);
  }
}

template <typename S, int M, typename F, int H>
void ModalTracker<S, M, F, H>::acquire(Report& out) {
  if (acq_.add(S(image_t_s_), out.decomposition) != AcquisitionStatus::Ok) {
    ++counters_.acquisition_refused;
    return;
  }
  const double span_s = image_t_s_ - double(acq_.time(0));
  const double period1_s = 2.0 * 3.14159265358979323846 / double(model_.omega_radps(0));
  const bool due = span_s >= cfg_.acquire_after_periods * period1_s || acq_.images() == H;
  if (!due || acq_.images() < acq_.config().min_images) return;
  acquiring_ = false;  // once per reset, whatever the outcome
  out.acquired = true;
  out.acquisition = acq_.search();
  if (out.acquisition != AcquisitionStatus::Ok) {
    ++counters_.acquisitions_failed;
    return;
  }
  ModalFilterConfig<S, M> fc = filter_config(model_, cfg_);
  acq_.apply(fc, S(cfg_.acquire_omega_frac));
  // The replay ends at this image (the last stored), where the filter is now.
  acq_.replay_into(filter_, fc, replay_rec_);
  ++counters_.acquisitions;
}

// Compiled once, in fsw_core (instantiate_modal_tracker.cpp); see nav_ukf.hpp.
#ifndef FSW_IMPLICIT_INSTANTIATION
extern template class ModalTracker<double, 10>;
extern template class ModalTracker<float, 10>;
#endif

}  // namespace fsw
