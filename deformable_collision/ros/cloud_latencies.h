#pragma once

#include <ros/time.h>

#include <chrono>
#include <cstdint>

#include "deformable_collision/Stats.h"
#include "deformable_collision/ros/latency_window.h"

namespace deformable_collision {

/// The latencies of the clouds the cycles applied, from their arrival (steady clock) and
/// from their stamps (ROS time) to the publication of their contacts, summarised per period
/// for ~stats. Allocates nothing once a period's count of clouds has been seen.
class CloudLatencies {
 public:
  using Clock = std::chrono::steady_clock;

  /// The first period starts at `start` and each lasts at least `period`.
  explicit CloudLatencies(Clock::time_point start, Clock::duration period = std::chrono::seconds(1))
      : period_(period), period_start_(start) {}

  /// A cloud that arrived at `arrival`, stamped `stamp` (zero: none), whose contacts were
  /// published at `published` (`published_ros` in ROS time).
  void add(Clock::time_point arrival, const ros::Time& stamp, Clock::time_point published,
           const ros::Time& published_ros);
  /// Summarises the period and starts the next if it has lasted `period` at `now`.
  void closePeriodIfDue(Clock::time_point now);
  /// Drops the open period's latencies and starts it again at `now`: those measured before
  /// ROS time went back (a looped bag) compare stamps of two different times.
  void restart(Clock::time_point now);
  /// The last closed period's summaries (zero before the first).
  void fill(Stats& stats) const;
  /// Periods closed since start, and the arrival latencies of the last one.
  std::uint64_t periods() const { return periods_; }
  const LatencySummary& arrival() const { return arrival_summary_; }

 private:
  const Clock::duration period_;
  Clock::time_point period_start_;
  LatencyWindow arrival_;
  LatencyWindow stamp_;
  LatencySummary arrival_summary_;
  LatencySummary stamp_summary_;
  double period_s_ = 0.0;  ///< The length of the period summarised.
  std::uint64_t periods_ = 0;
};

}  // namespace deformable_collision
