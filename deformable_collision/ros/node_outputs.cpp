#include "deformable_collision/ros/node_outputs.h"

#include <visualization_msgs/MarkerArray.h>

#include <boost/make_shared.hpp>

#include "deformable_collision/ros/contact_service.h"

namespace deformable_collision {
namespace {

double millisecondsBetween(NodeOutputs::Clock::time_point from, NodeOutputs::Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

}  // namespace

void NodeOutputs::advertise(ros::NodeHandle& handle) {
  contacts_publisher_.advertise<ContactArray>(handle, "contacts", 10);
  hierarchy_publisher_.advertise<visualization_msgs::MarkerArray>(handle, "hierarchy", 1);
  stats_publisher_.advertise<Stats>(handle, "stats", 10);
  forces_.advertise(handle);
}

void NodeOutputs::publishContacts(const Scene& scene, const std_msgs::Header& header) {
  if (!contacts_publisher_.subscribed()) return;
  // Once published, the message is roscpp's to serialise (before publish() returns) and a
  // subscriber's in this process to keep: if none kept it, its contacts and their names
  // are written over instead of allocated anew (16k contacts a cycle in the load test).
  if (!contacts_message_ || contacts_message_.use_count() > 1) {
    contacts_message_ = boost::make_shared<ContactArray>();
  }
  contacts_message_->header = header;
  fillContactArray(scene, scene.contacts(), scene.stats().level, *contacts_message_);
  contacts_publisher_.publish(contacts_message_);
}

void NodeOutputs::publishMarkers(Scene& scene, bool colliding_only, const std_msgs::Header& header,
                                 PublishQueue<CountedPublisher>& queue) {
  if (!hierarchy_publisher_.subscribed() || scene.objectCount() == 0) return;
  auto markers = boost::make_shared<visualization_msgs::MarkerArray>();
  markers_.build(scene, scene.stats().level, scene.contacts(), colliding_only, header, *markers);
  queue.post(hierarchy_publisher_, markers);
}

// Cycles and overruns count whether or not anyone listens: a later subscriber sees all.
void NodeOutputs::countCycle(const CycleTimes& times) {
  ++stats_message_.cycles;
  if (times.published - times.start > cycle_period_) {
    ++stats_message_.overruns;
    // The input made the cycle late if the rest of the cycle kept to the period.
    if (times.published - times.clouds_applied <= cycle_period_) {
      ++stats_message_.overruns_from_input;
    }
  }
}

void NodeOutputs::fillStats(const Scene& scene, const std_msgs::Header& header,
                            const CycleTimes& times, std::optional<Clock::time_point> oldest_input,
                            std::size_t points, const InputCounts& counts) {
  const CycleStats& cycle = scene.stats();
  Stats& stats = stats_message_;
  stats.header = header;
  stats.level = static_cast<std::uint8_t>(cycle.level);
  stats.max_level = static_cast<std::uint8_t>(scene.maxLevel());
  stats.level_auto = cycle.level_auto;
  stats.cycle_budget_ms = cycle.cycle_budget_ms;
  stats.input_ms = millisecondsBetween(times.start, times.clouds_applied);
  stats.shape_matching_ms = cycle.shape_matching_ms;
  stats.detection_ms = cycle.detection_ms;
  stats.detection_ahead_ms = cycle.detection_ahead_ms;
  stats.response_ms = cycle.response_ms;
  stats.publish_ms = millisecondsBetween(times.cycled, times.published);
  stats.cycle_ms = millisecondsBetween(times.start, times.published);
  stats.input_latency_ms =
      oldest_input ? millisecondsBetween(*oldest_input, times.contacts_published) : 0.0;
  latencies_.fill(stats);
  stats.objects = static_cast<std::uint32_t>(scene.objectCount());
  stats.points = static_cast<std::uint32_t>(points);
  stats.objects_moved = static_cast<std::uint32_t>(cycle.objects_moved);
  stats.object_pairs_tested = static_cast<std::uint32_t>(cycle.object_pairs_tested);
  stats.object_pairs_reused = static_cast<std::uint32_t>(cycle.object_pairs_reused);
  stats.spheres_updated = static_cast<std::uint32_t>(cycle.spheres_updated);
  stats.node_pairs_tested = static_cast<std::uint32_t>(cycle.node_pairs_tested);
  stats.point_tests = static_cast<std::uint32_t>(cycle.point_tests);
  stats.contacts = static_cast<std::uint32_t>(cycle.contacts);
  stats.clouds_received = counts.clouds_received;
  stats.clouds_rejected = counts.clouds_rejected;
  stats.clouds_coalesced = counts.clouds_coalesced;
  stats.non_finite_points = counts.non_finite_points;
  stats.reader_busy_s = counts.reader_busy_s;
  stats.reconfigurations_accepted = counts.reconfigurations_accepted;
  stats.reconfigurations_refused = counts.reconfigurations_refused;
}

}  // namespace deformable_collision
