// Every step status and detail has its own name for telemetry and logs.
#include <gtest/gtest.h>

#include <cctype>
#include <set>
#include <string>
#include <string_view>

#include "fsw/math/step_status.hpp"

using fsw::StepDetail;
using fsw::StepStatus;

namespace {

bool is_snake_case(const std::string& s) {
  if (s.empty()) return false;
  for (char c : s)
    if (!(std::islower(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

}  // namespace

static_assert(std::string_view(fsw::to_string(StepStatus::Gated)) == "gated", "names are compile-time constants");

TEST(StepStatusTest, EveryStatusHasItsOwnSnakeCaseName) {
  std::set<std::string> names;
  for (int v = 0; v <= static_cast<int>(StepStatus::BadInput); ++v) {
    const std::string name = fsw::to_string(static_cast<StepStatus>(v));
    EXPECT_TRUE(is_snake_case(name)) << name;
    EXPECT_NE(name, "unknown");
    names.insert(name);
  }
  EXPECT_EQ(names.size(), 4u);
  EXPECT_STREQ(fsw::to_string(StepStatus::NotPosDef), "not_pos_def");
}

TEST(StepStatusTest, EveryDetailHasItsOwnSnakeCaseName) {
  std::set<std::string> names;
  const int last = static_cast<int>(StepDetail::CovarianceRepaired);
  for (int v = 0; v <= last; ++v) {
    const std::string name = fsw::to_string(static_cast<StepDetail>(v));
    EXPECT_TRUE(is_snake_case(name)) << name;
    EXPECT_NE(name, "unknown") << v;
    names.insert(name);
  }
  EXPECT_EQ(names.size(), std::size_t(last + 1));
  EXPECT_STREQ(fsw::to_string(StepDetail::OffTick), "off_tick");
  EXPECT_STREQ(fsw::to_string(StepDetail::CovarianceRepaired), "covariance_repaired");
}

TEST(StepStatusTest, AValueOutsideTheEnumIsNamedUnknown) {
  // A corrupted byte read back from telemetry must not index past a table.
  EXPECT_STREQ(fsw::to_string(static_cast<StepStatus>(200)), "unknown");
  EXPECT_STREQ(fsw::to_string(static_cast<StepDetail>(200)), "unknown");
}
