// Fixed planes: the rest plane of every node of a static or kinematic object and the
// object's surfaces in line with the node, against which the response measures how deep a
// dynamic object's points have gone.
#include "deformable_collision/core/response/detail/fixed_planes.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <tuple>

namespace deformable_collision {
namespace detail {

FixedPlanes::FixedPlanes(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m)
    : tree_(&tree),
      gap_m_(gap_m),
      columns_(body, tree),
      parents_(tree.nodeCount(), 0),
      known_(tree.nodeCount(), 0),
      own_normals_(tree.nodeCount()),
      planes_(tree.nodeCount()) {
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
      parents_[c] = n;
    }
  }
}

const FixedPlanes::Plane& FixedPlanes::plane(std::uint32_t node) {
  Plane& plane = planes_[node];
  if (known_[node] & kMeasured) return plane;
  std::uint32_t source = node;
  while (source != 0 && !planar(source)) source = parents_[source];
  plane.normal = ownNormal(source);
  // The node's surfaces in line with it within `source`. The sphere's centre need not lie
  // midway between the layers of a slab (a few points of the top layer may fix the
  // sphere), so each side is measured on its own. A column half a gap wider than the
  // node's points still meets its neighbours in a lattice.
  const Reach own = reachOf(node, plane.normal);
  const RestColumn column{columns_.center(node), plane.normal, own.across + 0.5 * gap_m_};
  std::tie(plane.extent_along, plane.extent_against) =
      columns_.reachBothWays(source, column, own.along, own.against, gap_m_);
  known_[node] |= kMeasured;
  return plane;
}

// A node's own best-fit plane normal, and whether its points clearly span a plane: 16
// points or more, least spread under a tenth of the middle one. A handful of points always
// fits some plane (three do exactly), often a wrong one. Only planar nodes and the root lend
// their normals, so smaller nodes (half of them: the leaves) fit none.
const Eigen::Vector3d& FixedPlanes::ownNormal(std::uint32_t n) {
  if (known_[n] & kFitted) return own_normals_[n];
  const SphereNode& node = tree_->node(n);
  const std::vector<Eigen::Vector3d>& rest = columns_.slotPoints();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    mean += rest[s];
  }
  mean /= node.point_count;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    const Eigen::Vector3d d = rest[s] - mean;
    covariance += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  own_normals_[n] = solver.eigenvectors().col(0);
  const bool fits =
      node.point_count >= 16 && solver.eigenvalues()(0) < 0.1 * solver.eigenvalues()(1);
  known_[n] |= kFitted | (fits ? kFitsPlane : 0);
  return own_normals_[n];
}

bool FixedPlanes::planar(std::uint32_t n) {
  if (!(known_[n] & kPlanarKnown)) {
    // Nodes of fewer points are not fitted at all.
    if (tree_->node(n).point_count >= 16) ownNormal(n);
    const bool lends = (known_[n] & kFitsPlane) && !isSlice(n);
    known_[n] |= kPlanarKnown | (lends ? kPlanar : 0);
  }
  return known_[n] & kPlanar;
}

// A slice of a thicker part of the object: its points continue past both of the node's
// sides along its normal, each by more than half the gap, through no gap wider than the
// gap. A split along the axis in which a thick floor or block is not much longer than in
// the others cuts it into such slices (a third of a cube, of a few points across, spreads a
// tenth as much across as along), and their planes, at right angles to the object's
// surface, would push what rests on it sideways. The half gap keeps the surface layers: a
// fitted normal tilted by a thousandth puts the same layer's points a few tenths of a
// millimetre past the node's side across a wide column.
bool FixedPlanes::isSlice(std::uint32_t n) {
  const Eigen::Vector3d& normal = own_normals_[n];
  const Reach own = reachOf(n, normal);
  const RestColumn column{columns_.center(n), normal, own.across + 0.5 * gap_m_};
  const double along = own.along + 0.5 * gap_m_;
  const double against = own.against + 0.5 * gap_m_;
  return columns_.reach(0, column, own.along, 1.0, gap_m_, along) > along &&
         columns_.reach(0, column, own.against, -1.0, gap_m_, against) > against;
}

FixedPlanes::Reach FixedPlanes::reachOf(std::uint32_t n, const Eigen::Vector3d& normal) const {
  const SphereNode& node = tree_->node(n);
  const Eigen::Vector3d& center = columns_.center(n);
  const std::vector<Eigen::Vector3d>& rest = columns_.slotPoints();
  Reach reach;
  double across_squared = 0.0;
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    const Eigen::Vector3d d = rest[s] - center;
    const double offset = d.dot(normal);
    reach.along = std::max(reach.along, offset);
    reach.against = std::max(reach.against, -offset);
    across_squared = std::max(across_squared, (d - offset * normal).squaredNorm());
  }
  // One root for the node: a rounded root is monotone, so it is the largest of the roots.
  reach.across = std::sqrt(across_squared);
  return reach;
}

}  // namespace detail
}  // namespace deformable_collision
