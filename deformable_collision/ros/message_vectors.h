#pragma once

#include <geometry_msgs/Point.h>
#include <geometry_msgs/Vector3.h>

#include <Eigen/Core>

namespace deformable_collision {

/// An Eigen vector as a message's point or vector: the outputs' one conversion.
inline geometry_msgs::Point toPointMessage(const Eigen::Vector3d& p) {
  geometry_msgs::Point point;
  point.x = p.x();
  point.y = p.y();
  point.z = p.z();
  return point;
}

inline geometry_msgs::Vector3 toVectorMessage(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 vector;
  vector.x = v.x();
  vector.y = v.y();
  vector.z = v.z();
  return vector;
}

}  // namespace deformable_collision
