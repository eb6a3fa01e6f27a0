#pragma once

#include <Eigen/Core>

#include <mutex>
#include <vector>

namespace deformable_collision {

/// The other objects' points near one registered object (Scene::pointsNearObject), passed
/// from the cycle, which gathers them after each cycle, to the reader, which registers the
/// object's clouds with them left out: the newest only, by swapping buffers under a mutex,
/// so no point is copied and, once the three buffers have grown, nothing is allocated.
class NearPointsHandoff {
 public:
  /// Cycle: makes `points_m` the newest; it gets back a buffer to gather into next time.
  void put(std::vector<Eigen::Vector3d>& points_m);
  /// Reader: swaps the newest into `points_m` and returns true if one came since the last
  /// take; false, `points_m` untouched, otherwise.
  bool take(std::vector<Eigen::Vector3d>& points_m);

 private:
  std::mutex mutex_;
  std::vector<Eigen::Vector3d> newest_;
  bool fresh_ = false;
};

}  // namespace deformable_collision
