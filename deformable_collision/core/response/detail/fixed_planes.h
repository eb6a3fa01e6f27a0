// Internal to the core: the rest planes of the objects the response never moves.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {
namespace detail {

/// The rest plane of every node of an object the response never moves (static or
/// kinematic). A node's own points may be too few to span a plane (a leaf of a two-layer
/// floor is a small cube), so it takes the normal of its nearest ancestor that is clearly
/// planar, or the root's. The plane is anchored at the node's sphere centre; its surfaces
/// are where the object reaches from there in line with the node, through gaps no wider
/// than the contact distance, within that ancestor: a point deep in a thick floor is as
/// deep as the floor's top above it, not as the small node it touches.
struct FixedPlanes {
  void compute(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m);

  std::vector<Eigen::Vector3d> normals;  ///< Per node, in the rest shape.
  /// Per node: how far the object reaches from its sphere's centre along the normal and
  /// against it.
  std::vector<double> extent_along;
  std::vector<double> extent_against;
};

}  // namespace detail
}  // namespace deformable_collision
