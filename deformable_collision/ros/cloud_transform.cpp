#include "deformable_collision/ros/cloud_transform.h"

#include <tf2/exceptions.h>

namespace deformable_collision {

CloudTransformLookup lookUpCloudTransform(const tf2::BufferCore& buffer,
                                          const std::string& target_frame,
                                          const std::string& source_frame, const ros::Time& stamp) {
  CloudTransformLookup lookup;
  try {
    lookup.transform = buffer.lookupTransform(target_frame, source_frame, stamp).transform;
    lookup.status = CloudTransformStatus::kFound;
  } catch (const tf2::TransformException& e) {
    // Extrapolation (the pose at the stamp lags) and connectivity (the tree is still being
    // joined) may resolve; a frame no transform ever named only if its publisher is wrong.
    lookup.error = e.what();
    lookup.status = buffer._frameExists(source_frame) ? CloudTransformStatus::kNotYet
                                                      : CloudTransformStatus::kUnknownFrame;
  }
  return lookup;
}

}  // namespace deformable_collision
