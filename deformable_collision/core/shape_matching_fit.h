#pragma once

// Internal to the core: the least-squares registration of a shape-matching cluster, its
// goal and its residual d, shared by the body's files.

#include <Eigen/Core>
#include <vector>

#include "deformable_collision/core/shape_matching.h"

namespace deformable_collision::detail {

/// Fills the rest-shape moments of a cluster whose points, weights and offsets are set.
void precomputeMoments(Cluster& cluster, DeformationMode mode, double point_mass_kg);

/// Registers a cluster on its sums: the centre of mass, the warm-started rotation and the
/// least-squares transform (R alone for a rigid cluster) with its translation.
template <DeformationMode Mode>
void registerCluster(const Cluster& cluster, const ClusterSums& sums,
                     ClusterDeformation& deformation);

/// Registers a cluster on its observed points alone (those with finite `observed`
/// positions), with the moment matrices of that subset: points left at stale positions
/// would drag the fit. A cluster with no observed point keeps its last transform.
template <DeformationMode Mode>
void registerObservedSubset(const Cluster& cluster, double point_mass_kg,
                            const std::vector<Eigen::Vector3d>& positions,
                            const std::vector<Eigen::Vector3d>& observed,
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
                         const std::vector<Eigen::Vector3d>& positions, bool wide_vectors,
                         std::vector<ClusterDeformation>& deformations);

}  // namespace deformable_collision::detail
