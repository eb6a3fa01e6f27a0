#pragma once

#include <geometry_msgs/TransformStamped.h>

#include <Eigen/Geometry>
#include <string>

namespace deformable_collision {

/// `pose` of frame `child` in frame `parent` as a tf message.
inline geometry_msgs::TransformStamped toTransform(const Eigen::Isometry3d& pose,
                                                   const ros::Time& stamp,
                                                   const std::string& parent,
                                                   const std::string& child) {
  geometry_msgs::TransformStamped transform;
  transform.header.stamp = stamp;
  transform.header.frame_id = parent;
  transform.child_frame_id = child;
  transform.transform.translation.x = pose.translation().x();
  transform.transform.translation.y = pose.translation().y();
  transform.transform.translation.z = pose.translation().z();
  const Eigen::Quaterniond rotation(pose.linear());
  transform.transform.rotation.x = rotation.x();
  transform.transform.rotation.y = rotation.y();
  transform.transform.rotation.z = rotation.z();
  transform.transform.rotation.w = rotation.w();
  return transform;
}

}  // namespace deformable_collision
