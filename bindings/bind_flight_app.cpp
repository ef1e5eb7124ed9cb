#include <memory>

#include "bind.hpp"
#include "fsw/app/flight_app.hpp"
#include "validate.hpp"

namespace {
using App = fsw::FlightApp<double>;

py::dict link_counters(const App& app) {
  const fsw::LinkCounters& c = app.link();
  py::dict rejected;
  for (std::size_t i = 0; i < fsw::kRejectReasonCount; ++i) {
    rejected[fsw::to_string(static_cast<fsw::RejectReason>(i))] = c.rejected[i];
  }
  py::dict d;
  d["bytes_received"] = c.bytes_received;
  d["frames_total"] = c.frames_total;
  d["packets_accepted"] = c.packets_accepted;
  d["rejected_by_reason"] = rejected;
  d["rejected_total"] = c.rejected_total();
  d["seq_gaps_total"] = c.gaps_total();
  d["duplicates_total"] = c.duplicates_total();
  return d;
}

py::dict app_counters(const App& app) {
  const App::Counters& c = app.counters();
  py::dict d;
  d["imu_steps"] = c.imu_steps;
  d["pose_updates"] = c.pose_updates;
  d["pose_fused"] = c.pose_fused;
  d["poses_deferred"] = c.poses_deferred;
  d["learner_samples"] = c.learner_samples;
  d["resets"] = c.resets;
  d["resets_refused"] = c.resets_refused;
  d["reacquisitions"] = c.reacquisitions;
  d["configs_rejected"] = c.configs_rejected;
  d["valves"] = c.valves;
  d["valves_not_held"] = c.valves_not_held;
  d["plan_entries"] = c.plan_entries;
  d["plans_loaded"] = c.plans_loaded;
  d["plan_starts"] = c.plan_starts;
  d["plan_aborts"] = c.plan_aborts;
  d["plans_finished"] = c.plans_finished;
  d["plan_commands_refused"] = c.plan_commands_refused;
  d["plan_valve_commands"] = c.plan_valve_commands;
  d["unhandled"] = c.unhandled;
  d["tx_packets"] = c.tx_packets;
  d["tx_dropped"] = c.tx_dropped;
  d["tm_values_clamped"] = c.tm_values_clamped;
  return d;
}

py::dict modal_counters(const App& app) {
  const auto& c = app.modal().counters();
  py::dict d;
  d["segments"] = c.segments;
  d["segments_stale"] = c.segments_stale;
  d["images"] = c.images;
  d["images_fused"] = c.images_fused;
  d["images_incomplete"] = c.images_incomplete;
  d["points_outside"] = c.points_outside;
  d["acquisitions"] = c.acquisitions;
  d["acquisitions_failed"] = c.acquisitions_failed;
  d["acquisition_refused"] = c.acquisition_refused;
  return d;
}
}  // namespace

void bind_flight_app(py::module_& m) {
  py::class_<App, std::unique_ptr<App>>(
      m, "FlightApp",
      "The flight application in-process: the same bytes the flight executable reads from its "
      "serial port go into on_bytes(); the telemetry frames it would write come back. Packet "
      "format: docs/LINK.md.")
      .def(py::init([](const fsw::NavConfig<double>& cfg) { return std::make_unique<App>(cfg); }),
           py::arg("nav_config"))
      .def(
          "on_bytes",
          [](App& app, py::bytes data) {
            const std::string in = data;
            app.on_bytes(reinterpret_cast<const std::uint8_t*>(in.data()), in.size());
            std::string out;
            std::uint8_t buf[4096];
            while (app.tx_pending() > 0) {
              const std::size_t n = app.take_tx(buf, sizeof(buf));
              out.append(reinterpret_cast<const char*>(buf), n);
            }
            return py::bytes(out);
          },
          py::arg("data"), "Feeds link bytes (any chunking); returns the telemetry frames produced.")
      .def("link_counters", &link_counters, "Deframer counters, rejections by reason.")
      .def("counters", &app_counters, "Application counters.")
      .def("modal_counters", &modal_counters,
           "Modal estimator counters (range-image segments, images, frequency acquisitions).");
}
