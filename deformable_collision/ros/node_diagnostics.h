#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/ros/node_health.h"
#include "deformable_collision/ros/node_outputs.h"
#include "deformable_collision/ros/object_slot.h"

namespace deformable_collision {

/// The node's /diagnostics: one status per object and one for the cycle, each over the
/// period since the last (node_health.h says when each is OK, WARN or ERROR). Runs on the
/// cycle's thread, which alone touches what it reads of the slots and outputs besides the
/// reader's atomics; a cycle thread that stops therefore shows as stale diagnostics.
class NodeDiagnostics {
 public:
  NodeDiagnostics(const DiagnosticsParams& params, const std::vector<ObjectSlot>& slots,
                  const NodeOutputs& outputs);

  /// Publishes every period_s of ROS time through a timer on `handle`'s queue, which must be
  /// the cycle's; the statuses are named after the node's private namespace.
  void start(ros::NodeHandle& handle, const ros::NodeHandle& private_handle);

 private:
  /// What the previous status of an object had counted since start.
  struct ObjectCounts {
    std::uint64_t received = 0;
    std::uint64_t dropped = 0;
    std::uint64_t held = 0;
  };

  ObjectPeriod objectPeriod(std::size_t index, ObjectSlot::Clock::time_point now);
  void objectStatus(std::size_t index, diagnostic_updater::DiagnosticStatusWrapper& status);
  void cycleStatus(diagnostic_updater::DiagnosticStatusWrapper& status);

  const DiagnosticsParams params_;
  const std::vector<ObjectSlot>& slots_;
  const NodeOutputs& outputs_;
  std::vector<ObjectCounts> counted_;
  std::uint64_t cycles_counted_ = 0;
  std::uint64_t overruns_counted_ = 0;
  std::uint64_t latency_periods_counted_ = 0;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Timer timer_;
};

}  // namespace deformable_collision
