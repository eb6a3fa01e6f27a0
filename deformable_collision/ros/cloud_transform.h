#pragma once

#include <geometry_msgs/Transform.h>
#include <ros/time.h>
#include <tf2/buffer_core.h>

#include <string>

namespace deformable_collision {

/// Whether a cloud's transform was found and, if not, whether it may still come.
enum class CloudTransformStatus {
  kFound,
  kUnknownFrame,  ///< tf has never heard of the cloud's frame: no transform names it.
  kNotYet,        ///< The frame is known, but not at this stamp or not yet linked to the target.
};

struct CloudTransformLookup {
  CloudTransformStatus status = CloudTransformStatus::kNotYet;
  geometry_msgs::Transform transform;  ///< Only when kFound.
  std::string error;                   ///< tf's own words when not found.
};

/// The transform from `source_frame` (a cloud's) to `target_frame` at `stamp`. Only the
/// source frame's absence makes it kUnknownFrame: a target frame tf does not know yet is a
/// tree still filling, which every cloud waits for alike.
CloudTransformLookup lookUpCloudTransform(const tf2::BufferCore& buffer,
                                          const std::string& target_frame,
                                          const std::string& source_frame, const ros::Time& stamp);

}  // namespace deformable_collision
