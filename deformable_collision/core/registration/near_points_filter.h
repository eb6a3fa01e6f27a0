#pragma once

#include <Eigen/Core>
#include <vector>

#include "deformable_collision/core/common/nearest_point_index.h"
#include "deformable_collision/core/registration/cloud_registration.h"

namespace deformable_collision {

/// Leaves out the cloud points closer than a distance to any of a set of points: another
/// object's points near the registered one (Scene::pointsNearObject), the jaws that squeeze
/// it, whose faces lie about where its hidden faces were. Holds its points, so a
/// registration on another thread than the scene's filters by what it was last given.
class NearPointsFilter final : public CloudPointFilter {
 public:
  /// Swaps `points_m` in (it gets the former points, a buffer to fill next time) and
  /// indexes them: from now on a point closer than `distance_m` to one of them is excluded.
  /// Allocates nothing once it has held as many points.
  void reset(std::vector<Eigen::Vector3d>& points_m, double distance_m);
  bool excludes(const Eigen::Vector3d& point_m) override;

 private:
  std::vector<Eigen::Vector3d> points_;
  NearestPointIndex index_;
  double squared_distance_m2_ = 0.0;
};

}  // namespace deformable_collision
