#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/query/collision_query.h"

namespace deformable_collision {

/// The closest points of two objects' point sets as a level of their hierarchies shows them.
struct ClosestPoints {
  static constexpr std::uint32_t kNoPoint = std::numeric_limits<std::uint32_t>::max();
  /// The least distance of the two point sets at the leaves; above them the least gap of
  /// the level's spheres (0 if they overlap), a lower bound of it.
  double distance_m = 0.0;
  /// The least distance of the points lies in [distance_m, distance_m + error_bound_m]: 0 at
  /// the leaves, above them the two nodes' centre distance plus radii less distance_m.
  double error_bound_m = 0.0;
  /// A closest pair at the leaves; above them the two spheres' points nearest each other.
  Eigen::Vector3d point_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Unit, from b to a.
  std::uint32_t node_a = 0;
  std::uint32_t node_b = 0;
  std::uint32_t index_a = kNoPoint;  ///< The pair's body point indices, at the leaves only.
  std::uint32_t index_b = kNoPoint;
};

/// Distance beyond contact between two sphere trees: a best-first branch-and-bound descent
/// that visits node pairs in the order of their spheres' gaps and stops at the first that
/// cannot beat the best found, so its work follows the pairs near the closest, not the
/// points. Spheres are computed lazily (SphereTree::current), as a contact query would.
/// Holds its queue, so that repeated queries allocate nothing.
class HierarchyDistance {
 public:
  /// The closest points of `a` and `b` at `level` (a node that is a leaf above it stands
  /// for itself; `level` >= both trees' maxLevel() reads the points, exactly), or
  /// std::nullopt if no two points can be within `max_distance_m`.
  /// @throw std::invalid_argument if max_distance_m is negative or not finite.
  std::optional<ClosestPoints> closest(SphereTree& a, SphereTree& b, int level,
                                       double max_distance_m, QueryCounters& counters);

 private:
  struct PendingPair {
    double gap_m;  ///< A lower bound of the pair's points' least distance.
    std::uint32_t node_a;
    std::uint32_t node_b;
  };
  /// One query's state and steps (distance_query.cpp).
  struct Descent;

  std::vector<PendingPair> queue_;
};

}  // namespace deformable_collision
