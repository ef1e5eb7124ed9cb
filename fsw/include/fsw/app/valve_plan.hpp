// A stored open-loop valve plan: uplinked entry by entry (cmd_plan_entry),
// checked whole against the vehicle's limits before it is stored (cmd_plan
// load), then run on command (start, abort) one control interval at a time.
//
// An entry is one opening of one valve, [t_open_s, t_close_s) from the
// plan's start. Entries arrive in any order into a staging area keyed by
// plan id (an entry of another plan id or entry count starts it afresh; an
// entry sent again replaces its copy). A load checks the staged plan and
// stores it only when every rule holds; otherwise it answers why and
// changes nothing: the stored plan, its state and a running plan stay as
// they were. The rules, first failing one answered (PlanVerdict):
//   - no plan is running (Running);
//   - the count fits the store (TooLong: count or an entry index above
//     kCapacity);
//   - the staged entries are the load's plan id and count, all of them
//     received, at least one (Incomplete);
//   - 0 < duration_s, finite (BadTimes), duration_s <= max_duration_s
//     (DurationTooLong);
//   - per entry: valve < valves (ValveOutOfRange); 0 <= t_open_s <
//     t_close_s <= duration_s, finite (BadTimes); min_on_time_s <= on-time
//     (OnTimeTooShort) <= max_on_time_s (OnTimeTooLong); entries ordered by
//     t_open_s and no valve's openings overlapping (Overlap);
//   - the on-times summed <= max_total_on_time_s (TotalOnTimeTooLong).
// Limits in force at the load apply to that plan.
//
// Running: command(t, dt) gives the valve command for the control interval
// [t, t + dt) of mission time (t_start the start command's time tag): each
// valve's open time within the interval, and the mask of valves open in
// it. The tick at or after the plan's end closes every valve and finishes
// the plan; abort closes them at once.
//
// Fixed storage, no heap, no exceptions, no I/O; every loop bounded by
// kCapacity. Times are doubles in both builds (mission times, as the
// packet time tags).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fsw/link/apid.hpp"

namespace fsw {

enum class PlanState : std::uint8_t { Empty = 0, Loaded = 1, Running = 2, Finished = 3, Aborted = 4 };

enum class PlanVerdict : std::uint8_t {
  Accepted = 0,
  Incomplete = 1,          // entries missing, or of another plan id or count, or none
  TooLong = 2,             // more entries than the store holds
  ValveOutOfRange = 3,     // a valve index the vehicle does not have
  OnTimeTooShort = 4,      // an opening shorter than the minimum on-time
  OnTimeTooLong = 5,       // an opening longer than the maximum on-time
  BadTimes = 6,            // negative, non-finite, close <= open, past the plan's end, duration <= 0
  Overlap = 7,             // entries out of order, or one valve's openings overlapping
  TotalOnTimeTooLong = 8,  // the on-times summed above the limit
  DurationTooLong = 9,     // the plan longer than the limit
  NoPlan = 10,             // start: no stored plan of that id
  Running = 11,            // load or start while a plan runs
  NotRunning = 12,         // abort with no plan running
  UnknownAction = 13,
};
static_assert(static_cast<std::uint8_t>(PlanVerdict::UnknownAction) == kPlanVerdictMax, "tm_plan_status verdict");
static_assert(static_cast<std::uint8_t>(PlanState::Aborted) == kPlanStateMax, "tm_plan_status state");

// The vehicle's limits a plan must respect (cmd_config 19-23).
struct PlanLimits {
  std::uint32_t valves = static_cast<std::uint32_t>(kPlanValves);  // valve indices 0 .. valves - 1
  double min_on_time_s = 0.1;                                      // shortest opening
  double max_on_time_s = 20.0;                                     // longest opening
  double max_total_on_time_s = 120.0;                              // the openings summed
  double max_duration_s = 1800.0;                                  // the plan's length
};

// The name of the limit that is out of its domain, or nullptr.
inline const char* plan_limits_invalid_field(const PlanLimits& l) {
  if (l.valves < 1 || l.valves > kPlanValves) return "valves";
  if (!(l.min_on_time_s >= 0.0) || !std::isfinite(l.min_on_time_s)) return "min_on_time_s";
  if (!(l.max_on_time_s >= l.min_on_time_s) || !std::isfinite(l.max_on_time_s)) return "max_on_time_s";
  if (!(l.max_total_on_time_s > 0.0) || !std::isfinite(l.max_total_on_time_s)) return "max_total_on_time_s";
  if (!(l.max_duration_s > 0.0) || !std::isfinite(l.max_duration_s)) return "max_duration_s";
  return nullptr;
}

struct PlanEntry {
  double t_open_s = 0.0;
  double t_close_s = 0.0;
  std::uint8_t valve = 0;
};

// The valve command of one control interval.
struct PlanCommand {
  std::uint8_t valve_mask = 0;  // valves open at some time in the interval
  std::array<double, kPlanValves> on_time_s{};
  double plan_time_s = 0.0;              // the interval's start from the plan's start
  bool full = true;                      // every open valve open the whole interval
  PlanState state = PlanState::Running;  // Finished: this tick ended the plan (all closed)
};

class ValvePlan {
 public:
  static constexpr std::size_t kCapacity = 128;  // entries the store holds
  // An opening whose part in an interval is below this is no opening there
  // (rounding of times that fall on the interval's edges) [s].
  static constexpr double kEdgeTolS = 1e-9;

  // One uplinked entry into the staging area.
  void stage(const CmdPlanEntryMsg& m) {
    if (m.plan_id != stage_id_ || m.entry_count != stage_count_ || !staging_) {
      staging_ = true;
      stage_id_ = m.plan_id;
      stage_count_ = m.entry_count;
      stage_received_ = 0;
      stage_too_long_ = false;
      stage_inconsistent_ = false;
      for (auto& w : stage_have_) w = 0;
    }
    if (m.entry_count > kCapacity || m.entry_index >= kCapacity) {
      stage_too_long_ = true;
      return;
    }
    if (m.entry_index >= m.entry_count) {
      stage_inconsistent_ = true;
      return;
    }
    const std::size_t i = m.entry_index;
    std::uint32_t& word = stage_have_[i / 32];
    const std::uint32_t bit = 1u << (i % 32);
    if ((word & bit) == 0) ++stage_received_;
    word |= bit;
    staged_[i] = PlanEntry{m.t_open_s, m.t_close_s, m.valve};
  }

  // Checks the staged plan and stores it (Accepted), or changes nothing.
  PlanVerdict load(const CmdPlanMsg& m, const PlanLimits& lim) {
    if (state_ == PlanState::Running) return PlanVerdict::Running;
    if (m.entry_count > kCapacity || (staging_ && stage_too_long_ && m.plan_id == stage_id_))
      return PlanVerdict::TooLong;
    if (!staging_ || m.plan_id != stage_id_ || m.entry_count != stage_count_ || stage_inconsistent_ ||
        m.entry_count == 0 || stage_received_ != m.entry_count)
      return PlanVerdict::Incomplete;
    if (!(m.duration_s > 0.0) || !std::isfinite(m.duration_s)) return PlanVerdict::BadTimes;
    if (m.duration_s > lim.max_duration_s) return PlanVerdict::DurationTooLong;
    double total = 0.0;
    const PlanVerdict v = check_entries(m.entry_count, m.duration_s, lim, total);
    if (v != PlanVerdict::Accepted) return v;
    for (std::size_t i = 0; i < m.entry_count; ++i) entries_[i] = staged_[i];
    count_ = m.entry_count;
    id_ = m.plan_id;
    duration_s_ = m.duration_s;
    total_on_s_ = total;
    state_ = PlanState::Loaded;
    return PlanVerdict::Accepted;
  }

  // Runs the stored plan from t_start_s (its time zero).
  PlanVerdict start(std::uint32_t plan_id, double t_start_s) {
    if (state_ == PlanState::Running) return PlanVerdict::Running;
    if (state_ == PlanState::Empty || plan_id != id_) return PlanVerdict::NoPlan;
    state_ = PlanState::Running;
    t_start_s_ = t_start_s;
    return PlanVerdict::Accepted;
  }

  PlanVerdict abort() {
    if (state_ != PlanState::Running) return PlanVerdict::NotRunning;
    state_ = PlanState::Aborted;
    return PlanVerdict::Accepted;
  }

  // The command for the interval [t_s, t_s + dt_s) while the plan runs;
  // false before its start (time tag ahead) or when it does not run.
  bool command(double t_s, double dt_s, double tol_s, PlanCommand& out) const {
    if (state_ != PlanState::Running) return false;
    const double tau = t_s - t_start_s_;
    if (tau < -tol_s) return false;
    out = PlanCommand{};
    out.plan_time_s = tau;
    if (tau >= duration_s_ - tol_s) {
      out.state = PlanState::Finished;
      return true;
    }
    const double a = tau, b = tau + dt_s;
    for (std::size_t i = 0; i < count_; ++i) {
      const PlanEntry& e = entries_[i];
      const double on = std::fmin(b, e.t_close_s) - std::fmax(a, e.t_open_s);
      if (on <= kEdgeTolS) continue;
      out.on_time_s[e.valve] += on;
      out.valve_mask = static_cast<std::uint8_t>(out.valve_mask | (1u << e.valve));
    }
    for (std::size_t v = 0; v < kPlanValves; ++v) {
      if (out.on_time_s[v] > 0.0 && out.on_time_s[v] < dt_s - tol_s) out.full = false;
    }
    return true;
  }

  // The plan ended at the tick command() reported Finished.
  void finish() {
    if (state_ == PlanState::Running) state_ = PlanState::Finished;
  }

  PlanState state() const { return state_; }
  std::uint32_t id() const { return id_; }
  std::size_t size() const { return count_; }
  const PlanEntry& entry(std::size_t i) const { return entries_[i < kCapacity ? i : 0]; }
  double duration_s() const { return duration_s_; }
  double total_on_time_s() const { return total_on_s_; }
  double t_start_s() const { return t_start_s_; }
  std::uint32_t entries_received() const { return stage_received_; }

 private:
  PlanVerdict check_entries(std::size_t n, double duration_s, const PlanLimits& lim, double& total) const {
    std::array<double, kPlanValves> last_close{};
    for (auto& c : last_close) c = -1.0;
    double last_open = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const PlanEntry& e = staged_[i];
      if (e.valve >= lim.valves) return PlanVerdict::ValveOutOfRange;
      if (!std::isfinite(e.t_open_s) || !std::isfinite(e.t_close_s) || e.t_open_s < 0.0 ||
          !(e.t_close_s > e.t_open_s) || e.t_close_s > duration_s)
        return PlanVerdict::BadTimes;
      const double on = e.t_close_s - e.t_open_s;
      if (on + kEdgeTolS < lim.min_on_time_s) return PlanVerdict::OnTimeTooShort;
      if (on > lim.max_on_time_s + kEdgeTolS) return PlanVerdict::OnTimeTooLong;
      if (e.t_open_s < last_open || e.t_open_s < last_close[e.valve]) return PlanVerdict::Overlap;
      last_open = e.t_open_s;
      last_close[e.valve] = e.t_close_s;
      total += on;
    }
    if (total > lim.max_total_on_time_s + kEdgeTolS) return PlanVerdict::TotalOnTimeTooLong;
    return PlanVerdict::Accepted;
  }

  // Staging: the plan being uplinked.
  std::array<PlanEntry, kCapacity> staged_{};
  std::array<std::uint32_t, (kCapacity + 31) / 32> stage_have_{};
  std::uint32_t stage_id_ = 0;
  std::uint32_t stage_count_ = 0;
  std::uint32_t stage_received_ = 0;
  bool staging_ = false;
  bool stage_too_long_ = false;
  bool stage_inconsistent_ = false;
  // The stored plan.
  std::array<PlanEntry, kCapacity> entries_{};
  std::size_t count_ = 0;
  std::uint32_t id_ = 0;
  double duration_s_ = 0.0;
  double total_on_s_ = 0.0;
  double t_start_s_ = 0.0;
  PlanState state_ = PlanState::Empty;
};

}  // namespace fsw
