#pragma once

// Internal to the core: the least-squares registration of a shape-matching cluster, its
// goal and its residual d, shared by the body's files.

#include <Eigen/Core>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision::detail {

/// Fills the rest-shape moments of a cluster whose points, weights and offsets are set.
void precomputeMoments(Cluster& cluster, DeformationMode mode, double point_mass_kg);

/// Registers a cluster on its sums: the centre of mass, the warm-started rotation and the
/// least-squares transform (R alone for a rigid cluster) with its translation.
template <DeformationMode Mode>
void registerCluster(const Cluster& cluster, const ClusterSums& sums,
                     ClusterDeformation& deformation);

/// Whether a registration may carry on from `deformation` (its centre of mass as the
/// reference of the sums, its rotation as the warm start) for points whose centre lies
/// `shift` from that reference: not after absurd input, whose state is not finite or whose
/// centre is so far away that sums about it would lose the new points' digits.
bool carriedStateFits(const ClusterDeformation& deformation, const Eigen::Vector3d& shift,
                      double rebase_distance_m);

/// Registers a cluster on its observed points alone (those with finite `observed`
/// positions), with the moment matrices of that subset: points left at stale positions
/// would drag the fit. Starts from `fresh` instead of `deformation` where carriedStateFits
/// says no. A cluster with no observed point keeps its last transform if it is finite,
/// otherwise takes `fresh`.
template <DeformationMode Mode>
void registerObservedSubset(const Cluster& cluster, double point_mass_kg,
                            const std::vector<Eigen::Vector3d>& positions,
                            const std::vector<Eigen::Vector3d>& observed,
                            const ClusterDeformation& fresh, double rebase_distance_m,
                            ClusterDeformation& deformation);

/// The transform and translation a step pulls the cluster's points towards: the fit
/// blended with its rotation by beta (for a linear fit, after volume preservation if asked).
template <DeformationMode Mode>
void stepGoal(const Cluster& cluster, const ClusterDeformation& deformation, double beta,
              bool preserve_volume, Eigen::Matrix<double, 3, 9>& transform,
              Eigen::Vector3d& translation);

/// Sets every cluster's goal_deviation_bound_m to its residual d, the largest distance from
/// a point to its fitted position (docs/design.md, erratum 3), measured on the points.
template <DeformationMode Mode>
void measureFitResiduals(const std::vector<Cluster>& clusters,
                         const std::vector<Eigen::Vector3d>& positions, VectorWidth width,
                         std::vector<ClusterDeformation>& deformations);

}  // namespace deformable_collision::detail
