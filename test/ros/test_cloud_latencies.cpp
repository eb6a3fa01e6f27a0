#include "deformable_collision/ros/cloud_latencies.h"

#include <gtest/gtest.h>

namespace deformable_collision {
namespace {

using Clock = CloudLatencies::Clock;
using std::chrono::milliseconds;

TEST(CloudLatencies, SummarisesEachClosedPeriodForStats) {
  const Clock::time_point start{};
  CloudLatencies latencies(start, milliseconds(1000));
  Stats stats;
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 0u);
  EXPECT_EQ(stats.latency_clouds, 0u);

  const ros::Time published_ros(100.0);
  // Arrived 2 and 4 ms before their contacts; stamped 10 ms before, and not stamped.
  latencies.add(start + milliseconds(8), published_ros - ros::Duration(0.010),
                start + milliseconds(10), published_ros);
  latencies.add(start + milliseconds(6), ros::Time(), start + milliseconds(10), published_ros);
  latencies.closePeriodIfDue(start + milliseconds(999));
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 0u) << "a period shorter than 1 s stays open";

  latencies.closePeriodIfDue(start + milliseconds(1500));
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 1u);
  EXPECT_DOUBLE_EQ(stats.latency_period_s, 1.5);
  EXPECT_EQ(stats.latency_clouds, 2u);
  EXPECT_DOUBLE_EQ(stats.arrival_latency_mean_ms, 3.0);
  EXPECT_DOUBLE_EQ(stats.arrival_latency_max_ms, 4.0);
  EXPECT_NEAR(stats.stamp_latency_mean_ms, 10.0, 1e-6);
  EXPECT_NEAR(stats.stamp_latency_max_ms, 10.0, 1e-6);

  // The next period starts where the last closed, empty.
  latencies.closePeriodIfDue(start + milliseconds(2499));
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 1u);
  latencies.closePeriodIfDue(start + milliseconds(2500));
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 2u);
  EXPECT_EQ(stats.latency_clouds, 0u);
  EXPECT_EQ(stats.arrival_latency_max_ms, 0.0);
}

TEST(CloudLatencies, ARestartDropsTheOpenPeriodAndStartsItAgain) {
  const Clock::time_point start{};
  CloudLatencies latencies(start, milliseconds(1000));
  // A cloud of the end of a bag, its contacts published after the clock went back.
  const ros::Time published_ros(100.0);
  latencies.add(start + milliseconds(8), ros::Time(130.0), start + milliseconds(10), published_ros);
  latencies.restart(start + milliseconds(900));
  latencies.add(start + milliseconds(1000), published_ros - ros::Duration(0.005),
                start + milliseconds(1001), published_ros);
  latencies.closePeriodIfDue(start + milliseconds(1899));
  Stats stats;
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 0u) << "the period restarted at 900 ms";
  latencies.closePeriodIfDue(start + milliseconds(1900));
  latencies.fill(stats);
  EXPECT_EQ(stats.latency_periods, 1u);
  EXPECT_DOUBLE_EQ(stats.latency_period_s, 1.0);
  EXPECT_EQ(stats.latency_clouds, 1u) << "the cloud before the restart is not counted";
  EXPECT_NEAR(stats.stamp_latency_max_ms, 5.0, 1e-6);
}

}  // namespace
}  // namespace deformable_collision
