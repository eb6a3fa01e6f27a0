#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/hierarchy/sphere_tree.h"

namespace deformable_collision {

/// For every node of a tree over points that move only rigidly (a static object, or a
/// kinematic one through pose()), the slab that holds the node's points: two parallel
/// planes across the direction in which they spread least. A flat node's sphere reaches
/// half its width above and below its points, so over a floor or a wall the spheres of
/// everything resting on it overlap the floor's nodes far more often than the points come
/// within reach; the slab rules those pairs out.
class NodeSlabs {
 public:
  /// Levels below the root whose slabs measureOnDemand() measures at once: every query
  /// reads them.
  static constexpr int kLevelsAtOnce = 6;

  /// The slabs of every node of `tree`, whose points are `positions` (indexed by the tree's
  /// pointIndices()): those of the top kLevelsAtOnce levels now, the others when apart()
  /// first asks for them. A floor of a million points, whose slabs take a second to
  /// measure, pays for the nodes that objects come near. Keeps a copy of the points; `tree`
  /// must outlive the slabs. Nodes of coincident or collinear points get some slab that
  /// still holds them.
  /// @throw std::invalid_argument if the tree indexes a point beyond `positions`.
  void measureOnDemand(const SphereTree& tree, const std::vector<Eigen::Vector3d>& positions);

  /// measureOnDemand(), then every slab measured now (for pose(), which reads them all).
  /// @throw std::invalid_argument if the tree indexes a point beyond `positions`.
  void compute(const SphereTree& tree, const std::vector<Eigen::Vector3d>& positions);

  /// The slabs of `rest`'s points moved by `pose` (a kinematic object's rest shape posed):
  /// without visiting a point, and still holding them if `pose` is not quite a rotation
  /// (each slab widens by what the normal's turn cannot account for). `rest` is made by
  /// compute().
  void pose(const NodeSlabs& rest, const Eigen::Isometry3d& pose);

  bool empty() const { return slabs_.empty(); }
  std::size_t size() const { return slabs_.size(); }

  /// Whether every point of `node` is at least `distance_m` from every point of `sphere`,
  /// by the node's slab alone; false when the slab cannot tell (never wrongly true).
  bool apart(std::uint32_t node, const Sphere& sphere, double distance_m) {
    if (!measured_[node]) measure(node);
    const Slab& slab = slabs_[node];
    const double along = slab.normal.dot(sphere.center);
    // The dot products here and in measure() round by a few ulps of the points' and the
    // centre's norms (|v|_1 >= |v|_2), far below this margin, even 1e5 m from the origin.
    const double margin =
        1e-12 * (sphere.center.cwiseAbs().sum() + sphere.radius + distance_m + slab.magnitude_m);
    const double reach = sphere.radius + distance_m + margin;
    return along - reach > slab.high_m || along + reach < slab.low_m;
  }

 private:
  struct Slab {
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Unit.
    double low_m = 0.0;        ///< The least of normal . x over the node's points.
    double high_m = 0.0;       ///< The greatest.
    double magnitude_m = 0.0;  ///< The largest norm of the node's points, for rounding.
  };

  void measure(std::uint32_t node);

  std::vector<Slab> slabs_;
  std::vector<std::uint8_t> measured_;
  const SphereTree* tree_ = nullptr;
  /// The points by slot of the tree's pointIndices(), while slabs are left to measure.
  std::vector<Eigen::Vector3d> slot_points_;
};

}  // namespace deformable_collision
