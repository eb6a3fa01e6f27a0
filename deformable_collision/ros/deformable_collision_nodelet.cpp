#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "deformable_collision/ros/deformable_collision_node.h"

namespace deformable_collision {

/// The node in a nodelet manager. A bad configuration makes onInit throw, so the manager
/// refuses to load it and the error names the parameter.
class DeformableCollisionNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      node_ = std::make_unique<DeformableCollisionNode>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {
      NODELET_FATAL("not started: %s", e.what());
      throw;
    }
  }

  std::unique_ptr<DeformableCollisionNode> node_;
};

}  // namespace deformable_collision

PLUGINLIB_EXPORT_CLASS(deformable_collision::DeformableCollisionNodelet, nodelet::Nodelet)
