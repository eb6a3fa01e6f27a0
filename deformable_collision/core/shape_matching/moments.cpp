#include "deformable_collision/core/shape_matching/detail/kernels.h"

#include <algorithm>

#include "deformable_collision/core/shape_matching/detail/wide.h"

namespace deformable_collision::detail {

template <int K, MomentTerms Terms>
Moments<K> accumulate(const Cluster& cluster, std::size_t begin, std::size_t end,
                      const double* weights, const std::vector<Eigen::Vector3d>& positions,
                      const std::vector<Eigen::Vector3d>& velocities,
                      const Eigen::Vector3d& reference, [[maybe_unused]] VectorWidth width) {
  PartialMoments<K> sums;
  std::size_t j = begin;
#if defined(__GNUC__) && defined(__x86_64__)
  if (width == VectorWidth::kAvx512) {
    j = accumulateAvx512<K, Terms>(cluster, begin, end, weights, positions.data(),
                                   velocities.data(), reference, sums);
  } else if (width == VectorWidth::kAvx2) {
    j = accumulateAvx2<K, Terms>(cluster, begin, end, weights, positions.data(), velocities.data(),
                                 reference, sums);
  }
#endif
  // The wide vectors took whole blocks of eight, so slot j + n goes to part n.
  for (; j < end; j += kParts) {
    const int lanes = static_cast<int>(std::min<std::size_t>(kParts, end - j));
    SlotLanes<K> slots;
    for (int n = 0; n < lanes; ++n) {
      const std::uint32_t i = cluster.points[j + n];
      double features[K];
      featureArray<K>(cluster.rest_offsets[j + n], features);
      slots.set(n, features, positions[i].data(),
                Terms == MomentTerms::kAtRest ? nullptr : velocities[i].data(), reference);
      if (weights != nullptr) slots.w[n] = weights[j + n - begin];
    }
    if (weights != nullptr) {
      sums.template addLanes<true, Terms>(lanes, slots);
    } else {
      sums.template addLanes<false, Terms>(lanes, slots);
    }
  }
  return sums.total();
}

template <int K, MomentTerms Terms>
ClusterSums clusterSums(const Cluster& cluster, double point_mass_kg,
                        const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<Eigen::Vector3d>& velocities,
                        const Eigen::Vector3d& reference, VectorWidth width) {
  // Exclusive slots are summed unweighted and scaled by the point mass once.
  const Moments<K> exclusive = accumulate<K, Terms>(cluster, 0, cluster.exclusive_count, nullptr,
                                                    positions, velocities, reference, width);
  const Moments<K> shared = accumulate<K, Terms>(
      cluster, cluster.exclusive_count, cluster.points.size(), cluster.shared_weights_kg.data(),
      positions, velocities, reference, width);
  ClusterSums sums;
  sums.reference = reference;
  for (int r = 0; r < 3; ++r) {
    sums.offset[r] = point_mass_kg * exclusive.offset[r] + shared.offset[r];
    sums.momentum[r] = point_mass_kg * exclusive.momentum[r] + shared.momentum[r];
    sums.angular_momentum[r] =
        point_mass_kg * exclusive.angular_momentum[r] + shared.angular_momentum[r];
    for (int c = 0; c < K; ++c) {
      sums.offset_features(r, c) =
          point_mass_kg * exclusive.offset_features[r][c] + shared.offset_features[r][c];
    }
    for (int c = 0; c < 3; ++c) {
      sums.second_moment(r, c) =
          point_mass_kg * exclusive.second_moment[r][c] + shared.second_moment[r][c];
    }
  }
  return sums;
}

// The sums for every feature count and set of terms the body uses.
#define DEFORMABLE_COLLISION_SHAPE_MATCHING_ACCUMULATE(K, TERMS)                \
  template Moments<K> accumulate<K, MomentTerms::TERMS>(                        \
      const Cluster&, std::size_t, std::size_t, const double*,                  \
      const std::vector<Eigen::Vector3d>&, const std::vector<Eigen::Vector3d>&, \
      const Eigen::Vector3d&, VectorWidth);
#define DEFORMABLE_COLLISION_SHAPE_MATCHING_CLUSTER_SUMS(K, TERMS) \
  template ClusterSums clusterSums<K, MomentTerms::TERMS>(         \
      const Cluster&, double, const std::vector<Eigen::Vector3d>&, \
      const std::vector<Eigen::Vector3d>&, const Eigen::Vector3d&, VectorWidth);
#define DEFORMABLE_COLLISION_SHAPE_MATCHING_MOMENTS(K)                  \
  DEFORMABLE_COLLISION_SHAPE_MATCHING_ACCUMULATE(K, kMomentum)          \
  DEFORMABLE_COLLISION_SHAPE_MATCHING_ACCUMULATE(K, kMomentumAndSpin)   \
  DEFORMABLE_COLLISION_SHAPE_MATCHING_CLUSTER_SUMS(K, kMomentumAndSpin) \
  DEFORMABLE_COLLISION_SHAPE_MATCHING_CLUSTER_SUMS(K, kAtRest)
DEFORMABLE_COLLISION_SHAPE_MATCHING_MOMENTS(3)
DEFORMABLE_COLLISION_SHAPE_MATCHING_MOMENTS(9)
#undef DEFORMABLE_COLLISION_SHAPE_MATCHING_MOMENTS
#undef DEFORMABLE_COLLISION_SHAPE_MATCHING_CLUSTER_SUMS
#undef DEFORMABLE_COLLISION_SHAPE_MATCHING_ACCUMULATE

}  // namespace deformable_collision::detail
