#include "deformable_collision/core/hierarchy/node_slabs.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace deformable_collision {

void NodeSlabs::compute(const SphereTree& tree, const std::vector<Eigen::Vector3d>& positions) {
  const auto& indices = tree.pointIndices();
  for (const std::uint32_t index : indices) {
    if (index >= positions.size()) {
      throw std::invalid_argument("the tree indexes point " + std::to_string(index) + " of " +
                                  std::to_string(positions.size()));
    }
  }
  // The points by slot: each node reads its range in order, not scattered over the object.
  std::vector<Eigen::Vector3d> points(indices.size());
  for (std::size_t s = 0; s < indices.size(); ++s) points[s] = positions[indices[s]];
  std::vector<Slab> slabs(tree.nodeCount());
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    const std::uint32_t end = node.first_point + node.point_count;
    if (node.point_count == 0) continue;
    // Centred first: the covariance of points far from the origin keeps its precision.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::uint32_t s = node.first_point; s < end; ++s) mean += points[s];
    mean /= node.point_count;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (std::uint32_t s = node.first_point; s < end; ++s) {
      const Eigen::Vector3d d = points[s] - mean;
      covariance += d * d.transpose();
    }
    Slab& slab = slabs[n];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
    const Eigen::Vector3d least = solver.eigenvectors().col(0);
    // Any unit direction gives a slab that holds the points; a failed solve takes +z.
    if (solver.info() == Eigen::Success && least.allFinite() && least.norm() > 0.5) {
      slab.normal = least.normalized();
    }
    slab.low_m = slab.normal.dot(points[node.first_point]);
    slab.high_m = slab.low_m;
    double magnitude_squared = 0.0;
    for (std::uint32_t s = node.first_point; s < end; ++s) {
      const Eigen::Vector3d& point = points[s];
      const double along = slab.normal.dot(point);
      slab.low_m = std::min(slab.low_m, along);
      slab.high_m = std::max(slab.high_m, along);
      magnitude_squared = std::max(magnitude_squared, point.squaredNorm());
    }
    // One root for the node: a rounded root is monotone, so it is the largest of the roots.
    slab.magnitude_m = std::sqrt(magnitude_squared);
  }
  slabs_ = std::move(slabs);
}

void NodeSlabs::pose(const NodeSlabs& rest, const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d linear = pose.linear();
  const Eigen::Vector3d& translation = pose.translation();
  slabs_.resize(rest.slabs_.size());
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
