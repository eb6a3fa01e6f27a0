#include "deformable_collision/core/shape_matching/clustering.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace deformable_collision {
namespace {

using Indices = std::vector<std::uint32_t>;

Eigen::AlignedBox3d boundsOf(const std::vector<Eigen::Vector3d>& points, const Indices& indices) {
  Eigen::AlignedBox3d box;
  for (const auto i : indices) box.extend(points[i]);
  return box;
}

void bisect(const std::vector<Eigen::Vector3d>& points, Indices indices, int cluster_count,
            std::vector<Indices>& cells) {
  if (cluster_count == 1) {
    std::sort(indices.begin(), indices.end());
    cells.push_back(std::move(indices));
    return;
  }
  const Eigen::AlignedBox3d box = boundsOf(points, indices);
  Eigen::Index axis = 0;
  box.sizes().maxCoeff(&axis);
  const int first_count = cluster_count / 2;
  // Proportional split keeps every cluster's share of points equal for any cluster_count.
  const std::size_t split = indices.size() * first_count / cluster_count;
  const auto before = [&](std::uint32_t a, std::uint32_t b) {
    const double pa = points[a][axis];
    const double pb = points[b][axis];
    return pa < pb || (pa == pb && a < b);
  };
  std::nth_element(indices.begin(), indices.begin() + split, indices.end(), before);
  Indices second(indices.begin() + split, indices.end());
  indices.resize(split);
  bisect(points, std::move(indices), first_count, cells);
  bisect(points, std::move(second), cluster_count - first_count, cells);
}

/// Per cell, the points in its box grown by `overlap_ratio` of its diagonal, ascending. Only
/// the cells whose own boxes meet the grown box can hold such points: a point is tested
/// against the clusters near it, not against all of them.
std::vector<Indices> grownClusters(const std::vector<Eigen::Vector3d>& points,
                                   const std::vector<Indices>& cells, double overlap_ratio) {
  std::vector<Eigen::AlignedBox3d> boxes;
  boxes.reserve(cells.size());
  for (const auto& cell : cells) boxes.push_back(boundsOf(points, cell));
  std::vector<Indices> clusters(cells.size());
  for (std::size_t k = 0; k < cells.size(); ++k) {
    Eigen::AlignedBox3d grown = boxes[k];
    const double margin = overlap_ratio * grown.diagonal().norm();
    grown.min().array() -= margin;
    grown.max().array() += margin;
    for (std::size_t j = 0; j < cells.size(); ++j) {
      if (!grown.intersects(boxes[j])) continue;
      for (const auto i : cells[j]) {
        if (grown.contains(points[i])) clusters[k].push_back(i);
      }
    }
    std::sort(clusters[k].begin(), clusters[k].end());
  }
  return clusters;
}

}  // namespace

std::vector<std::vector<std::uint32_t>> partitionIntoClusters(
    const std::vector<Eigen::Vector3d>& points, int cluster_count, double overlap_ratio) {
  if (cluster_count < 1 || static_cast<std::size_t>(cluster_count) > points.size()) {
    throw std::invalid_argument("cluster count " + std::to_string(cluster_count) +
                                " must be in [1, " + std::to_string(points.size()) +
                                "] (the number of points)");
  }
  if (!(overlap_ratio >= 0.0) || !std::isfinite(overlap_ratio)) {
    throw std::invalid_argument("cluster overlap ratio " + std::to_string(overlap_ratio) +
                                " must be finite and >= 0");
  }
  Indices all(points.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  std::vector<Indices> cells;
  cells.reserve(cluster_count);
  bisect(points, std::move(all), cluster_count, cells);
  if (cluster_count == 1 || overlap_ratio == 0.0) return cells;
  return grownClusters(points, cells, overlap_ratio);
}

}  // namespace deformable_collision
