#pragma once

#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>

#include <boost/thread/recursive_mutex.hpp>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/DeformableCollisionConfig.h"
#include "deformable_collision/ObjectMaterialConfig.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/cloud_reader.h"
#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/ros/object_slot.h"
#include "deformable_collision/ros/reconfigure_checks.h"

namespace deformable_collision {

/// dynamic_reconfigure for what can change while the node runs: ~reconfigure (level or
/// budget, friction, markers, registration work per cloud) and ~reconfigure/objects/<name>
/// (a dynamic object's stiffness and damping, a tracked one's contact stiffness). The
/// servers start from the loaded config and run on the cycle's queue, so a change takes
/// effect at the next cycle; one that fails its check is refused with a warning and the old
/// values kept. Counts both for ~stats.
class NodeReconfigure {
 public:
  NodeReconfigure(Scene& scene, NodeConfig& config, std::vector<ObjectSlot>& slots,
                  CloudReader& reader);

  /// Starts the servers under `handle` (the node's private handle on the cycle's queue).
  void start(const ros::NodeHandle& handle);
  /// After an object's rest shape was (re)made from the config: its reconfigured material.
  void reapply(const ObjectSlot& slot);

  std::uint32_t accepted() const { return accepted_; }
  std::uint32_t refused() const { return refused_; }

 private:
  struct ObjectServer {
    std::unique_ptr<boost::recursive_mutex> mutex;
    std::unique_ptr<dynamic_reconfigure::Server<ObjectMaterialConfig>> server;
    ObjectMaterialConfig current;
  };

  DeformableCollisionConfig initialNodeConfig() const;
  static ObjectMaterialConfig initialObjectConfig(const ObjectParams& params);
  void onNode(DeformableCollisionConfig& requested, std::uint32_t level);
  void onObject(std::size_t slot, ObjectMaterialConfig& requested, std::uint32_t level);
  /// Takes a checked reconfiguration of the node into the scene, the config and the reader.
  void applyNode(const DeformableCollisionConfig& requested);
  void count(bool accepted, const std::string& what, const std::string& problem);

  Scene& scene_;
  NodeConfig& config_;
  std::vector<ObjectSlot>& slots_;
  CloudReader& reader_;
  boost::recursive_mutex node_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<DeformableCollisionConfig>> node_server_;
  DeformableCollisionConfig node_current_;
  std::vector<ObjectServer>
      object_servers_;  ///< Per slot; empty for a kind with nothing to change.
  std::uint32_t accepted_ = 0;
  std::uint32_t refused_ = 0;
};

}  // namespace deformable_collision
