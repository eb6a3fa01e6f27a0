#include "deformable_collision/core/common/nearest_point_index.h"

#include <algorithm>
#include <limits>

namespace deformable_collision {

void NearestPointIndex::build(const std::vector<Eigen::Vector3d>& points) {
  points_ = &points;
  order_.resize(points.size());
  split_axis_.resize(points.size());
  for (std::uint32_t i = 0; i < order_.size(); ++i) order_[i] = i;
  split(0, static_cast<std::uint32_t>(order_.size()));
  ordered_.resize(points.size());
  for (std::uint32_t s = 0; s < order_.size(); ++s) ordered_[s] = points[order_[s]];
}

// The widest coordinate of the range is split at its median: the ranges halve, and the
// tree's depth stays log2 of the size whatever the points' layout (no recursion deeper
// than about 32).
void NearestPointIndex::split(std::uint32_t begin, std::uint32_t end) {
  if (end - begin <= kLeafSize) return;
  const std::vector<Eigen::Vector3d>& points = *points_;
  Eigen::Vector3d low = points[order_[begin]];
  Eigen::Vector3d high = low;
  for (std::uint32_t s = begin + 1; s < end; ++s) {
    low = low.cwiseMin(points[order_[s]]);
    high = high.cwiseMax(points[order_[s]]);
  }
  int axis = 0;
  (high - low).maxCoeff(&axis);
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(
      order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
      [&](std::uint32_t i, std::uint32_t j) { return points[i][axis] < points[j][axis]; });
  split_axis_[mid] = static_cast<std::uint8_t>(axis);
  split(begin, mid);
  split(mid + 1, end);
}

bool NearestPointIndex::nearest(const Eigen::Vector3d& query, Nearest& found) const {
  if (order_.empty()) return false;
  found.squared_distance_m2 = std::numeric_limits<double>::infinity();
  search(0, static_cast<std::uint32_t>(order_.size()), query, found);
  return true;
}

bool NearestPointIndex::nearestWithin(const Eigen::Vector3d& query, double below_squared_m2,
                                      Nearest& found) const {
  found.squared_distance_m2 = below_squared_m2;
  if (order_.empty()) return false;
  search(0, static_cast<std::uint32_t>(order_.size()), query, found);
  return found.squared_distance_m2 < below_squared_m2;
}

void NearestPointIndex::search(std::uint32_t begin, std::uint32_t end, const Eigen::Vector3d& query,
                               Nearest& best) const {
  if (end - begin <= kLeafSize) {
    for (std::uint32_t s = begin; s < end; ++s) {
      const double squared = (ordered_[s] - query).squaredNorm();
      if (squared < best.squared_distance_m2) best = {order_[s], squared};
    }
    return;
  }
  const std::uint32_t mid = begin + (end - begin) / 2;
  const Eigen::Vector3d& median = ordered_[mid];
  const double squared = (median - query).squaredNorm();
  if (squared < best.squared_distance_m2) best = {order_[mid], squared};
  const int axis = split_axis_[mid];
  const double offset = query[axis] - median[axis];
  // The query's side first: its nearest point there usually rules the other side out.
  const bool below = offset < 0.0;
  if (below) {
    search(begin, mid, query, best);
  } else {
    search(mid + 1, end, query, best);
  }
  if (offset * offset < best.squared_distance_m2) {
    if (below) {
      search(mid + 1, end, query, best);
    } else {
      search(begin, mid, query, best);
    }
  }
}

}  // namespace deformable_collision
