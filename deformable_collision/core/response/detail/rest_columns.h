// Internal to the core: the points of an object's rest shape in line with a node, found down
// the object's own tree.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {
namespace detail {

/// The rest points within `radius` of the line through `center` along `normal`.
struct RestColumn {
  Eigen::Vector3d center;
  Eigen::Vector3d normal;
  double radius;
};

/// Walks along columns of a node's rest points from a start outwards, through gaps no wider
/// than a given one. A walk reads only the points its column holds near where it goes: it
/// descends the tree from the node, passing over subtrees whose rest boxes (along the
/// normal) or spheres (across it) miss the column or the stretch of it being read. Each
/// point's offset is computed and compared as in a walk over the whole column sorted, so the
/// reach is the same, bit for bit.
class RestColumns {
 public:
  RestColumns(const ShapeMatchingBody& body, const SphereTree& tree);

  /// The rest points by slot of the tree's pointIndices(): a node's points are a range,
  /// read in order.
  const std::vector<Eigen::Vector3d>& slotPoints() const { return slot_points_; }

  /// The node's rest sphere centre in the object's coordinates.
  const Eigen::Vector3d& center(std::uint32_t node) const { return nodes_[node].center; }

  /// How far the points of `within` in `column` reach from `start` (an offset along the
  /// normal times `sign`, +1 or -1) in `sign`'s direction, through no gap wider than `gap_m`.
  /// Once the reach passes `enough` the walk stops there: it only goes further.
  double reach(std::uint32_t within, const RestColumn& column, double start, double sign,
               double gap_m, double enough = std::numeric_limits<double>::infinity());

  /// reach() along the normal from `along_start` and against it from `against_start`.
  std::pair<double, double> reachBothWays(std::uint32_t within, const RestColumn& column,
                                          double along_start, double against_start, double gap_m);

 private:
  /// What a descent reads of a node.
  struct Node {
    Eigen::Vector3d center;
    /// Its rest radius with a margin for the rounding of the points' coordinates against
    /// the centre's (a cluster's nodes are spheres of its centred points).
    double reach;
    /// The box around its points: much thinner than the sphere across a flat node, so it
    /// bounds the points' offsets along a normal (the sphere bounds them across it).
    Eigen::Vector3d box_center, box_half;
    double box_margin;  ///< For the rounding of the offsets of the box's points.
    std::uint32_t first_child, child_count, first_point, point_count;
  };

  /// The part of a column being read: the points with sign times their offset in
  /// (low, high] but not in [skip_low, skip_high], and what every node's test needs of the
  /// column.
  struct Stretch {
    const RestColumn& column;
    double sign, low, high;
    double skip_low = std::numeric_limits<double>::infinity();
    double skip_high = -std::numeric_limits<double>::infinity();
    Eigen::Vector3d abs_normal = Eigen::Vector3d::Zero();
    double margin = 0.0;  ///< For the rounding of offsets from the column's centre.
  };

  Stretch stretchOf(const RestColumn& column, double sign, double low, double high) const;
  /// Sorted in offsets_: sign times the offsets of the stretch's points of `within`.
  void gather(std::uint32_t within, const Stretch& stretch);
  /// Whether none of the node's points can lie in the stretch.
  bool misses(const Node& node, const Stretch& stretch) const;
  void gatherPoints(const Node& node, const Stretch& stretch);
  /// Bounds on sign times the offsets of the node's points: around the first, within the
  /// second.
  std::pair<double, double> offsetBounds(const Node& node, const Stretch& stretch) const;
  /// The boxes of the nodes, children (which come after their parents) first.
  void boundBoxes();

  std::vector<Node> nodes_;
  std::vector<Eigen::Vector3d> slot_points_;
  std::vector<std::uint32_t> pending_;
  std::vector<double> offsets_;
};

}  // namespace detail
}  // namespace deformable_collision
