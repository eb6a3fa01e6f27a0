#include "deformable_collision/ros/cloud_latencies.h"

namespace deformable_collision {

void CloudLatencies::add(Clock::time_point arrival, const ros::Time& stamp,
                         Clock::time_point published, const ros::Time& published_ros) {
  arrival_.add(std::chrono::duration<double, std::milli>(published - arrival).count());
  if (!stamp.isZero()) stamp_.add(1e3 * (published_ros - stamp).toSec());
}

void CloudLatencies::closePeriodIfDue(Clock::time_point now) {
  const Clock::duration period = now - period_start_;
  if (period < period_) return;
  arrival_summary_ = arrival_.close();
  stamp_summary_ = stamp_.close();
  period_s_ = std::chrono::duration<double>(period).count();
  ++periods_;
  period_start_ = now;
}

void CloudLatencies::restart(Clock::time_point now) {
  arrival_.clear();
  stamp_.clear();
  period_start_ = now;
}

void CloudLatencies::fill(Stats& stats) const {
  stats.latency_periods = periods_;
  stats.latency_period_s = period_s_;
  stats.latency_clouds = arrival_summary_.count;
  stats.arrival_latency_mean_ms = arrival_summary_.mean_ms;
  stats.arrival_latency_p99_ms = arrival_summary_.p99_ms;
  stats.arrival_latency_max_ms = arrival_summary_.max_ms;
  stats.stamp_latency_mean_ms = stamp_summary_.mean_ms;
  stats.stamp_latency_p99_ms = stamp_summary_.p99_ms;
  stats.stamp_latency_max_ms = stamp_summary_.max_ms;
}

}  // namespace deformable_collision
