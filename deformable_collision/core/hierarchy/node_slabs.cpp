#include "deformable_collision/core/hierarchy/node_slabs.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace deformable_collision {

void NodeSlabs::measureOnDemand(const SphereTree& tree,
                                const std::vector<Eigen::Vector3d>& positions) {
  const auto& indices = tree.pointIndices();
  for (const std::uint32_t index : indices) {
    if (index >= positions.size()) {
      throw std::invalid_argument("the tree indexes point " + std::to_string(index) + " of " +
                                  std::to_string(positions.size()));
    }
  }
  tree_ = &tree;
  // The points by slot: each node reads its range in order, not scattered over the object
  // (a large node's scattered reads made a contact's first cycle several times longer).
  slot_points_.resize(indices.size());
  for (std::size_t s = 0; s < indices.size(); ++s) slot_points_[s] = positions[indices[s]];
  slabs_.assign(tree.nodeCount(), Slab());
  measured_.assign(tree.nodeCount(), 0);
  // Every query starts at the root: the top levels' slabs are asked for at once, and each
  // level costs a pass over all the points, which the object's maker pays better than the
  // cycle of its first contact.
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    if (tree.node(n).level < kLevelsAtOnce) measure(n);
  }
}

void NodeSlabs::compute(const SphereTree& tree, const std::vector<Eigen::Vector3d>& positions) {
  measureOnDemand(tree, positions);
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    if (!measured_[n]) measure(n);
  }
  std::vector<Eigen::Vector3d>().swap(slot_points_);
}

void NodeSlabs::measure(std::uint32_t n) {
  measured_[n] = 1;
  const SphereNode& node = tree_->node(n);
  const std::uint32_t end = node.first_point + node.point_count;
  if (node.point_count == 0) return;
  const std::vector<Eigen::Vector3d>& points = slot_points_;
  // Centred first: the covariance of points far from the origin keeps its precision.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double magnitude_squared = 0.0;
  for (std::uint32_t s = node.first_point; s < end; ++s) {
    mean += points[s];
    magnitude_squared = std::max(magnitude_squared, points[s].squaredNorm());
  }
  mean /= node.point_count;
  // The solver reads the lower triangle only.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (std::uint32_t s = node.first_point; s < end; ++s) {
    const Eigen::Vector3d d = points[s] - mean;
    for (int row = 0; row < 3; ++row) {
      for (int column = 0; column <= row; ++column) covariance(row, column) += d(row) * d(column);
    }
  }
  Slab& slab = slabs_[n];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  const Eigen::Vector3d least = solver.eigenvectors().col(0);
  // Any unit direction gives a slab that holds the points; a failed solve takes +z.
  if (solver.info() == Eigen::Success && least.allFinite() && least.norm() > 0.5) {
    slab.normal = least.normalized();
  }
  slab.low_m = slab.normal.dot(points[node.first_point]);
  slab.high_m = slab.low_m;
  for (std::uint32_t s = node.first_point; s < end; ++s) {
    const double along = slab.normal.dot(points[s]);
    slab.low_m = std::min(slab.low_m, along);
    slab.high_m = std::max(slab.high_m, along);
  }
  // One root for the node: a rounded root is monotone, so it is the largest of the roots.
  slab.magnitude_m = std::sqrt(magnitude_squared);
}

void NodeSlabs::pose(const NodeSlabs& rest, const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d linear = pose.linear();
  const Eigen::Vector3d& translation = pose.translation();
  slabs_.resize(rest.slabs_.size());
  measured_.resize(slabs_.size(), 1);
  for (std::size_t n = 0; n < slabs_.size(); ++n) {
    const Slab& from = rest.slabs_[n];
    Slab& to = slabs_[n];
    const Eigen::Vector3d turned = linear * from.normal;
    const double length = turned.norm();
    to.normal = length > 0.0 ? Eigen::Vector3d(turned / length) : Eigen::Vector3d::UnitZ();
    // For a posed point A x + t: normal' . (A x + t) = normal . x + (A^T normal' - normal) . x
    // + normal' . t, and |x| <= magnitude: the middle term is what widens the slab (rounding
    // alone for a rotation).
    const double widening =
        (linear.transpose() * to.normal - from.normal).norm() * from.magnitude_m;
    const double shift = to.normal.dot(translation);
    to.low_m = from.low_m + shift - widening;
    to.high_m = from.high_m + shift + widening;
    to.magnitude_m = linear.norm() * from.magnitude_m + translation.norm();
  }
}

}  // namespace deformable_collision
