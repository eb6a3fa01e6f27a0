#include "deformable_collision/core/registration/near_points_filter.h"

namespace deformable_collision {

void NearPointsFilter::reset(std::vector<Eigen::Vector3d>& points_m, double distance_m) {
  points_.swap(points_m);
  index_.build(points_);
  squared_distance_m2_ = distance_m * distance_m;
}

bool NearPointsFilter::excludes(const Eigen::Vector3d& point_m) {
  NearestPointIndex::Nearest nearest;
  return index_.nearestWithin(point_m, squared_distance_m2_, nearest);
}

}  // namespace deformable_collision
