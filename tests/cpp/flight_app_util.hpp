// Helpers for the flight-app tests: a bench-side framer and a telemetry
// collector built from the same link code the bench cross-checks in Python.
#pragma once

#include <algorithm>
#include <vector>

#include "fsw/app/flight_app.hpp"
#include "fsw/link/apid.hpp"
#include "fsw/link/deframer.hpp"
#include "fsw/link/framer.hpp"

namespace flight_app_test {

using namespace fsw;

struct Uplink {
  Framer framer{Direction::ToFlight};
  std::vector<std::uint8_t> bytes;

  template <typename Msg>
  void add(Apid apid, const Msg& m, double t_s) {
    std::uint8_t buf[kMaxFrameBytes];
    const std::size_t n = framer.frame_message(apid, m, t_s, buf, sizeof(buf));
    bytes.insert(bytes.end(), buf, buf + n);
  }
  void reset(double t, const Vec3<double>& r, const Vec3<double>& v, const Quat<double>& q) {
    CmdResetMsg<double> m;
    m.target_mask = 1;
    m.r_hill_m = r;
    m.v_hill_mps = v;
    m.q_hb = q;
    m.pos_sigma_m = 0.05;
    m.vel_sigma_mps = 0.01;
    m.att_sigma_rad = 0.05;
    add(Apid::CmdReset, m, t);
  }
  void imu(double t, const Vec3<double>& a, const Vec3<double>& w) {
    ImuSampleMsg<double> m;
    m.accel_b_mps2 = a;
    m.omega_bi_b_rps = w;
    add(Apid::ImuSample, m, t);
  }
  void valves(double t, double interval_s, std::uint8_t mask) {
    ThrusterValvesMsg<double> m;
    m.t_s = t;
    m.interval_s = interval_s;
    m.valve_mask = mask;
    add(Apid::ThrusterValves, m, t);
  }
  void config(double t, ConfigParam id, double value) {
    CmdConfigMsg<double> m;
    m.param_id = static_cast<std::uint32_t>(id);
    m.value = value;
    add(Apid::CmdConfig, m, t);
  }
  // One range image as segments of 24 points (first / continuation / last,
  // or unsegmented), skipping the segments listed in drop.
  void range_image(double t, std::uint32_t image_id, const std::vector<Vec3<double>>& p_m,
                   const std::vector<double>& sigma_m, const std::vector<int>& drop = {}) {
    const std::size_t total = p_m.size();
    const std::size_t n_seg = (total + kRangePointsPerSegment - 1) / kRangePointsPerSegment;
    for (std::size_t s = 0; s < n_seg; ++s) {
      RangeImageSegmentMsg<double> m;
      m.image_id = image_id;
      m.points_total = static_cast<std::uint16_t>(total);
      m.first_point = static_cast<std::uint16_t>(s * kRangePointsPerSegment);
      const std::size_t n = std::min(kRangePointsPerSegment, total - s * kRangePointsPerSegment);
      m.n_points = static_cast<std::uint16_t>(n);
      for (std::size_t k = 0; k < n; ++k) {
        m.points[k].p_m = p_m[s * kRangePointsPerSegment + k];
        m.points[k].sigma_m = sigma_m[s * kRangePointsPerSegment + k];
      }
      const bool first = s == 0, last = s + 1 == n_seg;
      const SeqFlags f = first && last ? SeqFlags::Unsegmented
                         : first       ? SeqFlags::First
                         : last        ? SeqFlags::Last
                                       : SeqFlags::Continuation;
      if (std::find(drop.begin(), drop.end(), int(s)) != drop.end()) {
        framer.set_next_seq(Apid::RangeImageSegment, framer.next_seq(Apid::RangeImageSegment) + 1);
        continue;  // lost on the link (its sequence count is skipped)
      }
      std::uint8_t buf[kMaxFrameBytes];
      const std::size_t nb = framer.frame_message(Apid::RangeImageSegment, m, t, buf, sizeof(buf), f);
      bytes.insert(bytes.end(), buf, buf + nb);
    }
  }
  void pose(double t_capture, const Vec3<double>& r, const Quat<double>& q, double r_sigma, double a_sigma) {
    LedPoseMsg<double> m;
    m.r_hill_m = r;
    m.q_hb = q;
    m.r_sigma_m = r_sigma;
    m.att_sigma_rad = a_sigma;
    add(Apid::LedPose, m, t_capture);
  }
};

struct Telemetry {
  Deframer deframer{Direction::FromFlight};
  std::vector<TmEstimateMsg<double>> estimates;
  std::vector<TmInnovationMsg<double>> innovations;
  std::vector<TmCovarianceDiagMsg<double>> covariances;
  std::vector<TmLearnerMsg<double>> learner;
  std::vector<TmModalMsg<double>> modal;
  std::vector<TmHousekeepingMsg<double>> housekeeping;
  int link_counters = 0;
  int rejected = 0;

  void feed(const std::uint8_t* data, std::size_t n) {
    std::size_t used = 0;
    while (used < n) {
      DeframeResult r;
      used += deframer.feed(data + used, n - used, r);
      if (r.kind == DeframeResult::Kind::Rejected) ++rejected;
      if (r.kind != DeframeResult::Kind::Packet) continue;
      const PacketView& p = r.packet;
      switch (static_cast<Apid>(p.header.apid)) {
        case Apid::TmEstimate: {
          TmEstimateMsg<double> m;
          decode(p.payload, p.t_s, m);
          estimates.push_back(m);
          break;
        }
        case Apid::TmInnovation: {
          TmInnovationMsg<double> m;
          decode(p.payload, p.t_s, m);
          innovations.push_back(m);
          break;
        }
        case Apid::TmCovarianceDiag: {
          TmCovarianceDiagMsg<double> m;
          decode(p.payload, p.t_s, m);
          covariances.push_back(m);
          break;
        }
        case Apid::TmLearner: {
          TmLearnerMsg<double> m;
          decode(p.payload, p.t_s, m);
          learner.push_back(m);
          break;
        }
        case Apid::TmModal: {
          TmModalMsg<double> m;
          decode(p.payload, p.t_s, m);
          modal.push_back(m);
          break;
        }
        case Apid::TmHousekeeping: {
          TmHousekeepingMsg<double> m;
          decode(p.payload, p.t_s, m);
          housekeeping.push_back(m);
          break;
        }
        case Apid::TmLinkCounters: ++link_counters; break;
        default: break;
      }
    }
  }
  template <typename S>
  void drain(FlightApp<S>& app) {
    std::uint8_t buf[4096];
    while (app.tx_pending() > 0) {
      const std::size_t n = app.take_tx(buf, sizeof(buf));
      feed(buf, n);
    }
  }
};

}  // namespace flight_app_test
