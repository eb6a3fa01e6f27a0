#pragma once

// Internal to the core: the AVX-512 and AVX2 twins of shape matching's per-point passes,
// eight or four slots per instruction with the same bits as the portable code. Each handles
// whole blocks (of eight where the sums' parts are concerned) and returns the first slot left
// for the portable code. Callable only where widestVectors() reaches their width, for a body
// of at most kMostWidePoints points.

#include <Eigen/Core>
#include <cstddef>
#include <utility>

#include "deformable_collision/core/shape_matching/detail/kernels.h"

namespace deformable_collision::detail {

/// The gathers take a point's index times 3 as a 32-bit offset in doubles.
constexpr std::size_t kMostWidePoints = std::size_t{1} << 29;

#if defined(__GNUC__) && defined(__x86_64__)
// The kernels take the goal kernel, the motion and the reference by value: a local whose
// address went out of line could alias the points the portable loops then write, and those
// loops would read it again after every point.

/// The first slots of [begin, end) into `sums`, which hold nothing yet; `weights` as for
/// accumulate.
template <int K, MomentTerms Terms>
__attribute__((target("avx512f"))) std::size_t accumulateAvx512(
    const Cluster& cluster, std::size_t begin, std::size_t end, const double* weights,
    const Eigen::Vector3d* positions, const Eigen::Vector3d* velocities,
    const Eigen::Vector3d reference, PartialMoments<K>& sums);

/// The cluster's first exclusive slots: each point makes the step's move (StepMotion::move)
/// and is added to `sums`, which hold nothing yet.
template <int K, bool Damped>
__attribute__((target("avx512f"))) std::size_t moveExclusiveAvx512(
    const GoalKernel<K> kernel, const Cluster& cluster, const StepMotion motion,
    Eigen::Vector3d* positions, Eigen::Vector3d* velocities, const Eigen::Vector3d reference,
    PartialMoments<K>& sums);

/// Adds the goals of the cluster's first shared slots to `goal_sums`.
template <int K>
__attribute__((target("avx512f"))) std::size_t addSharedGoalsAvx512(const GoalKernel<K> kernel,
                                                                    const Cluster& cluster,
                                                                    Eigen::Vector3d* goal_sums);

/// The largest squaredGoalDistance over the cluster's first slots, and the first slot left.
template <int K>
__attribute__((target("avx512f"))) std::pair<double, std::size_t> largestSquaredGoalDistanceAvx512(
    const GoalKernel<K> kernel, const Cluster& cluster, const Eigen::Vector3d* positions);

/// accumulateAvx512 on four lanes.
template <int K, MomentTerms Terms>
__attribute__((target("avx2"))) std::size_t accumulateAvx2(
    const Cluster& cluster, std::size_t begin, std::size_t end, const double* weights,
    const Eigen::Vector3d* positions, const Eigen::Vector3d* velocities,
    const Eigen::Vector3d reference, PartialMoments<K>& sums);

/// moveExclusiveAvx512 on four lanes.
template <int K, bool Damped>
__attribute__((target("avx2"))) std::size_t moveExclusiveAvx2(
    const GoalKernel<K> kernel, const Cluster& cluster, const StepMotion motion,
    Eigen::Vector3d* positions, Eigen::Vector3d* velocities, const Eigen::Vector3d reference,
    PartialMoments<K>& sums);

/// addSharedGoalsAvx512 on four lanes.
template <int K>
__attribute__((target("avx2"))) std::size_t addSharedGoalsAvx2(const GoalKernel<K> kernel,
                                                               const Cluster& cluster,
                                                               Eigen::Vector3d* goal_sums);

/// largestSquaredGoalDistanceAvx512 on four lanes.
template <int K>
__attribute__((target("avx2"))) std::pair<double, std::size_t> largestSquaredGoalDistanceAvx2(
    const GoalKernel<K> kernel, const Cluster& cluster, const Eigen::Vector3d* positions);
#endif

}  // namespace deformable_collision::detail
