// Fixed planes: the rest plane of every node of a static or kinematic object and the
// object's surfaces in line with the node, against which the response measures how deep a
// dynamic object's points have gone.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <tuple>

#include "deformable_collision/core/response/detail/fixed_planes.h"
#include "deformable_collision/core/response/detail/rest_columns.h"

namespace deformable_collision {
namespace detail {
namespace {

/// Each node's own best-fit plane normal, and whether its points clearly span a plane: 16
/// points or more, least spread under a tenth of the middle one. A handful of points always
/// fits some plane (three do exactly), often a wrong one. Only planar nodes and the root lend
/// their normals, so smaller nodes (half of them: the leaves) fit none.
void fitOwnPlanes(const std::vector<Eigen::Vector3d>& rest, const SphereTree& tree,
                  std::vector<Eigen::Vector3d>& own_normal, std::vector<std::uint8_t>& planar) {
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    if (node.point_count < 16 && n != 0) continue;
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
    own_normal[n] = solver.eigenvectors().col(0);
    planar[n] = node.point_count >= 16 && solver.eigenvalues()(0) < 0.1 * solver.eigenvalues()(1);
  }
}

/// The parent of every node (the root is its own).
std::vector<std::uint32_t> parentsOf(const SphereTree& tree) {
  std::vector<std::uint32_t> parent(tree.nodeCount(), 0);
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
      parent[c] = n;
    }
  }
  return parent;
}

/// How far a node's own points reach from its centre along its normal, against it and
/// across it.
struct NodeReach {
  double along = 0.0;
  double against = 0.0;
  double across = 0.0;
};

NodeReach reachOfNode(const std::vector<Eigen::Vector3d>& rest, const SphereNode& node,
                      const Eigen::Vector3d& center, const Eigen::Vector3d& normal) {
  NodeReach reach;
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

/// Clears `planar` for the nodes that are slices of a thicker part of the object: its
/// points continue past both of the node's sides along its normal, each by more than half
/// `gap_m`, through no gap wider than `gap_m`. A split along the axis in which a thick floor
/// or block is not much longer than in the others cuts it into such slices (a third of a
/// cube, of a few points across, spreads a tenth as much across as along), and their
/// planes, at right angles to the object's surface, would push what rests on it sideways.
/// The half gap keeps the surface layers: a fitted normal tilted by a thousandth puts the
/// same layer's points a few tenths of a millimetre past the node's side across a wide
/// column.
/// Each planar node's reach along its own normal goes to `own_reach`.
void clearSlices(const SphereTree& tree, const std::vector<Eigen::Vector3d>& own_normal,
                 double gap_m, RestColumns& columns, std::vector<std::uint8_t>& planar,
                 std::vector<NodeReach>& own_reach) {
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    if (!planar[n]) continue;
    RestColumn column{columns.center(n), own_normal[n], 0.0};
    const NodeReach own =
        reachOfNode(columns.slotPoints(), tree.node(n), column.center, column.normal);
    own_reach[n] = own;
    column.radius = own.across + 0.5 * gap_m;
    const double past = 0.5 * gap_m;
    const double along = own.along + past;
    const double against = own.against + past;
    if (columns.reach(0, column, own.along, 1.0, gap_m, along) > along &&
        columns.reach(0, column, own.against, -1.0, gap_m, against) > against) {
      planar[n] = 0;
    }
  }
}

/// The node's surfaces in line with it within `source`, whose plane it takes. The sphere's
/// centre need not lie midway between the layers of a slab (a few points of the top layer
/// may fix the sphere), so each side is measured on its own. A column half a gap wider than
/// the node's points still meets its neighbours in a lattice. `own` is the node's reach along
/// its normal.
void measureExtents(std::uint32_t n, std::uint32_t source, const NodeReach& own, double gap_m,
                    RestColumns& columns, FixedPlanes& planes) {
  const RestColumn column{columns.center(n), planes.normals[n], own.across + 0.5 * gap_m};
  std::tie(planes.extent_along[n], planes.extent_against[n]) =
      columns.reachBothWays(source, column, own.along, own.against, gap_m);
}

}  // namespace

void FixedPlanes::compute(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m) {
  const std::uint32_t count = static_cast<std::uint32_t>(tree.nodeCount());
  const std::vector<std::uint32_t> parent = parentsOf(tree);
  std::vector<Eigen::Vector3d> own_normal(count);
  std::vector<std::uint8_t> planar(count, 0);
  RestColumns columns(body, tree);
  fitOwnPlanes(columns.slotPoints(), tree, own_normal, planar);
  std::vector<NodeReach> own_reach(count);
  clearSlices(tree, own_normal, gap_m, columns, planar, own_reach);
  normals.resize(count);
  extent_along.resize(count);
  extent_against.resize(count);
  for (std::uint32_t n = 0; n < count; ++n) {
    std::uint32_t source = n;
    while (!planar[source] && source != 0) source = parent[source];
    normals[n] = own_normal[source];
    // A node still planar takes its own plane: its reach along it is known.
    const NodeReach own =
        planar[n] ? own_reach[n]
                  : reachOfNode(columns.slotPoints(), tree.node(n), columns.center(n), normals[n]);
    measureExtents(n, source, own, gap_m, columns, *this);
  }
}

}  // namespace detail
}  // namespace deformable_collision
