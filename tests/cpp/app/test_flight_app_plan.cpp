// The stored valve plan through the flight app: uplinked entry by entry,
// checked whole at load (every refusal rule changes nothing and is
// counted), run from its start command one IMU interval at a time (the
// valve command sent as tm_plan_valves and held for the thruster learner),
// finished, aborted; float and double.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "flight_app_util.hpp"

using namespace fsw;
using namespace flight_app_test;

namespace {

struct Entry {
  std::uint8_t valve;
  double t_open_s, t_close_s;
};

struct PlanUplink : Uplink {
  void entry(double t, std::uint32_t id, std::uint16_t index, std::uint16_t count, const Entry& e) {
    CmdPlanEntryMsg m;
    m.plan_id = id;
    m.entry_index = index;
    m.entry_count = count;
    m.valve = e.valve;
    m.t_open_s = e.t_open_s;
    m.t_close_s = e.t_close_s;
    add(Apid::CmdPlanEntry, m, t);
  }
  void plan(double t, std::uint32_t id, const std::vector<Entry>& entries) {
    for (std::size_t i = 0; i < entries.size(); ++i)
      entry(t, id, std::uint16_t(i), std::uint16_t(entries.size()), entries[i]);
  }
  void command(double t, PlanAction action, std::uint32_t id, std::uint32_t count = 0, double duration_s = 0.0) {
    CmdPlanMsg m;
    m.action = static_cast<std::uint32_t>(action);
    m.plan_id = id;
    m.entry_count = count;
    m.duration_s = duration_s;
    add(Apid::CmdPlan, m, t);
  }
  void load(double t, std::uint32_t id, std::size_t count, double duration_s) {
    command(t, PlanAction::Load, id, std::uint32_t(count), duration_s);
  }
};

struct PlanTelemetry {
  Deframer deframer{Direction::FromFlight};
  std::vector<TmPlanStatusMsg> status;
  std::vector<TmPlanValvesMsg> valves;
  int learner = 0;

  template <typename S>
  void drain(FlightApp<S>& app) {
    std::uint8_t buf[4096];
    while (app.tx_pending() > 0) {
      const std::size_t n = app.take_tx(buf, sizeof(buf));
      std::size_t used = 0;
      while (used < n) {
        DeframeResult r;
        used += deframer.feed(buf + used, n - used, r);
        if (r.kind != DeframeResult::Kind::Packet) continue;
        const PacketView& p = r.packet;
        if (p.header.apid == static_cast<std::uint16_t>(Apid::TmPlanStatus)) {
          TmPlanStatusMsg m;
          EXPECT_TRUE(decode(p.payload, p.t_s, m));
          status.push_back(m);
        } else if (p.header.apid == static_cast<std::uint16_t>(Apid::TmPlanValves)) {
          TmPlanValvesMsg m;
          EXPECT_TRUE(decode(p.payload, p.t_s, m));
          valves.push_back(m);
        } else if (p.header.apid == static_cast<std::uint16_t>(Apid::TmLearner)) {
          ++learner;
        }
      }
    }
  }
};

// The plan every refusal test starts from: loaded, id 7.
const std::vector<Entry> kGood = {{2, 0.3, 0.8}, {5, 0.5, 0.6}, {2, 1.0, 1.5}};
constexpr double kGoodDuration = 2.0;

template <typename S>
class FlightAppPlan : public ::testing::Test {
 protected:
  void SetUp() override {
    app = std::make_unique<FlightApp<S>>();
    PlanUplink up;
    up.reset(0.0, Vec3<double>(0.1, -0.7, 0.0), Vec3<double>::Zero(), Quat<double>::Identity());
    up.plan(0.0, 7, kGood);
    up.load(0.0, 7, kGood.size(), kGoodDuration);
    send(up);
    ASSERT_EQ(app->plan().state(), PlanState::Loaded);
    ASSERT_EQ(tm.status.back().verdict, 0);
    tm.status.clear();
  }
  void feed(const Uplink& up) {
    app->on_bytes(up.bytes.data(), up.bytes.size());
    tm.drain(*app);
  }
  // An uplink that continues this test's sequence counts, and its sending.
  PlanUplink uplink() const {
    PlanUplink up;
    up.framer = framer_state;
    return up;
  }
  void send(const PlanUplink& up) {
    feed(up);
    framer_state = up.framer;
  }
  // A second plan, id 8, loaded with the given entries, duration and
  // possibly another count; the verdict answered. The first plan stays.
  PlanVerdict try_load(const std::vector<Entry>& entries, double duration_s, std::size_t count) {
    PlanUplink up = uplink();
    up.plan(1.0, 8, entries);
    up.load(1.0, 8, count, duration_s);
    send(up);
    EXPECT_FALSE(tm.status.empty());
    return tm.status.empty() ? PlanVerdict::Accepted : static_cast<PlanVerdict>(tm.status.back().verdict);
  }
  PlanVerdict try_load(const std::vector<Entry>& entries, double duration_s = kGoodDuration) {
    return try_load(entries, duration_s, entries.size());
  }
  // Nothing changed: the first plan stored as it was, not running, one
  // refusal more counted and reported.
  void expect_unchanged(std::uint32_t refused = 1) {
    const ValvePlan& p = app->plan();
    EXPECT_EQ(p.state(), PlanState::Loaded);
    EXPECT_EQ(p.id(), 7u);
    ASSERT_EQ(p.size(), kGood.size());
    for (std::size_t i = 0; i < kGood.size(); ++i) {
      EXPECT_EQ(p.entry(i).valve, kGood[i].valve);
      EXPECT_EQ(p.entry(i).t_open_s, kGood[i].t_open_s);
      EXPECT_EQ(p.entry(i).t_close_s, kGood[i].t_close_s);
    }
    EXPECT_EQ(p.duration_s(), kGoodDuration);
    EXPECT_EQ(app->counters().plans_loaded, 1u);
    EXPECT_EQ(app->counters().plan_commands_refused, refused);
    ASSERT_FALSE(tm.status.empty());
    EXPECT_EQ(tm.status.back().plan_id, 7u);
    EXPECT_EQ(tm.status.back().state, static_cast<std::uint8_t>(PlanState::Loaded));
    EXPECT_EQ(tm.status.back().commands_refused, refused);
    EXPECT_TRUE(tm.valves.empty());
  }
  // IMU samples at 0.1 s from t0 to t1 (inclusive).
  void imu(double t0, double t1) {
    PlanUplink up = uplink();
    for (int k = int(std::lround(t0 * 10)); k <= int(std::lround(t1 * 10)); ++k)
      up.imu(0.1 * k, Vec3<double>(0.002, 0, 0), Vec3<double>(0, 0, 0.001));
    send(up);
  }
  void command(double t, PlanAction action, std::uint32_t id) {
    PlanUplink up = uplink();
    up.command(t, action, id);
    send(up);
  }

  std::unique_ptr<FlightApp<S>> app;
  PlanTelemetry tm;
  Framer framer_state{Direction::ToFlight};
};

using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(FlightAppPlan, Scalars);

}  // namespace

TYPED_TEST(FlightAppPlan, AcceptsACompletePlanInAnyOrderAndReportsIt) {
  PlanUplink up = this->uplink();
  const std::vector<Entry> e = {{0, 0.0, 0.2}, {1, 0.1, 0.4}, {0, 0.5, 0.7}};
  up.entry(1.0, 9, 2, 3, e[2]);
  up.entry(1.0, 9, 0, 3, {0, 9.0, 9.5});  // replaced by the next copy of entry 0
  up.entry(1.0, 9, 0, 3, e[0]);
  up.entry(1.0, 9, 1, 3, e[1]);
  up.load(1.0, 9, 3, 1.0);
  this->send(up);
  ASSERT_EQ(this->tm.status.size(), 1u);
  const TmPlanStatusMsg& s = this->tm.status.back();
  EXPECT_EQ(s.verdict, 0);
  EXPECT_EQ(s.action, static_cast<std::uint8_t>(PlanAction::Load));
  EXPECT_EQ(s.plan_id, 9u);
  EXPECT_EQ(s.state, static_cast<std::uint8_t>(PlanState::Loaded));
  EXPECT_EQ(s.entry_count, 3u);
  EXPECT_EQ(s.plans_loaded, 2u);
  EXPECT_DOUBLE_EQ(s.duration_s, 1.0);
  EXPECT_NEAR(s.total_on_time_s, 0.2 + 0.3 + 0.2, 1e-12);
  EXPECT_EQ(this->app->plan().entry(0).t_open_s, 0.0);
  EXPECT_EQ(this->app->counters().plan_entries, 3u + 4u);
  EXPECT_EQ(this->app->counters().plan_commands_refused, 0u);
}

TYPED_TEST(FlightAppPlan, RefusesValveOutOfRange) {
  EXPECT_EQ(this->try_load({{8, 0.0, 0.5}}), PlanVerdict::ValveOutOfRange);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesValveBeyondConfiguredValveCount) {
  PlanUplink up = this->uplink();
  up.config(0.5, ConfigParam::PlanValves, 4);
  this->send(up);
  EXPECT_EQ(this->try_load({{4, 0.0, 0.5}}), PlanVerdict::ValveOutOfRange);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesOnTimeBelowMinimum) {
  EXPECT_EQ(this->try_load({{1, 0.0, 0.05}}), PlanVerdict::OnTimeTooShort);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesOnTimeAboveMaximum) {
  PlanUplink up = this->uplink();
  up.config(0.5, ConfigParam::PlanMaxOnTime, 1.0);
  this->send(up);
  EXPECT_EQ(this->try_load({{1, 0.0, 1.5}}), PlanVerdict::OnTimeTooLong);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesNegativeTime) {
  EXPECT_EQ(this->try_load({{1, -0.5, 0.5}}), PlanVerdict::BadTimes);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesCloseNotAfterOpen) {
  EXPECT_EQ(this->try_load({{1, 0.9, 0.5}}), PlanVerdict::BadTimes);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesOpeningPastThePlansEnd) {
  EXPECT_EQ(this->try_load({{1, 1.5, 2.5}}, 2.0), PlanVerdict::BadTimes);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesZeroDuration) {
  EXPECT_EQ(this->try_load({{1, 0.0, 0.5}}, 0.0), PlanVerdict::BadTimes);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesOverlappingOpeningsOfOneValve) {
  EXPECT_EQ(this->try_load({{3, 0.0, 0.5}, {3, 0.4, 0.9}}), PlanVerdict::Overlap);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesEntriesOutOfOrder) {
  EXPECT_EQ(this->try_load({{3, 0.6, 0.9}, {4, 0.0, 0.5}}), PlanVerdict::Overlap);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesTotalOnTimeAboveLimit) {
  PlanUplink up = this->uplink();
  up.config(0.5, ConfigParam::PlanMaxTotalOnTime, 0.8);
  this->send(up);
  EXPECT_EQ(this->try_load({{0, 0.0, 0.5}, {1, 0.2, 0.7}}), PlanVerdict::TotalOnTimeTooLong);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesDurationAboveLimit) {
  EXPECT_EQ(this->try_load({{1, 0.0, 0.5}}, 1801.0), PlanVerdict::DurationTooLong);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesIncompletePlan) {
  PlanUplink up = this->uplink();
  up.entry(1.0, 8, 0, 3, {0, 0.0, 0.5});
  up.entry(1.0, 8, 2, 3, {1, 0.6, 0.9});  // entry 1 lost
  up.load(1.0, 8, 3, 1.0);
  this->send(up);
  ASSERT_FALSE(this->tm.status.empty());
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::Incomplete));
  EXPECT_EQ(this->tm.status.back().entries_received, 2u);
  this->expect_unchanged();
}

// An entry whose index lies past its own plan's count spoils the staging:
// both good entries arrive too, and still the load is refused.
TYPED_TEST(FlightAppPlan, RefusesPlanWithAnEntryIndexPastItsCount) {
  PlanUplink up = this->uplink();
  up.entry(1.0, 8, 0, 2, {0, 0.0, 0.5});
  up.entry(1.0, 8, 2, 2, {2, 0.0, 0.5});  // index 2 of 2
  up.entry(1.0, 8, 1, 2, {1, 0.6, 0.9});
  up.load(1.0, 8, 2, 1.0);
  this->send(up);
  ASSERT_FALSE(this->tm.status.empty());
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::Incomplete));
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesLoadOfAnotherCount) {
  EXPECT_EQ(this->try_load({{0, 0.0, 0.5}, {1, 0.6, 0.9}}, 1.0, 3), PlanVerdict::Incomplete);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesPlanTooLongForTheStore) {
  std::vector<Entry> many;
  for (std::size_t i = 0; i <= ValvePlan::kCapacity; ++i) many.push_back({0, 0.2 * double(i), 0.2 * double(i) + 0.1});
  EXPECT_EQ(this->try_load(many, 100.0), PlanVerdict::TooLong);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, NonFiniteEntryNeverReachesThePlan) {
  PlanUplink up = this->uplink();
  up.entry(1.0, 8, 0, 1, {0, 0.0, std::numeric_limits<double>::quiet_NaN()});
  up.load(1.0, 8, 1, 1.0);
  this->send(up);
  EXPECT_EQ(this->app->link().rejected[static_cast<std::size_t>(RejectReason::NonFinitePayload)], 1u);
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::Incomplete));
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesStartOfAnotherPlan) {
  this->command(1.0, PlanAction::Start, 8);
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::NoPlan));
  this->imu(1.0, 1.5);
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesAbortWhenNotRunning) {
  this->command(1.0, PlanAction::Abort, 7);
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::NotRunning));
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesUnknownAction) {
  this->command(1.0, static_cast<PlanAction>(9), 7);
  EXPECT_EQ(this->tm.status.back().verdict, static_cast<std::uint8_t>(PlanVerdict::UnknownAction));
  this->expect_unchanged();
}

TYPED_TEST(FlightAppPlan, RefusesLoadWhileRunningAndKeepsRunning) {
  this->command(1.0, PlanAction::Start, 7);
  this->imu(1.0, 1.3);
  const std::size_t before = this->tm.valves.size();
  EXPECT_EQ(this->try_load({{1, 0.0, 0.5}}), PlanVerdict::Running);
  EXPECT_EQ(this->app->plan().state(), PlanState::Running);
  EXPECT_EQ(this->app->plan().id(), 7u);
  EXPECT_EQ(this->app->counters().plan_commands_refused, 1u);
  this->imu(1.4, 1.4);
  EXPECT_EQ(this->tm.valves.size(), before + 1);  // the plan goes on
}

// The command of every interval: valve 2 open 0.3 to 0.8 and 1.0 to 1.5,
// valve 5 0.5 to 0.6, from a start at t = 1.0; the plan ends at 3.0.
TYPED_TEST(FlightAppPlan, EmitsEachIntervalsCommandAtItsTime) {
  this->imu(0.1, 0.9);
  EXPECT_TRUE(this->tm.valves.empty());  // loaded, not started
  this->command(1.0, PlanAction::Start, 7);
  EXPECT_EQ(this->tm.status.back().state, static_cast<std::uint8_t>(PlanState::Running));
  this->imu(1.0, 3.5);
  const auto& v = this->tm.valves;
  ASSERT_EQ(v.size(), 21u);  // 1.0 .. 2.9 running, 3.0 finished
  for (std::size_t k = 0; k < 20; ++k) {
    const double tau = 0.1 * double(k);
    EXPECT_NEAR(v[k].t_s, 1.0 + tau, 1e-9);
    EXPECT_NEAR(v[k].plan_time_s, tau, 1e-9);
    EXPECT_EQ(v[k].state, static_cast<std::uint8_t>(PlanState::Running));
    EXPECT_EQ(v[k].plan_id, 7u);
    EXPECT_NEAR(v[k].interval_s, 0.1, 1e-15);
    const bool v2 = (k >= 3 && k < 8) || (k >= 10 && k < 15);
    const bool v5 = k == 5;
    EXPECT_EQ(v[k].valve_mask, (v2 ? 1u << 2 : 0u) | (v5 ? 1u << 5 : 0u)) << "interval " << k;
    EXPECT_NEAR(v[k].on_time_s[2], v2 ? 0.1 : 0.0, 1e-9);
    EXPECT_NEAR(v[k].on_time_s[5], v5 ? 0.1 : 0.0, 1e-9);
  }
  EXPECT_EQ(v[20].state, static_cast<std::uint8_t>(PlanState::Finished));
  EXPECT_EQ(v[20].valve_mask, 0u);
  EXPECT_NEAR(v[20].t_s, 3.0, 1e-9);
  EXPECT_EQ(this->app->plan().state(), PlanState::Finished);
  EXPECT_EQ(this->app->counters().plans_finished, 1u);
  EXPECT_EQ(this->app->counters().plan_valve_commands, 20u);
  EXPECT_EQ(this->tm.status.back().state, static_cast<std::uint8_t>(PlanState::Finished));
}

TYPED_TEST(FlightAppPlan, OpeningsOffTheIntervalEdgesGiveTheirOnTimes) {
  PlanUplink up = this->uplink();
  up.plan(1.0, 8, {{4, 0.25, 0.45}});
  up.load(1.0, 8, 1, 0.6);
  up.command(2.0, PlanAction::Start, 8);
  this->send(up);
  this->imu(2.0, 2.7);
  const auto& v = this->tm.valves;
  ASSERT_EQ(v.size(), 7u);
  const double want[6] = {0.0, 0.0, 0.05, 0.1, 0.05, 0.0};
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(v[k].on_time_s[4], want[k], 1e-9) << k;
    EXPECT_EQ(v[k].valve_mask, want[k] > 0 ? 1u << 4 : 0u) << k;
  }
  EXPECT_EQ(v[6].state, static_cast<std::uint8_t>(PlanState::Finished));
}

TYPED_TEST(FlightAppPlan, StartTaggedAheadWaitsForItsTime) {
  this->command(2.0, PlanAction::Start, 7);
  this->imu(1.0, 1.9);
  EXPECT_TRUE(this->tm.valves.empty());
  this->imu(2.0, 2.0);
  ASSERT_EQ(this->tm.valves.size(), 1u);
  EXPECT_NEAR(this->tm.valves[0].plan_time_s, 0.0, 1e-9);
}

TYPED_TEST(FlightAppPlan, AbortClosesEveryValveAtOnce) {
  this->command(1.0, PlanAction::Start, 7);
  this->imu(1.0, 1.4);  // valve 2 open from 1.3
  ASSERT_EQ(this->tm.valves.back().valve_mask, 1u << 2);
  this->command(1.45, PlanAction::Abort, 7);
  ASSERT_EQ(this->tm.valves.size(), 6u);
  EXPECT_EQ(this->tm.valves.back().state, static_cast<std::uint8_t>(PlanState::Aborted));
  EXPECT_EQ(this->tm.valves.back().valve_mask, 0u);
  EXPECT_NEAR(this->tm.valves.back().t_s, 1.45, 1e-12);
  EXPECT_EQ(this->tm.status.back().verdict, 0);
  EXPECT_EQ(this->tm.status.back().state, static_cast<std::uint8_t>(PlanState::Aborted));
  this->imu(1.5, 3.5);
  EXPECT_EQ(this->tm.valves.size(), 6u);  // nothing more commanded
  EXPECT_EQ(this->app->counters().plan_aborts, 1u);
  // The stored plan stays and runs again from a new start.
  this->command(4.0, PlanAction::Start, 7);
  EXPECT_EQ(this->tm.status.back().verdict, 0);
  this->imu(4.0, 4.3);
  EXPECT_EQ(this->tm.valves.back().valve_mask, 1u << 2);
}

TYPED_TEST(FlightAppPlan, ResetAbortsARunningPlan) {
  this->command(1.0, PlanAction::Start, 7);
  this->imu(1.0, 1.4);
  PlanUplink up = this->uplink();
  up.reset(1.45, Vec3<double>(0.1, -0.7, 0.0), Vec3<double>::Zero(), Quat<double>::Identity());
  this->send(up);
  EXPECT_EQ(this->app->plan().state(), PlanState::Aborted);
  EXPECT_EQ(this->tm.valves.back().state, static_cast<std::uint8_t>(PlanState::Aborted));
  EXPECT_EQ(this->tm.valves.back().valve_mask, 0u);
}

// The plan's whole-interval firings reach the thruster learner as a ground
// thruster_valves would; a ground thruster_valves meanwhile is not held.
TYPED_TEST(FlightAppPlan, PlanFiringsTeachTheLearner) {
  this->command(1.0, PlanAction::Start, 7);
  PlanUplink up = this->uplink();
  for (int k = 10; k <= 30; ++k) {
    up.imu(0.1 * k, Vec3<double>(0.002, 0, 0), Vec3<double>(0, 0, 0.001));
    if (k == 12) up.valves(0.1 * k, 0.1, 0x01);
  }
  this->send(up);
  // Firing intervals: valve 2 at 1.3 .. 1.7 and 2.0 .. 2.4, valve 5 with it at 1.5: 10 intervals.
  EXPECT_EQ(this->app->counters().learner_samples, 10u);
  EXPECT_EQ(this->tm.learner, 10);
  EXPECT_EQ(this->app->counters().valves_not_held, 1u);
  EXPECT_EQ(this->app->learner().count(), 10);
}

TYPED_TEST(FlightAppPlan, ConfigRefusesPlanLimitsOutOfTheirDomain) {
  PlanUplink up = this->uplink();
  up.config(0.5, ConfigParam::PlanValves, 9);
  up.config(0.5, ConfigParam::PlanValves, 2.5);
  up.config(0.5, ConfigParam::PlanMinOnTime, -0.1);
  up.config(0.5, ConfigParam::PlanMaxOnTime, 0.05);  // below the minimum on-time
  up.config(0.5, ConfigParam::PlanMaxDuration, 0.0);
  up.config(0.5, ConfigParam::PlanMaxTotalOnTime, 0.0);
  this->send(up);
  EXPECT_EQ(this->app->counters().configs_rejected, 6u);
  const PlanLimits& l = this->app->plan_limits();
  const PlanLimits d;
  EXPECT_EQ(l.valves, d.valves);
  EXPECT_EQ(l.min_on_time_s, d.min_on_time_s);
  EXPECT_EQ(l.max_on_time_s, d.max_on_time_s);
  EXPECT_EQ(l.max_duration_s, d.max_duration_s);
  EXPECT_EQ(l.max_total_on_time_s, d.max_total_on_time_s);
}
