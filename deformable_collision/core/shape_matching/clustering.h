#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// Splits a rest shape into `cluster_count` spatial clusters, deterministically: recursive
/// bisection of the point set along its longest axis, at the quantile that keeps the cluster
/// sizes balanced (ties broken by point index). Each cluster then also takes every point
/// inside its cell's bounding box grown by `overlap_ratio` times the cell's diagonal, so
/// neighbouring clusters share a seam of points and the object does not fall apart at it.
///
/// Returns, per cluster, the sorted indices of its points. Every point belongs to at least
/// one cluster.
/// @throw std::invalid_argument if `cluster_count` is not in [1, points.size()] or
///        `overlap_ratio` is negative or not finite.
std::vector<std::vector<std::uint32_t>> partitionIntoClusters(
    const std::vector<Eigen::Vector3d>& points, int cluster_count, double overlap_ratio);

}  // namespace deformable_collision
