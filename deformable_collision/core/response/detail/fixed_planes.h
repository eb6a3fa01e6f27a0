// Internal to the core: the rest planes of the objects the response never moves.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/response/detail/rest_columns.h"
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
///
/// A node's plane is measured when the response first asks for it: it depends on the rest
/// shape alone, so it is the same whenever and in whatever order it is asked for, and a
/// floor of a million points, whose planes take seconds to measure, pays only for the
/// nodes that objects touch.
class FixedPlanes {
 public:
  /// A node's plane in the rest shape.
  struct Plane {
    Eigen::Vector3d normal;
    /// How far the object reaches from the node's sphere centre along the normal and
    /// against it.
    double extent_along = 0.0;
    double extent_against = 0.0;
  };

  /// Reads what it needs of the rest shape now; `tree` (the tree of `body`) must outlive
  /// the planes.
  FixedPlanes(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m);

  /// The node's plane, measured on the first ask.
  const Plane& plane(std::uint32_t node);

 private:
  /// How far a node's own points reach from its centre along a normal, against it and
  /// across it.
  struct Reach {
    double along = 0.0;
    double against = 0.0;
    double across = 0.0;
  };

  /// What is known of a node (bits).
  enum Known : std::uint8_t {
    kFitted = 1,       ///< own_normals_ holds its best-fit normal ...
    kFitsPlane = 2,    ///< ... and its points clearly span that plane.
    kPlanarKnown = 4,  ///< Whether it lends its plane is known ...
    kPlanar = 8,       ///< ... and it does.
    kMeasured = 16,    ///< planes_ holds its plane.
  };

  const Eigen::Vector3d& ownNormal(std::uint32_t node);
  bool planar(std::uint32_t node);
  bool isSlice(std::uint32_t node);
  Reach reachOf(std::uint32_t node, const Eigen::Vector3d& normal) const;

  const SphereTree* tree_;
  double gap_m_;
  RestColumns columns_;
  std::vector<std::uint32_t> parents_;
  std::vector<std::uint8_t> known_;
  std::vector<Eigen::Vector3d> own_normals_;
  std::vector<Plane> planes_;
};

}  // namespace detail
}  // namespace deformable_collision
