// The levels of the node's /diagnostics statuses, case by case.
#include "deformable_collision/ros/node_health.h"

#include <gtest/gtest.h>

#include <string>

namespace deformable_collision {
namespace {

using diagnostic_msgs::DiagnosticStatus;
using diagnostic_updater::DiagnosticStatusWrapper;

/// A camera at 10 Hz whose last cloud came 0.05 s ago, two clouds in the period.
ObjectPeriod cameraPeriod() {
  ObjectPeriod period;
  period.in_scene = true;
  period.received = 2;
  period.since_last_cloud_s = 0.05;
  period.interval_s = 0.1;
  return period;
}

struct ObjectCase {
  const char* what;
  void (*change)(ObjectPeriod&);
  std::uint8_t level;
  const char* message_part;
};

class ObjectHealthCases : public ::testing::TestWithParam<ObjectCase> {};

TEST_P(ObjectHealthCases, LevelAndMessage) {
  ObjectPeriod period = cameraPeriod();
  GetParam().change(period);
  DiagnosticStatusWrapper status;
  objectHealth(period, status);
  EXPECT_EQ(status.level, GetParam().level) << GetParam().what << ": " << status.message;
  EXPECT_NE(status.message.find(GetParam().message_part), std::string::npos) << status.message;
}

INSTANTIATE_TEST_SUITE_P(
    Objects, ObjectHealthCases,
    ::testing::Values(
        ObjectCase{"clouds on time", [](ObjectPeriod&) {}, DiagnosticStatus::OK, "clouds arrive"},
        ObjectCase{"a late cloud", [](ObjectPeriod& p) { p.since_last_cloud_s = 0.2; },
                   DiagnosticStatus::OK, "clouds arrive"},
        ObjectCase{"3 intervals and 0.25 s late",
                   [](ObjectPeriod& p) { p.since_last_cloud_s = 0.31; }, DiagnosticStatus::WARN,
                   "no cloud for 0.31 s"},
        ObjectCase{"10 intervals but under 1 s",
                   [](ObjectPeriod& p) { p.since_last_cloud_s = 0.9; }, DiagnosticStatus::WARN,
                   "no cloud for"},
        ObjectCase{"stopped", [](ObjectPeriod& p) { p.since_last_cloud_s = 1.5; },
                   DiagnosticStatus::ERROR, "no cloud for 1.50 s"},
        ObjectCase{"a slow sensor on time",
                   [](ObjectPeriod& p) {
                     p.interval_s = 2.0;
                     p.since_last_cloud_s = 1.5;
                   },
                   DiagnosticStatus::OK, "clouds arrive"},
        ObjectCase{"stopped but its clouds are ignored",
                   [](ObjectPeriod& p) {
                     p.expects_clouds = false;
                     p.since_last_cloud_s = 100.0;
                   },
                   DiagnosticStatus::OK, "clouds arrive"},
        ObjectCase{"rate unknown yet",
                   [](ObjectPeriod& p) {
                     p.interval_s = 0.0;
                     p.since_last_cloud_s = 5.0;
                   },
                   DiagnosticStatus::OK, "clouds arrive"},
        ObjectCase{"one of two dropped", [](ObjectPeriod& p) { p.dropped = 1; },
                   DiagnosticStatus::WARN, "1 of 2 clouds dropped"},
        ObjectCase{"all dropped", [](ObjectPeriod& p) { p.dropped = 2; }, DiagnosticStatus::ERROR,
                   "2 of 2 clouds dropped"},
        ObjectCase{"held", [](ObjectPeriod& p) { p.held = 1; }, DiagnosticStatus::WARN,
                   "registration held the model for 1 clouds"},
        ObjectCase{"dropped and held: both said",
                   [](ObjectPeriod& p) {
                     p.dropped = 1;
                     p.held = 1;
                   },
                   DiagnosticStatus::WARN, "dropped; registration held"},
        ObjectCase{"no cloud yet",
                   [](ObjectPeriod& p) {
                     p.in_scene = false;
                     p.received = 0;
                     p.since_last_cloud_s.reset();
                   },
                   DiagnosticStatus::WARN, "no cloud yet"},
        ObjectCase{"a placed robot link", [](ObjectPeriod& p) { p.has_topic = false; },
                   DiagnosticStatus::OK, "placed by tf"},
        ObjectCase{"a robot link without its frame",
                   [](ObjectPeriod& p) {
                     p.has_topic = false;
                     p.in_scene = false;
                   },
                   DiagnosticStatus::WARN, "waiting for its frame"}));

struct CycleCase {
  const char* what;
  std::uint64_t cycles, overruns;
  std::optional<double> p99_ms;
  std::uint8_t level;
  const char* message_part;
};

class CycleHealthCases : public ::testing::TestWithParam<CycleCase> {};

TEST_P(CycleHealthCases, LevelAndMessage) {
  CyclePeriod period;
  period.cycles = GetParam().cycles;
  period.overruns = GetParam().overruns;
  period.latency_p99_ms = GetParam().p99_ms;
  DiagnosticStatusWrapper status;
  cycleHealth(period, status);
  EXPECT_EQ(status.level, GetParam().level) << GetParam().what << ": " << status.message;
  EXPECT_NE(status.message.find(GetParam().message_part), std::string::npos) << status.message;
}

INSTANTIATE_TEST_SUITE_P(
    Cycles, CycleHealthCases,
    ::testing::Values(
        CycleCase{"keeping to the rate", 100, 0, 20.0, DiagnosticStatus::OK, "keep"},
        CycleCase{"no clouds", 100, 0, std::nullopt, DiagnosticStatus::OK, "keep"},
        CycleCase{"idle", 0, 0, std::nullopt, DiagnosticStatus::OK, "idle"},
        CycleCase{"one overrun", 100, 1, std::nullopt, DiagnosticStatus::WARN,
                  "1 of 100 cycles overran"},
        CycleCase{"half overran", 100, 50, std::nullopt, DiagnosticStatus::WARN, "50 of 100"},
        CycleCase{"most overran", 100, 51, std::nullopt, DiagnosticStatus::ERROR, "51 of 100"},
        CycleCase{"slow contacts", 100, 0, 150.0, DiagnosticStatus::WARN, "latency p99 150.0 ms"},
        CycleCase{"very slow contacts", 100, 0, 1500.0, DiagnosticStatus::ERROR,
                  "latency p99 1500.0 ms"},
        CycleCase{"latency exactly at the bound", 100, 0, 100.0, DiagnosticStatus::OK, "keep"}));

}  // namespace
}  // namespace deformable_collision
