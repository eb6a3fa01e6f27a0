#include "deformable_collision/ros/near_points_handoff.h"

namespace deformable_collision {

void NearPointsHandoff::put(std::vector<Eigen::Vector3d>& points_m) {
  std::lock_guard<std::mutex> lock(mutex_);
  newest_.swap(points_m);
  fresh_ = true;
}

bool NearPointsHandoff::take(std::vector<Eigen::Vector3d>& points_m) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!fresh_) return false;
  newest_.swap(points_m);
  fresh_ = false;
  return true;
}

}  // namespace deformable_collision
