#pragma once

#include <ros/ros.h>
#include <std_msgs/Header.h>

#include <boost/shared_ptr.hpp>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/Stats.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/cloud_latencies.h"
#include "deformable_collision/ros/counted_publisher.h"
#include "deformable_collision/ros/force_outputs.h"
#include "deformable_collision/ros/hierarchy_markers.h"

namespace deformable_collision {

/// The node's outputs of each cycle: ~contacts, ~hierarchy, ~contact_summary,
/// ~contact_markers and ~stats, each built only while someone subscribes, and the latencies
/// ~stats reports. Used by the cycle's thread alone.
class NodeOutputs {
 public:
  using Clock = std::chrono::steady_clock;

  /// When the steps of one cycle ended, for ~stats.
  struct CycleTimes {
    Clock::time_point start;
    Clock::time_point clouds_applied;
    Clock::time_point cycled;
    Clock::time_point contacts_published;
    ros::Time contacts_published_ros;
    Clock::time_point published;
  };

  /// The input side's counts since the start, and the reconfigurations', for ~stats.
  struct InputCounts {
    std::uint64_t clouds_received = 0;
    std::uint64_t clouds_rejected = 0;
    std::uint64_t clouds_coalesced = 0;
    std::uint64_t non_finite_points = 0;
    double reader_busy_s = 0.0;
    std::uint32_t reconfigurations_accepted = 0;
    std::uint32_t reconfigurations_refused = 0;
  };

  /// A cycle longer than `cycle_period` counts as an overrun; latencies are summarised
  /// from `start` on.
  NodeOutputs(Clock::time_point start, Clock::duration cycle_period)
      : cycle_period_(cycle_period), latencies_(start) {}

  /// Advertises the topics on `handle`, whose queue must be the cycle's: the cycle alone
  /// counts their subscribers (CountedPublisher).
  void advertise(ros::NodeHandle& handle);
  /// ~contacts: the scene's contacts of its last cycle.
  void publishContacts(const Scene& scene, const std_msgs::Header& header);
  /// ~contact_summary and ~contact_markers of the last cycle's contacts, the markers
  /// through `queue`.
  void publishForces(const Scene& scene, double scale_m_per_n, const std_msgs::Header& header,
                     PublishQueue<CountedPublisher>& queue) {
    forces_.publish(scene, scale_m_per_n, header, queue);
  }
  /// ~hierarchy: the spheres of the last cycle's level, built here, published by `queue`.
  void publishMarkers(Scene& scene, bool colliding_only, const std_msgs::Header& header,
                      PublishQueue<CountedPublisher>& queue);
  CloudLatencies& latencies() { return latencies_; }
  const CloudLatencies& latencies() const { return latencies_; }
  /// Cycles since start, and of them those longer than the cycle period.
  std::uint64_t cycles() const { return stats_message_.cycles; }
  std::uint64_t overruns() const { return stats_message_.overruns; }
  /// ~stats of the cycle: counts the cycle (and an overrun) whether or not anyone listens;
  /// `fill_registrations(Stats&)` adds the registered objects' figures.
  template <typename FillRegistrations>
  void publishStats(const Scene& scene, const std_msgs::Header& header, const CycleTimes& times,
                    std::optional<Clock::time_point> oldest_input, std::size_t points,
                    const InputCounts& counts, FillRegistrations&& fill_registrations) {
    countCycle(times);
    if (!stats_publisher_.subscribed()) return;
    fillStats(scene, header, times, oldest_input, points, counts);
    fill_registrations(stats_message_);
    stats_publisher_.publish(stats_message_);
  }

 private:
  void countCycle(const CycleTimes& times);
  void fillStats(const Scene& scene, const std_msgs::Header& header, const CycleTimes& times,
                 std::optional<Clock::time_point> oldest_input, std::size_t points,
                 const InputCounts& counts);

  const Clock::duration cycle_period_;
  CountedPublisher contacts_publisher_;
  CountedPublisher hierarchy_publisher_;
  CountedPublisher stats_publisher_;
  HierarchyMarkers markers_;
  ForceOutputs forces_;
  CloudLatencies latencies_;
  Stats stats_message_;
  /// The last ~contacts message, filled again in place while nobody else holds it.
  boost::shared_ptr<ContactArray> contacts_message_;
};

}  // namespace deformable_collision
