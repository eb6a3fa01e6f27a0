#include "deformable_collision/ros/latency_window.h"

#include <gtest/gtest.h>

namespace deformable_collision {
namespace {

TEST(LatencyWindow, SummarisesAPeriodThenStartsAnEmptyOne) {
  LatencyWindow window;
  for (int ms = 100; ms >= 1; --ms) window.add(ms);
  const LatencySummary summary = window.close();
  EXPECT_EQ(summary.count, 100u);
  EXPECT_DOUBLE_EQ(summary.mean_ms, 50.5);
  EXPECT_DOUBLE_EQ(summary.p99_ms, 99.0);  // 99 of the 100 are at most 99 ms
  EXPECT_DOUBLE_EQ(summary.max_ms, 100.0);

  const LatencySummary empty = window.close();
  EXPECT_EQ(empty.count, 0u);
  EXPECT_EQ(empty.mean_ms, 0.0);
  EXPECT_EQ(empty.p99_ms, 0.0);
  EXPECT_EQ(empty.max_ms, 0.0);
}

TEST(LatencyWindow, NinetyNinthPercentileIsTheNearestRank) {
  LatencyWindow window;
  window.add(3.0);
  EXPECT_DOUBLE_EQ(window.close().p99_ms, 3.0);
  // Of 200, the 198th smallest: two may exceed it.
  for (int i = 0; i < 198; ++i) window.add(1.0);
  window.add(7.0);
  window.add(9.0);
  const LatencySummary two_outliers = window.close();
  EXPECT_DOUBLE_EQ(two_outliers.p99_ms, 1.0);
  EXPECT_DOUBLE_EQ(two_outliers.max_ms, 9.0);
  // Of 101, the 100th smallest: one may exceed it.
  for (int i = 0; i < 99; ++i) window.add(1.0);
  window.add(7.0);
  window.add(9.0);
  EXPECT_DOUBLE_EQ(window.close().p99_ms, 7.0);
}

}  // namespace
}  // namespace deformable_collision
