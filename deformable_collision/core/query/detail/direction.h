#pragma once

#include <Eigen/Core>

namespace deformable_collision {

/// Unit vector from b to a, or +z when the two coincide (any direction is then as good): a
/// contact's or a closest pair's normal.
inline Eigen::Vector3d directionFrom(const Eigen::Vector3d& b, const Eigen::Vector3d& a) {
  const Eigen::Vector3d d = a - b;
  const double length = d.norm();
  return length > 0.0 ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitZ();
}

}  // namespace deformable_collision
