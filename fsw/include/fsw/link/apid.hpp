// The link's message dictionary: every APID, its direction, its exact payload
// length and layout, and typed encoders/decoders. Payload fields are
// little-endian; floating-point fields are IEEE-754 doubles on the wire and
// are converted to the flight scalar S (float or double) by the decoders.
// docs/LINK.md is the human-readable copy of this table; keep both in step.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fsw/link/space_packet.hpp"
#include "fsw/math/so3.hpp"

namespace fsw {

// Direction of travel. Bench -> flight packets are telecommands (type 1),
// flight -> bench packets are telemetry (type 0).
enum class Direction : std::uint8_t { ToFlight = 1, FromFlight = 0 };

constexpr PacketType packet_type_of(Direction d) {
  return d == Direction::ToFlight ? PacketType::Telecommand : PacketType::Telemetry;
}

enum class Apid : std::uint16_t {
  ImuSample = 0x010,          // to flight, 10 Hz
  LedPose = 0x011,            // to flight, 1 Hz, time tag = capture time
  ThrusterValves = 0x012,     // to flight, valve states over one firing interval
  RangeImageSegment = 0x013,  // to flight, segmented (first/continuation/last)
  CmdReset = 0x020,           // to flight
  CmdConfig = 0x021,          // to flight
  CmdPlanEntry = 0x022,       // to flight: one valve opening of a stored valve plan
  CmdPlan = 0x023,            // to flight: load (check and store), start or abort the valve plan
  TmEstimate = 0x040,         // from flight
  TmCovarianceDiag = 0x041,   // from flight
  TmInnovation = 0x042,       // from flight: innovation, NIS, log-likelihood, step status
  TmLearner = 0x043,          // from flight
  TmLinkCounters = 0x044,     // from flight
  TmHousekeeping = 0x045,     // from flight
  TmModal = 0x046,            // from flight: one modal filter step per range image
  TmPlanStatus = 0x047,       // from flight: the valve plan's state, answer to every cmd_plan
  TmPlanValves = 0x048,       // from flight: the plan's valve command for one control interval
};

// One row of the table. The floating-point fields of each payload form one
// contiguous run of doubles [f64_offset, f64_offset + 8 * f64_count), all of
// which must be finite; quat_offset (or -1) locates a [w, x, y, z] quaternion
// inside that run that must have unit norm.
struct ApidInfo {
  Apid apid;
  const char* name;
  Direction direction;
  std::uint16_t payload_len;
  bool segmentable;
  std::uint16_t f64_offset;
  std::uint16_t f64_count;
  std::int16_t quat_offset;
};

constexpr std::size_t kRangePointsPerSegment = 24;
constexpr std::size_t kRangePointBytes = 32;  // p_m[3], sigma_m
constexpr std::size_t kRangeSegmentHeaderBytes = 12;
constexpr std::uint16_t kMaxRangePointsPerImage = 4096;
constexpr std::size_t kCovDiagMax = 15;
constexpr std::size_t kLinkCounterSlots = 28;
constexpr std::size_t kModalTmModes = 10;     // modes carried by tm_modal
constexpr double kQuatNormTol = 1e-6;         // |‖q‖ - 1| allowed on the wire
constexpr std::size_t kPlanValves = 8;        // valves a plan command carries (tm_plan_valves)
constexpr std::uint8_t kPlanStateMax = 4;     // PlanState (fsw/app/valve_plan.hpp)
constexpr std::uint8_t kPlanVerdictMax = 13;  // PlanVerdict (fsw/app/valve_plan.hpp)

inline constexpr std::array<ApidInfo, 17> kApidTable{{
    {Apid::ImuSample, "imu_sample", Direction::ToFlight, 48, false, 0, 6, -1},
    {Apid::LedPose, "led_pose", Direction::ToFlight, 72, false, 0, 9, 24},
    {Apid::ThrusterValves, "thruster_valves", Direction::ToFlight, 16, false, 0, 1, -1},
    {Apid::RangeImageSegment, "range_image_segment", Direction::ToFlight,
     static_cast<std::uint16_t>(kRangeSegmentHeaderBytes + kRangePointsPerSegment * kRangePointBytes), true, 12,
     static_cast<std::uint16_t>(kRangePointsPerSegment * 4), -1},
    {Apid::CmdReset, "cmd_reset", Direction::ToFlight, 112, false, 8, 13, 56},
    {Apid::CmdConfig, "cmd_config", Direction::ToFlight, 16, false, 8, 1, -1},
    {Apid::CmdPlanEntry, "cmd_plan_entry", Direction::ToFlight, 32, false, 16, 2, -1},
    {Apid::CmdPlan, "cmd_plan", Direction::ToFlight, 24, false, 16, 1, -1},
    {Apid::TmEstimate, "tm_estimate", Direction::FromFlight, 80, false, 0, 10, 48},
    {Apid::TmCovarianceDiag, "tm_covariance_diag", Direction::FromFlight, 128, false, 8, 15, -1},
    {Apid::TmInnovation, "tm_innovation", Direction::FromFlight, 72, false, 8, 8, -1},
    {Apid::TmLearner, "tm_learner", Direction::FromFlight, 104, false, 8, 12, -1},
    {Apid::TmLinkCounters, "tm_link_counters", Direction::FromFlight, 128, false, 0, 0, -1},
    {Apid::TmHousekeeping, "tm_housekeeping", Direction::FromFlight, 40, false, 0, 3, -1},
    {Apid::TmModal, "tm_modal", Direction::FromFlight, 352, false, 16, 42, -1},
    {Apid::TmPlanStatus, "tm_plan_status", Direction::FromFlight, 40, false, 24, 2, -1},
    {Apid::TmPlanValves, "tm_plan_valves", Direction::FromFlight, 88, false, 8, 10, -1},
}};

constexpr std::size_t kApidCount = kApidTable.size();

// Row index of an APID, or -1 if unknown.
constexpr int apid_index(std::uint16_t apid) {
  for (std::size_t i = 0; i < kApidTable.size(); ++i) {
    if (static_cast<std::uint16_t>(kApidTable[i].apid) == apid) return static_cast<int>(i);
  }
  return -1;
}
constexpr const ApidInfo* apid_info(std::uint16_t apid) {
  const int i = apid_index(apid);
  return i < 0 ? nullptr : &kApidTable[static_cast<std::size_t>(i)];
}

constexpr std::size_t max_payload_len() {
  std::size_t m = 0;
  for (const auto& r : kApidTable) m = r.payload_len > m ? r.payload_len : m;
  return m;
}
constexpr std::size_t kMaxPayloadLen = max_payload_len();
constexpr std::size_t kMaxPacketLen = kPacketHeaderSize + kMaxPayloadLen;  // without CRC
constexpr std::size_t kCrcSize = 2;

namespace apid_detail {
constexpr bool table_is_consistent() {
  for (std::size_t i = 0; i < kApidTable.size(); ++i) {
    const auto& r = kApidTable[i];
    if (static_cast<std::uint16_t>(r.apid) > kMaxApid || static_cast<std::uint16_t>(r.apid) == kIdleApid) return false;
    if (r.f64_offset + 8u * r.f64_count > r.payload_len) return false;
    if (r.quat_offset >= 0 && (r.quat_offset < r.f64_offset || r.quat_offset + 32 > r.f64_offset + 8 * r.f64_count))
      return false;
    for (std::size_t j = i + 1; j < kApidTable.size(); ++j)
      if (kApidTable[j].apid == r.apid) return false;
  }
  return true;
}
}  // namespace apid_detail
static_assert(apid_detail::table_is_consistent(), "APID table: offsets, ranges or duplicates");
static_assert(kMaxPacketLen == 794, "largest packet (range image segment) changed: update docs/LINK.md");

// Integer fields and ranges a payload must respect beyond finiteness
// (deframer step 10, InvalidField). The payload has the table length.
inline bool payload_fields_valid(Apid apid, SeqFlags flags, const std::uint8_t* p) {
  switch (apid) {
    case Apid::LedPose: return get_f64le(p + 56) >= 0.0 && get_f64le(p + 64) >= 0.0;
    case Apid::ThrusterValves: return get_f64le(p) >= 0.0;
    case Apid::RangeImageSegment: {
      const std::uint32_t total = get_u16le(p + 4);
      const std::uint32_t first = get_u16le(p + 6);
      const std::uint32_t n = get_u16le(p + 8);
      if (total == 0 || total > kMaxRangePointsPerImage || n > kRangePointsPerSegment) return false;
      if (first + n > total) return false;
      // The sequence flags must agree with where the segment sits in the image.
      const bool starts = first == 0;
      const bool ends = first + n == total;
      switch (flags) {
        case SeqFlags::Unsegmented:
          if (!(starts && ends)) return false;
          break;
        case SeqFlags::First:
          if (!(starts && !ends)) return false;
          break;
        case SeqFlags::Continuation:
          if (starts || ends) return false;
          break;
        case SeqFlags::Last:
          if (starts || !ends) return false;
          break;
      }
      for (std::uint32_t i = 0; i < n; ++i) {
        if (!(get_f64le(p + kRangeSegmentHeaderBytes + i * kRangePointBytes + 24) >= 0.0)) return false;
      }
      return true;
    }
    case Apid::CmdReset: return get_f64le(p + 88) >= 0.0 && get_f64le(p + 96) >= 0.0 && get_f64le(p + 104) >= 0.0;
    case Apid::TmCovarianceDiag: return get_u32le(p) <= kCovDiagMax;
    case Apid::TmInnovation: return p[1] <= 3 && p[3] <= 6;
    case Apid::TmModal: return p[4] <= 3 && p[5] <= 3 && p[7] <= kModalTmModes;
    case Apid::TmPlanStatus: return p[4] <= kPlanStateMax && p[6] <= kPlanVerdictMax;
    case Apid::TmPlanValves: return p[5] <= kPlanStateMax;
    default: return true;
  }
}

// ---------------------------------------------------------------------------
// Typed messages. Field names carry frame and unit; every message has the
// time tag t_s of its packet.

template <typename S>
struct ImuSampleMsg {
  S t_s{};
  Vec3<S> accel_b_mps2 = Vec3<S>::Zero();
  Vec3<S> omega_bi_b_rps = Vec3<S>::Zero();
};
template <typename S>
struct LedPoseMsg {
  S t_s{};  // capture time
  Vec3<S> r_hill_m = Vec3<S>::Zero();
  Quat<S> q_hb = Quat<S>::Identity();  // body -> Hill
  S r_sigma_m{};                       // 1-sigma per axis, 0 = use the configured model
  S att_sigma_rad{};                   // 1-sigma per axis, 0 = use the configured model
};
template <typename S>
struct ThrusterValvesMsg {
  S t_s{};                      // start of the firing interval
  S interval_s{};               // length of the firing interval
  std::uint8_t valve_mask = 0;  // bit i = thruster i open
};
template <typename S>
struct RangePoint {
  Vec3<S> p_m = Vec3<S>::Zero();  // measured point, structure frame
  S sigma_m{};                    // 1-sigma range noise of this point
};
template <typename S>
struct RangeImageSegmentMsg {
  S t_s{};
  SeqFlags seq_flags = SeqFlags::Unsegmented;
  std::uint32_t image_id = 0;
  std::uint16_t points_total = 0;  // points in the whole image
  std::uint16_t first_point = 0;   // index of points[0] in the image
  std::uint16_t n_points = 0;      // valid entries of points
  std::array<RangePoint<S>, kRangePointsPerSegment> points{};
};
template <typename S>
struct CmdResetMsg {
  S t_s{};
  std::uint32_t target_mask = 0;  // bit 0 nav, 1 learner, 2 modal, 3 link counters
  Vec3<S> r_hill_m = Vec3<S>::Zero();
  Vec3<S> v_hill_mps = Vec3<S>::Zero();
  Quat<S> q_hb = Quat<S>::Identity();
  S pos_sigma_m{};
  S vel_sigma_mps{};
  S att_sigma_rad{};
};
template <typename S>
struct CmdConfigMsg {
  S t_s{};
  std::uint32_t param_id = 0;
  S value{};
};
// The valve plan's messages keep their times in double in both builds: a
// plan's open and close times are mission times, as the packet time tags.
struct CmdPlanEntryMsg {
  double t_s = 0.0;
  std::uint32_t plan_id = 0;
  std::uint16_t entry_index = 0;  // 0 .. entry_count - 1
  std::uint16_t entry_count = 0;  // entries in the whole plan
  std::uint8_t valve = 0;         // valve index (bit of thruster_valves' mask)
  double t_open_s = 0.0;          // from the plan's start [s]
  double t_close_s = 0.0;         // from the plan's start [s]
};
enum class PlanAction : std::uint32_t { Load = 1, Start = 2, Abort = 3 };
struct CmdPlanMsg {
  double t_s = 0.0;          // start: the plan's time zero
  std::uint32_t action = 0;  // PlanAction
  std::uint32_t plan_id = 0;
  std::uint32_t entry_count = 0;  // load: entries the plan holds
  double duration_s = 0.0;        // load: the plan's length, its last coast included [s]
};
struct TmPlanStatusMsg {
  double t_s = 0.0;
  std::uint32_t plan_id = 0;           // the stored plan (0: none)
  std::uint8_t state = 0;              // PlanState
  std::uint8_t action = 0;             // the cmd_plan answered (0: none, the plan ended)
  std::uint8_t verdict = 0;            // PlanVerdict: 0 accepted, else why refused
  std::uint32_t entry_count = 0;       // entries of the stored plan
  std::uint32_t entries_received = 0;  // distinct entries of the plan being uplinked
  std::uint32_t plans_loaded = 0;
  std::uint32_t commands_refused = 0;  // cmd_plan refused since start
  double duration_s = 0.0;             // of the stored plan
  double total_on_time_s = 0.0;        // of the stored plan
};
struct TmPlanValvesMsg {
  double t_s = 0.0;  // start of the control interval
  std::uint32_t plan_id = 0;
  std::uint8_t valve_mask = 0;  // valves open at some time in the interval
  std::uint8_t state = 0;       // PlanState: running, or finished / aborted (all closed)
  double interval_s = 0.0;
  double plan_time_s = 0.0;                     // the interval's start from the plan's start
  std::array<double, kPlanValves> on_time_s{};  // each valve's open time within the interval
};

template <typename S>
struct TmEstimateMsg {
  S t_s{};
  Vec3<S> r_hill_m = Vec3<S>::Zero();
  Vec3<S> v_hill_mps = Vec3<S>::Zero();
  Quat<S> q_hb = Quat<S>::Identity();
};
template <typename S>
struct TmCovarianceDiagMsg {
  S t_s{};
  std::uint32_t n_valid = 0;
  Eigen::Matrix<S, kCovDiagMax, 1> p_diag = Eigen::Matrix<S, kCovDiagMax, 1>::Zero();
};
template <typename S>
struct TmInnovationMsg {
  S t_s{};
  std::uint8_t step_kind = 0;  // 0 predict, 1 pose update
  std::uint8_t status = 0;     // 0 ok, 1 gated, 2 not positive definite, 3 bad input
  std::uint8_t fused = 0;
  std::uint8_t meas_dim = 0;  // valid entries of innovation
  std::uint32_t step_index = 0;
  Eigen::Matrix<S, 6, 1> innovation = Eigen::Matrix<S, 6, 1>::Zero();
  S nis{};
  S log_likelihood{};
};
template <typename S>
struct TmLearnerMsg {
  S t_s{};
  std::uint32_t n_samples = 0;
  std::uint32_t status = 0;
  Vec3<S> dv_b_mps = Vec3<S>::Zero();
  Vec3<S> dw_b_rps = Vec3<S>::Zero();
  Eigen::Matrix<S, 6, 1> variance = Eigen::Matrix<S, 6, 1>::Zero();
};
struct TmLinkCountersMsg {
  double t_s = 0.0;
  std::uint32_t packets_accepted = 0;
  std::uint32_t frames_total = 0;
  std::uint32_t seq_gaps_total = 0;
  std::uint32_t duplicates_total = 0;
  std::array<std::uint32_t, kLinkCounterSlots> rejected{};  // index = RejectReason value
};
template <typename S>
struct TmHousekeepingMsg {
  S t_s{};
  S uptime_s{};
  S last_step_cpu_s{};
  S max_step_cpu_s{};
  std::uint32_t cycle_count = 0;
  std::uint32_t mode = 0;
  std::uint32_t tx_packets = 0;
  std::uint32_t tx_dropped = 0;  // telemetry packets lost to a full transmit buffer
};
template <typename S>
struct TmModalMsg {
  S t_s{};  // image time
  std::uint32_t image_id = 0;
  std::uint8_t status = 0;         // StepStatus of the filter step
  std::uint8_t decomposition = 0;  // ModalStatus of the image's decomposition
  std::uint8_t fused = 0;
  std::uint8_t n_modes = 0;     // valid entries of the arrays (<= kModalTmModes)
  std::uint32_t n_used = 0;     // points in the decomposition
  std::uint32_t n_skipped = 0;  // points skipped: off the model, not finite, bad sigma
  S rcond{};                    // 1 / cond(M_Y) (0 when not computed or singular)
  S nis{};                      // sum of the per-mode NIS
  Eigen::Matrix<S, kModalTmModes, 1> omega_radps = Eigen::Matrix<S, kModalTmModes, 1>::Zero();
  Eigen::Matrix<S, kModalTmModes, 1> alpha_ps = Eigen::Matrix<S, kModalTmModes, 1>::Zero();
  Eigen::Matrix<S, kModalTmModes, 1> amplitude = Eigen::Matrix<S, kModalTmModes, 1>::Zero();
  Eigen::Matrix<S, kModalTmModes, 1> amplitude_sigma = Eigen::Matrix<S, kModalTmModes, 1>::Zero();
};

// ---------------------------------------------------------------------------
// Field access. Decoders check that each converted value is finite in S (a
// finite double can overflow a float) and return false otherwise; encoders
// write exactly info.payload_len bytes (the payload buffer must hold it).

namespace payload_detail {
template <typename S>
inline bool rd(const std::uint8_t* p, std::size_t off, S& out) {
  out = static_cast<S>(get_f64le(p + off));
  return std::isfinite(out);
}
template <typename S, int N>
inline bool rd(const std::uint8_t* p, std::size_t off, Eigen::Matrix<S, N, 1>& v) {
  bool ok = true;
  for (int i = 0; i < N; ++i) ok = rd(p, off + 8 * static_cast<std::size_t>(i), v(i)) && ok;
  return ok;
}
template <typename S>
inline bool rdq(const std::uint8_t* p, std::size_t off, Quat<S>& q) {
  Vec4<S> wxyz;
  const bool ok = rd(p, off, wxyz);
  q = from_wxyz(wxyz);
  return ok;
}
template <typename S>
inline void wr(std::uint8_t* p, std::size_t off, S x) {
  put_f64le(p + off, static_cast<double>(x));
}
template <typename S, int N>
inline void wr(std::uint8_t* p, std::size_t off, const Eigen::Matrix<S, N, 1>& v) {
  for (int i = 0; i < N; ++i) wr(p, off + 8 * static_cast<std::size_t>(i), v(i));
}
template <typename S>
inline void wrq(std::uint8_t* p, std::size_t off, const Quat<S>& q) {
  wr<S, 4>(p, off, to_wxyz(q));
}
inline void zero(std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) p[i] = 0;
}
}  // namespace payload_detail

// Each decode_x(payload, t_s, msg) reads a payload of exactly the table length
// (the deframer has checked it). Each encode_x(msg, payload) fills it.

template <typename S>
bool decode(const std::uint8_t* p, double t_s, ImuSampleMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  return rd(p, 0, m.accel_b_mps2) & rd(p, 24, m.omega_bi_b_rps) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const ImuSampleMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  wr(p, 0, m.accel_b_mps2);
  wr(p, 24, m.omega_bi_b_rps);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, LedPoseMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  return rd(p, 0, m.r_hill_m) & rdq(p, 24, m.q_hb) & rd(p, 56, m.r_sigma_m) & rd(p, 64, m.att_sigma_rad) &
         std::isfinite(m.t_s);
}
template <typename S>
void encode(const LedPoseMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  wr(p, 0, m.r_hill_m);
  wrq(p, 24, m.q_hb);
  wr(p, 56, m.r_sigma_m);
  wr(p, 64, m.att_sigma_rad);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, ThrusterValvesMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.valve_mask = p[8];
  return rd(p, 0, m.interval_s) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const ThrusterValvesMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  zero(p, 16);
  wr(p, 0, m.interval_s);
  p[8] = m.valve_mask;
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, SeqFlags flags, RangeImageSegmentMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.seq_flags = flags;
  m.image_id = get_u32le(p);
  m.points_total = get_u16le(p + 4);
  m.first_point = get_u16le(p + 6);
  m.n_points = get_u16le(p + 8);
  bool ok = std::isfinite(m.t_s) && m.n_points <= kRangePointsPerSegment;
  for (std::size_t i = 0; i < kRangePointsPerSegment; ++i) {
    const std::size_t off = kRangeSegmentHeaderBytes + i * kRangePointBytes;
    ok = rd(p, off, m.points[i].p_m) & rd(p, off + 24, m.points[i].sigma_m) & ok;
  }
  return ok;
}
template <typename S>
void encode(const RangeImageSegmentMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  zero(p, kRangeSegmentHeaderBytes + kRangePointsPerSegment * kRangePointBytes);
  put_u32le(p, m.image_id);
  put_u16le(p + 4, m.points_total);
  put_u16le(p + 6, m.first_point);
  put_u16le(p + 8, m.n_points);
  for (std::size_t i = 0; i < kRangePointsPerSegment && i < m.n_points; ++i) {
    const std::size_t off = kRangeSegmentHeaderBytes + i * kRangePointBytes;
    wr(p, off, m.points[i].p_m);
    wr(p, off + 24, m.points[i].sigma_m);
  }
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, CmdResetMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.target_mask = get_u32le(p);
  return rd(p, 8, m.r_hill_m) & rd(p, 32, m.v_hill_mps) & rdq(p, 56, m.q_hb) & rd(p, 88, m.pos_sigma_m) &
         rd(p, 96, m.vel_sigma_mps) & rd(p, 104, m.att_sigma_rad) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const CmdResetMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  zero(p, 8);
  put_u32le(p, m.target_mask);
  wr(p, 8, m.r_hill_m);
  wr(p, 32, m.v_hill_mps);
  wrq(p, 56, m.q_hb);
  wr(p, 88, m.pos_sigma_m);
  wr(p, 96, m.vel_sigma_mps);
  wr(p, 104, m.att_sigma_rad);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, CmdConfigMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.param_id = get_u32le(p);
  return rd(p, 8, m.value) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const CmdConfigMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  zero(p, 8);
  put_u32le(p, m.param_id);
  wr(p, 8, m.value);
}

inline bool decode(const std::uint8_t* p, double t_s, CmdPlanEntryMsg& m) {
  m.t_s = t_s;
  m.plan_id = get_u32le(p);
  m.entry_index = get_u16le(p + 4);
  m.entry_count = get_u16le(p + 6);
  m.valve = p[8];
  m.t_open_s = get_f64le(p + 16);
  m.t_close_s = get_f64le(p + 24);
  return std::isfinite(t_s) && std::isfinite(m.t_open_s) && std::isfinite(m.t_close_s);
}
inline void encode(const CmdPlanEntryMsg& m, std::uint8_t* p) {
  payload_detail::zero(p, 16);
  put_u32le(p, m.plan_id);
  put_u16le(p + 4, m.entry_index);
  put_u16le(p + 6, m.entry_count);
  p[8] = m.valve;
  put_f64le(p + 16, m.t_open_s);
  put_f64le(p + 24, m.t_close_s);
}

inline bool decode(const std::uint8_t* p, double t_s, CmdPlanMsg& m) {
  m.t_s = t_s;
  m.action = get_u32le(p);
  m.plan_id = get_u32le(p + 4);
  m.entry_count = get_u32le(p + 8);
  m.duration_s = get_f64le(p + 16);
  return std::isfinite(t_s) && std::isfinite(m.duration_s);
}
inline void encode(const CmdPlanMsg& m, std::uint8_t* p) {
  payload_detail::zero(p, 16);
  put_u32le(p, m.action);
  put_u32le(p + 4, m.plan_id);
  put_u32le(p + 8, m.entry_count);
  put_f64le(p + 16, m.duration_s);
}

inline bool decode(const std::uint8_t* p, double t_s, TmPlanStatusMsg& m) {
  m.t_s = t_s;
  m.plan_id = get_u32le(p);
  m.state = p[4];
  m.action = p[5];
  m.verdict = p[6];
  m.entry_count = get_u32le(p + 8);
  m.entries_received = get_u32le(p + 12);
  m.plans_loaded = get_u32le(p + 16);
  m.commands_refused = get_u32le(p + 20);
  m.duration_s = get_f64le(p + 24);
  m.total_on_time_s = get_f64le(p + 32);
  return std::isfinite(t_s) && std::isfinite(m.duration_s) && std::isfinite(m.total_on_time_s);
}
inline void encode(const TmPlanStatusMsg& m, std::uint8_t* p) {
  put_u32le(p, m.plan_id);
  p[4] = m.state;
  p[5] = m.action;
  p[6] = m.verdict;
  p[7] = 0;
  put_u32le(p + 8, m.entry_count);
  put_u32le(p + 12, m.entries_received);
  put_u32le(p + 16, m.plans_loaded);
  put_u32le(p + 20, m.commands_refused);
  put_f64le(p + 24, m.duration_s);
  put_f64le(p + 32, m.total_on_time_s);
}

inline bool decode(const std::uint8_t* p, double t_s, TmPlanValvesMsg& m) {
  m.t_s = t_s;
  m.plan_id = get_u32le(p);
  m.valve_mask = p[4];
  m.state = p[5];
  m.interval_s = get_f64le(p + 8);
  m.plan_time_s = get_f64le(p + 16);
  bool ok = std::isfinite(t_s) && std::isfinite(m.interval_s) && std::isfinite(m.plan_time_s);
  for (std::size_t i = 0; i < kPlanValves; ++i) {
    m.on_time_s[i] = get_f64le(p + 24 + 8 * i);
    ok = ok && std::isfinite(m.on_time_s[i]);
  }
  return ok;
}
inline void encode(const TmPlanValvesMsg& m, std::uint8_t* p) {
  put_u32le(p, m.plan_id);
  p[4] = m.valve_mask;
  p[5] = m.state;
  put_u16le(p + 6, 0);
  put_f64le(p + 8, m.interval_s);
  put_f64le(p + 16, m.plan_time_s);
  for (std::size_t i = 0; i < kPlanValves; ++i) put_f64le(p + 24 + 8 * i, m.on_time_s[i]);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmEstimateMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  return rd(p, 0, m.r_hill_m) & rd(p, 24, m.v_hill_mps) & rdq(p, 48, m.q_hb) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmEstimateMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  wr(p, 0, m.r_hill_m);
  wr(p, 24, m.v_hill_mps);
  wrq(p, 48, m.q_hb);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmCovarianceDiagMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.n_valid = get_u32le(p);
  return rd(p, 8, m.p_diag) & (m.n_valid <= kCovDiagMax) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmCovarianceDiagMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  zero(p, 8);
  put_u32le(p, m.n_valid);
  wr(p, 8, m.p_diag);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmInnovationMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.step_kind = p[0];
  m.status = p[1];
  m.fused = p[2];
  m.meas_dim = p[3];
  m.step_index = get_u32le(p + 4);
  return rd(p, 8, m.innovation) & rd(p, 56, m.nis) & rd(p, 64, m.log_likelihood) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmInnovationMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  p[0] = m.step_kind;
  p[1] = m.status;
  p[2] = m.fused;
  p[3] = m.meas_dim;
  put_u32le(p + 4, m.step_index);
  wr(p, 8, m.innovation);
  wr(p, 56, m.nis);
  wr(p, 64, m.log_likelihood);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmLearnerMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.n_samples = get_u32le(p);
  m.status = get_u32le(p + 4);
  return rd(p, 8, m.dv_b_mps) & rd(p, 32, m.dw_b_rps) & rd(p, 56, m.variance) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmLearnerMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  put_u32le(p, m.n_samples);
  put_u32le(p + 4, m.status);
  wr(p, 8, m.dv_b_mps);
  wr(p, 32, m.dw_b_rps);
  wr(p, 56, m.variance);
}

inline bool decode(const std::uint8_t* p, double t_s, TmLinkCountersMsg& m) {
  m.t_s = t_s;
  m.packets_accepted = get_u32le(p);
  m.frames_total = get_u32le(p + 4);
  m.seq_gaps_total = get_u32le(p + 8);
  m.duplicates_total = get_u32le(p + 12);
  for (std::size_t i = 0; i < kLinkCounterSlots; ++i) m.rejected[i] = get_u32le(p + 16 + 4 * i);
  return std::isfinite(t_s);
}
inline void encode(const TmLinkCountersMsg& m, std::uint8_t* p) {
  put_u32le(p, m.packets_accepted);
  put_u32le(p + 4, m.frames_total);
  put_u32le(p + 8, m.seq_gaps_total);
  put_u32le(p + 12, m.duplicates_total);
  for (std::size_t i = 0; i < kLinkCounterSlots; ++i) put_u32le(p + 16 + 4 * i, m.rejected[i]);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmHousekeepingMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.cycle_count = get_u32le(p + 24);
  m.mode = get_u32le(p + 28);
  m.tx_packets = get_u32le(p + 32);
  m.tx_dropped = get_u32le(p + 36);
  return rd(p, 0, m.uptime_s) & rd(p, 8, m.last_step_cpu_s) & rd(p, 16, m.max_step_cpu_s) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmHousekeepingMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  wr(p, 0, m.uptime_s);
  wr(p, 8, m.last_step_cpu_s);
  wr(p, 16, m.max_step_cpu_s);
  put_u32le(p + 24, m.cycle_count);
  put_u32le(p + 28, m.mode);
  put_u32le(p + 32, m.tx_packets);
  put_u32le(p + 36, m.tx_dropped);
}

template <typename S>
bool decode(const std::uint8_t* p, double t_s, TmModalMsg<S>& m) {
  using namespace payload_detail;
  m.t_s = static_cast<S>(t_s);
  m.image_id = get_u32le(p);
  m.status = p[4];
  m.decomposition = p[5];
  m.fused = p[6];
  m.n_modes = p[7];
  m.n_used = get_u32le(p + 8);
  m.n_skipped = get_u32le(p + 12);
  return rd(p, 16, m.rcond) & rd(p, 24, m.nis) & rd(p, 32, m.omega_radps) & rd(p, 112, m.alpha_ps) &
         rd(p, 192, m.amplitude) & rd(p, 272, m.amplitude_sigma) & std::isfinite(m.t_s);
}
template <typename S>
void encode(const TmModalMsg<S>& m, std::uint8_t* p) {
  using namespace payload_detail;
  put_u32le(p, m.image_id);
  p[4] = m.status;
  p[5] = m.decomposition;
  p[6] = m.fused;
  p[7] = m.n_modes;
  put_u32le(p + 8, m.n_used);
  put_u32le(p + 12, m.n_skipped);
  wr(p, 16, m.rcond);
  wr(p, 24, m.nis);
  wr(p, 32, m.omega_radps);
  wr(p, 112, m.alpha_ps);
  wr(p, 192, m.amplitude);
  wr(p, 272, m.amplitude_sigma);
}

}  // namespace fsw
