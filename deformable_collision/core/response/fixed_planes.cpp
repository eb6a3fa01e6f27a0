// Fixed planes: the rest plane of every node of a static or kinematic object and the
// object's surfaces in line with the node, against which the response measures how deep a
// dynamic object's points have gone.
#include <Eigen/Eigenvalues>
#include <algorithm>

#include "deformable_collision/core/response/detail/fixed_planes.h"

namespace deformable_collision {
namespace detail {
namespace {

/// Each node's own best-fit plane normal, and whether its points clearly span a plane: 16
/// points or more, least spread under a tenth of the middle one. A handful of points always
/// fits some plane (three do exactly), often a wrong one.
void fitOwnPlanes(const ShapeMatchingBody& body, const SphereTree& tree,
                  std::vector<Eigen::Vector3d>& own_normal, std::vector<std::uint8_t>& planar) {
  const auto& rest = body.restPositions();
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      mean += rest[tree.pointIndices()[s]];
    }
    mean /= node.point_count;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      const Eigen::Vector3d d = rest[tree.pointIndices()[s]] - mean;
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

NodeReach reachOfNode(const ShapeMatchingBody& body, const SphereTree& tree, const SphereNode& node,
                      const Eigen::Vector3d& center, const Eigen::Vector3d& normal) {
  const auto& rest = body.restPositions();
  NodeReach reach;
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    const Eigen::Vector3d d = rest[tree.pointIndices()[s]] - center;
    const double offset = d.dot(normal);
    reach.along = std::max(reach.along, offset);
    reach.against = std::max(reach.against, -offset);
    reach.across = std::max(reach.across, (d - offset * normal).norm());
  }
  return reach;
}

/// The offsets along `normal` of `within`'s points in line with `center`: those within
/// `radius` of the line through it along the normal; sorted.
void columnOffsets(const ShapeMatchingBody& body, const SphereTree& tree, const SphereNode& within,
                   const Eigen::Vector3d& center, const Eigen::Vector3d& normal, double radius,
                   std::vector<double>& offsets) {
  offsets.clear();
  const auto& rest = body.restPositions();
  for (std::uint32_t s = within.first_point; s < within.first_point + within.point_count; ++s) {
    const Eigen::Vector3d d = rest[tree.pointIndices()[s]] - center;
    const double offset = d.dot(normal);
    if ((d - offset * normal).norm() <= radius) offsets.push_back(offset);
  }
  std::sort(offsets.begin(), offsets.end());
}

/// How far the column's points reach from `start` in `sign`'s direction, through no gap
/// wider than `gap_m`: the surface of a layered or solid slab, not what lies beyond a gap.
template <typename Iterator>
double reachAcrossGaps(Iterator first, Iterator last, double start, double sign, double gap_m) {
  double reach = start;
  for (; first != last; ++first) {
    const double offset = sign * *first;
    if (offset <= reach) continue;
    if (offset - reach > gap_m) break;
    reach = offset;
  }
  return reach;
}

Eigen::Vector3d restCenter(const ShapeMatchingBody& body, const SphereNode& node) {
  return node.cluster < 0
             ? node.rest_center
             : Eigen::Vector3d(node.rest_center + body.cluster(node.cluster).rest_center_of_mass);
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
void clearSlices(const ShapeMatchingBody& body, const SphereTree& tree,
                 const std::vector<Eigen::Vector3d>& own_normal, double gap_m,
                 std::vector<std::uint8_t>& planar) {
  std::vector<double> offsets;
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    if (!planar[n]) continue;
    const SphereNode& node = tree.node(n);
    const Eigen::Vector3d center = restCenter(body, node);
    const NodeReach own = reachOfNode(body, tree, node, center, own_normal[n]);
    columnOffsets(body, tree, tree.node(0), center, own_normal[n], own.across + 0.5 * gap_m,
                  offsets);
    const double past = 0.5 * gap_m;
    const bool continues_along =
        reachAcrossGaps(offsets.begin(), offsets.end(), own.along, 1.0, gap_m) > own.along + past;
    const bool continues_against = reachAcrossGaps(offsets.rbegin(), offsets.rend(), own.against,
                                                   -1.0, gap_m) > own.against + past;
    if (continues_along && continues_against) planar[n] = 0;
  }
}

}  // namespace

void FixedPlanes::compute(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m) {
  const std::uint32_t count = static_cast<std::uint32_t>(tree.nodeCount());
  const std::vector<std::uint32_t> parent = parentsOf(tree);
  std::vector<Eigen::Vector3d> own_normal(count);
  std::vector<std::uint8_t> planar(count, 0);
  fitOwnPlanes(body, tree, own_normal, planar);
  clearSlices(body, tree, own_normal, gap_m, planar);
  normals.resize(count);
  extent_along.resize(count);
  extent_against.resize(count);
  std::vector<double> offsets;
  for (std::uint32_t n = 0; n < count; ++n) {
    std::uint32_t source = n;
    while (!planar[source] && source != 0) source = parent[source];
    normals[n] = own_normal[source];
    const SphereNode& node = tree.node(n);
    const Eigen::Vector3d center = restCenter(body, node);
    // The sphere's centre need not lie midway between the layers of a slab (a few points
    // of the top layer may fix the sphere), so each side is measured on its own. A column
    // half a gap wider than the node's points still meets its neighbours in a lattice.
    const NodeReach own = reachOfNode(body, tree, node, center, normals[n]);
    columnOffsets(body, tree, tree.node(source), center, normals[n], own.across + 0.5 * gap_m,
                  offsets);
    extent_along[n] = reachAcrossGaps(offsets.begin(), offsets.end(), own.along, 1.0, gap_m);
    extent_against[n] = reachAcrossGaps(offsets.rbegin(), offsets.rend(), own.against, -1.0, gap_m);
  }
}

}  // namespace detail
}  // namespace deformable_collision
