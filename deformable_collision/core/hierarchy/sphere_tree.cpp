// The update of a SphereTree (paper sections 5.2 and 5.4): each visited node's sphere from
// its cluster's deformation, once per cycle, exact where the query measures leaves.
#include "deformable_collision/core/hierarchy/sphere_tree.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/common/detail/wide_kernels.h"
#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/common/wide_vectors.h"

namespace deformable_collision {
namespace {

/// Relative slack added to every computed radius: the centre, the norms and the deviation
/// bound are each rounded (relative error a few 1e-16 of the radius and of the coordinates),
/// and enclosure must hold for the points as callers measure them.
constexpr double kRoundingMargin = 1e-12;

double withRoundingMargin(double radius, const Eigen::Vector3d& center) {
  return radius + kRoundingMargin * (radius + center.cwiseAbs().maxCoeff());
}

/// Sum of the `Count` products transform(row, j) * features[j], in the order of Eigen's
/// product on SSE2, whose bits the spheres had before it was written out: the first two rows
/// one column after the other, the last as a balanced tree. GCC keeps Eigen's loop for a
/// 3 x 9 product out of line, which made every sphere update pay for a call and a loop.
template <int Count>
[[gnu::always_inline]] inline double rowSum(const Eigen::Matrix<double, 3, 9>& transform, int row,
                                            const double* features) {
  if (row < 2) {
    double sum = transform(row, 0) * features[0];
#pragma GCC unroll 9
    for (int j = 1; j < Count; ++j) sum = sum + transform(row, j) * features[j];
    return sum;
  }
  double products[Count];
#pragma GCC unroll 9
  for (int j = 0; j < Count; ++j) products[j] = transform(row, j) * features[j];
  if constexpr (Count == 3) {
    return products[0] + (products[1] + products[2]);
  } else {
    static_assert(Count == 9, "a linear or a quadratic transform");
    return ((products[0] + products[1]) + (products[2] + products[3])) +
           ((products[4] + products[5]) + (products[6] + (products[7] + products[8])));
  }
}

/// Where a node's sphere centre, at `rest_center` in its cluster's centred coordinates,
/// goes under the cluster's goal transform.
[[gnu::always_inline]] inline Eigen::Vector3d deformedCenter(const Eigen::Vector3d& rest_center,
                                                             const ClusterDeformation& deformation,
                                                             DeformationMode mode) {
  const double x = rest_center.x(), y = rest_center.y(), z = rest_center.z();
  const Eigen::Matrix<double, 3, 9>& t = deformation.transform;
  const Eigen::Vector3d& translation = deformation.translation;
  if (mode == DeformationMode::kQuadratic) {
    const double features[9] = {x, y, z, x * x, y * y, z * z, x * y, y * z, z * x};
    return {rowSum<9>(t, 0, features) + translation.x(),
            rowSum<9>(t, 1, features) + translation.y(),
            rowSum<9>(t, 2, features) + translation.z()};
  }
  const double features[3] = {x, y, z};
  return {rowSum<3>(t, 0, features) + translation.x(), rowSum<3>(t, 1, features) + translation.y(),
          rowSum<3>(t, 2, features) + translation.z()};
}

#if defined(__GNUC__) && defined(__x86_64__)
DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

/// Copies the up to eight points at `indices` of `positions` (three coordinates a point)
/// into the rows `x`, `y`, `z`, and returns the largest of their squared distances from
/// `leaf_center`; with `exact`, raises `node_farthest_squared` to the largest from
/// `node_center`. Eight points per instruction, each distance summed as Eigen sums it.
__attribute__((target("avx512f"))) double gatherLeafAvx512(
    const double* positions, const std::uint32_t* indices, std::uint32_t count, double* x,
    double* y, double* z, const Eigen::Vector3d& leaf_center, const Eigen::Vector3d& node_center,
    bool exact, double& node_farthest_squared) {
  const __mmask8 lanes = lanesFrom(0, count);
  const __m256i offsets = _mm512_castsi512_si256(
      _mm512_mullo_epi32(_mm512_maskz_loadu_epi32(lanes, indices), _mm512_set1_epi32(3)));
  const __m512d none = _mm512_setzero_pd();
  const __m512d px = _mm512_mask_i32gather_pd(none, lanes, offsets, positions, 8);
  const __m512d py = _mm512_mask_i32gather_pd(none, lanes, offsets, positions + 1, 8);
  const __m512d pz = _mm512_mask_i32gather_pd(none, lanes, offsets, positions + 2, 8);
  _mm512_mask_storeu_pd(x, lanes, px);
  _mm512_mask_storeu_pd(y, lanes, py);
  _mm512_mask_storeu_pd(z, lanes, pz);
  if (exact) {
    const __m512d squared =
        squaredDistancesAvx512(node_center.x(), node_center.y(), node_center.z(), px, py, pz);
    node_farthest_squared =
        std::max(node_farthest_squared, _mm512_mask_reduce_max_pd(lanes, squared));
  }
  const __m512d squared =
      squaredDistancesAvx512(leaf_center.x(), leaf_center.y(), leaf_center.z(), px, py, pz);
  return std::max(0.0, _mm512_mask_reduce_max_pd(lanes, squared));
}

DEFORMABLE_COLLISION_END_WIDE_KERNELS
#endif

}  // namespace

void SphereTree::beginCycle(SphereUpdate method) {
  method_ = method;
  // After 2^32 cycles (a few weeks at 1 kHz) the count comes round to the stamps of spheres
  // still held: they are cleared first, or an old sphere would pass for a current one.
  if (++cycle_ == 0) {
    for (NodeState& state : states_) state.stamp = 0;
    std::fill(leaves_current_stamps_.begin(), leaves_current_stamps_.end(), 0);
    std::fill(leaf_stamps_.begin(), leaf_stamps_.end(), 0);
    for (ClusterNorms& norms : cluster_norms_) norms.stamp = 0;
    cycle_ = 1;
  }
  counters_ = {};
  if (method == SphereUpdate::kBottomUpRefit) refitBottomUp();
}

const NodeState& SphereTree::updateSphere(std::uint32_t index) {
  NodeState& state = states_[index];
  if (state.isLeaf() && leaf_stamps_[state.first_leaf] == cycle_) {
    // Measured with a node above it (measureWithLeaves).
    const std::uint32_t k = state.first_leaf;
    state.sphere.center =
        Eigen::Vector3d(leaf_spheres_.x[k], leaf_spheres_.y[k], leaf_spheres_.z[k]);
    state.sphere.radius = leaf_spheres_.radius[k];
    state.stamp = cycle_;
    return state;
  }
  Sphere sphere;
  if (method_ == SphereUpdate::kExactRefit) {
    sphere = exactSphere(index);
  } else if (nodes_[index].cluster < 0) {
    sphere = spanningSphere(index);
  } else {
    sphere = deformationSphere(index);
  }
  setSphere(index, sphere);
  ++counters_.spheres_updated;
  return states_[index];
}

const SphereTree::ClusterNorms& SphereTree::norms(std::size_t cluster) {
  ClusterNorms& norms = cluster_norms_[cluster];
  if (norms.stamp == cycle_) return norms;
  norms.stamp = cycle_;
  const DeformationMode mode = body_->config().mode;
  // A rotation has norm 1: rigid clusters compute no norm at all.
  if (mode == DeformationMode::kRigid) return norms;
  const auto& transform = body_->deformation(cluster).transform;
  norms.linear = spectralNorm(transform.leftCols<3>());
  if (mode == DeformationMode::kQuadratic) {
    norms.quadratic = spectralNorm(transform.middleCols<3>(3));
    norms.mixed = spectralNorm(transform.rightCols<3>());
  }
  ++counters_.norm_evaluations;
  return norms;
}

const NodeState& SphereTree::updateWithLeaves(std::uint32_t index, std::uint32_t leaf_limit) {
  const SphereNode& node = nodes_[index];
  if (node.leaf_count > leaf_limit || node.isLeaf()) return updateSphere(index);
  if (method_ == SphereUpdate::kDeformation && node.cluster >= 0) {
    measureWithLeaves(index);
  } else {
    current(index);
    for (std::uint32_t k = node.first_leaf; k < node.first_leaf + node.leaf_count; ++k) {
      current(leaf_nodes_[k]);
    }
  }
  leaves_current_stamps_[index] = cycle_;
  return states_[index];
}

void SphereTree::measureWithLeaves(std::uint32_t index) {
  // The same spheres as deformationSphere() gives the node and each leaf, bit for bit: the
  // leaves' points, in leaf order, are the node's points in its own order.
  const SphereNode& node = nodes_[index];
  const ClusterDeformation& deformation = body_->deformation(node.cluster);
  const DeformationMode mode = body_->config().mode;
  const Eigen::Vector3d center = deformedCenter(node.rest_center, deformation, mode);
  const bool exact = node.point_count <= exact_radius_points_;
  const auto& positions = body_->positions();
  // The points lie wherever their cloud put them, and a scene's shape matching has moved
  // many others since: asking for all of the node's at once overlaps their cache misses,
  // which the gathers below would otherwise wait for one leaf at a time.
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    __builtin_prefetch(positions[point_indices_[s]].data());
  }
  double farthest_squared = 0.0;
  for (std::uint32_t k = node.first_leaf; k < node.first_leaf + node.leaf_count; ++k) {
    const Eigen::Vector3d leaf_center = deformedCenter(leaf_rest_centers_[k], deformation, mode);
    const std::uint32_t first = leaf_slot_starts_[k];
    const std::uint32_t count = leaf_slot_starts_[k + 1] - first;
    double leaf_farthest_squared = 0.0;
#if defined(__GNUC__) && defined(__x86_64__)
    if (gather_wide_ && count <= 8) {
      leaf_farthest_squared = gatherLeafAvx512(
          positions.front().data(), &point_indices_[first], count, &slot_positions_(0, first),
          &slot_positions_(1, first), &slot_positions_(2, first), leaf_center, center, exact,
          farthest_squared);
    } else
#endif
    {
      for (std::uint32_t s = first; s < first + count; ++s) {
        const Eigen::Vector3d& x = positions[point_indices_[s]];
        slot_positions_.col(s) = x;
        leaf_farthest_squared = std::max(leaf_farthest_squared, (x - leaf_center).squaredNorm());
        if (exact) farthest_squared = std::max(farthest_squared, (x - center).squaredNorm());
      }
    }
    // The leaf's NodeState is left alone: it is copied from here if ever asked for.
    counters_.spheres_updated += leaf_stamps_[k] != cycle_;
    leaf_stamps_[k] = cycle_;
    leaf_spheres_.x[k] = leaf_center.x();
    leaf_spheres_.y[k] = leaf_center.y();
    leaf_spheres_.z[k] = leaf_center.z();
    leaf_spheres_.radius[k] = withRoundingMargin(std::sqrt(leaf_farthest_squared), leaf_center);
  }
  const double radius = exact ? std::sqrt(farthest_squared) : boundRadius(node, deformation);
  counters_.spheres_updated += states_[index].stamp != cycle_;
  setSphere(index, {center, withRoundingMargin(radius, center)});
}

double SphereTree::boundRadius(const SphereNode& node, const ClusterDeformation& deformation) {
  const ClusterNorms& n = norms(node.cluster);
  return n.linear * node.rest_radius_m + n.quadratic * node.quadratic_extent_m2 +
         n.mixed * node.mixed_extent_m2 + deformation.goal_deviation_bound_m;
}

Sphere SphereTree::deformationSphere(std::uint32_t index) {
  const SphereNode& node = nodes_[index];
  const ClusterDeformation& deformation = body_->deformation(node.cluster);
  Sphere sphere;
  sphere.center = deformedCenter(node.rest_center, deformation, body_->config().mode);
  if (node.isLeaf() || node.point_count <= exact_radius_points_) {
    // A few points are quickly measured, and their exact distance is tighter than the bound.
    // A leaf's points are gathered for the leaf-pair tests in the same pass.
    // One square root for the farthest point: the root is correctly rounded and monotone,
    // so this is the largest of the points' distances, bit for bit.
    const auto& positions = body_->positions();
    const bool leaf = node.isLeaf();
    double farthest_squared = 0.0;
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      const Eigen::Vector3d& x = positions[point_indices_[s]];
      if (leaf) slot_positions_.col(s) = x;
      farthest_squared = std::max(farthest_squared, (x - sphere.center).squaredNorm());
    }
    sphere.radius = withRoundingMargin(std::sqrt(farthest_squared), sphere.center);
    return sphere;
  }
  sphere.radius = withRoundingMargin(boundRadius(node, deformation), sphere.center);
  return sphere;
}

Sphere SphereTree::boundWithoutPoints(std::uint32_t index) {
  const SphereNode& node = nodes_[index];
  if (method_ != SphereUpdate::kDeformation || node.cluster < 0) return sphere(index);
  const ClusterDeformation& deformation = body_->deformation(node.cluster);
  const Eigen::Vector3d center =
      deformedCenter(node.rest_center, deformation, body_->config().mode);
  return {center, withRoundingMargin(boundRadius(node, deformation), center)};
}

Sphere SphereTree::exactSphere(std::uint32_t index) {
  const SphereNode& node = nodes_[index];
  const auto& positions = body_->positions();
  const bool leaf = node.isLeaf();
  scratch_points_.clear();
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    const Eigen::Vector3d& x = positions[point_indices_[s]];
    if (leaf) slot_positions_.col(s) = x;  // gathered for the leaf-pair tests
    scratch_points_.push_back(x);
  }
  Sphere sphere = smallestEnclosingSphere(scratch_points_, scratch_sphere_);
  sphere.radius = withRoundingMargin(sphere.radius, sphere.center);
  return sphere;
}

Sphere SphereTree::spanningSphere(std::uint32_t index) {
  const SphereNode& node = nodes_[index];
  scratch_spheres_.clear();
  for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
    scratch_spheres_.push_back(sphere(c));
  }
  Sphere result = enclosingSphereOfSpheres(scratch_spheres_.data(), scratch_spheres_.size());
  result.radius = withRoundingMargin(result.radius, result.center);
  return result;
}

void SphereTree::refitBottomUp() {
  // Children always follow their parent in nodes_, so a backward sweep sees them first.
  for (std::uint32_t i = static_cast<std::uint32_t>(nodes_.size()); i-- > 0;) {
    const SphereNode& node = nodes_[i];
    if (node.isLeaf()) {
      setSphere(i, exactSphere(i));
    } else {
      scratch_spheres_.clear();
      for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
        scratch_spheres_.push_back(states_[c].sphere);
      }
      Sphere sphere = enclosingSphereOfSpheres(scratch_spheres_.data(), scratch_spheres_.size());
      sphere.radius = withRoundingMargin(sphere.radius, sphere.center);
      setSphere(i, sphere);
    }
  }
  counters_.spheres_updated = nodes_.size();
}

}  // namespace deformable_collision
