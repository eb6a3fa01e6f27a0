#include "deformable_collision/core/query/distance_query.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/query/detail/direction.h"

namespace deformable_collision {
namespace {

double sphereGap(const Sphere& a, const Sphere& b) {
  return std::max(0.0, (a.center - b.center).norm() - a.radius - b.radius);
}

}  // namespace

struct HierarchyDistance::Descent {
  SphereTree& a;
  SphereTree& b;
  int level;
  bool exact;  ///< To the points: the level is at or below both trees' leaves.
  std::vector<PendingPair>& queue;
  QueryCounters& counters;
  /// The best distance so far (squared at the leaves), and whether one was found.
  double best_m;
  std::optional<ClosestPoints> best;

  static bool later(const PendingPair& x, const PendingPair& y) { return x.gap_m > y.gap_m; }

  bool endsDescent(const NodeState& node) const {
    return exact ? node.isLeaf() : endsDescentToLevel(node, level);
  }

  /// Queues the pair if its spheres' gap, and its parents', can still beat the best.
  void offer(std::uint32_t node_a, std::uint32_t node_b, double parents_gap_m) {
    ++counters.node_pairs_tested;
    const double gap_m =
        std::max(parents_gap_m, sphereGap(a.current(node_a).sphere, b.current(node_b).sphere));
    if (gap_m > best_m || (best && gap_m == best_m)) return;
    queue.push_back({gap_m, node_a, node_b});
    std::push_heap(queue.begin(), queue.end(), later);
  }

  /// Splits the pair at the node that goes on (the larger if both do).
  void split(const PendingPair& pair) {
    const NodeState& node_a = a.current(pair.node_a);
    const NodeState& node_b = b.current(pair.node_b);
    const bool split_a = !endsDescent(node_a) &&
                         (endsDescent(node_b) || node_a.sphere.radius >= node_b.sphere.radius);
    const NodeState& parent = split_a ? node_a : node_b;
    const std::uint32_t first = parent.first_child, count = parent.child_count;
    for (std::uint32_t c = first; c < first + count; ++c) {
      if (split_a) {
        offer(c, pair.node_b, pair.gap_m);
      } else {
        offer(pair.node_a, c, pair.gap_m);
      }
    }
  }

  /// Above the leaves, the first pair to end its descent holds the level's least gap.
  void takeSpheres(const PendingPair& pair) {
    const Sphere& sphere_a = a.current(pair.node_a).sphere;
    const Sphere& sphere_b = b.current(pair.node_b).sphere;
    ClosestPoints result;
    result.node_a = pair.node_a;
    result.node_b = pair.node_b;
    result.normal = directionFrom(sphere_b.center, sphere_a.center);
    result.point_a = sphere_a.center - sphere_a.radius * result.normal;
    result.point_b = sphere_b.center + sphere_b.radius * result.normal;
    result.distance_m = pair.gap_m;
    const double greatest_m =
        (sphere_a.center - sphere_b.center).norm() + sphere_a.radius + sphere_b.radius;
    // The sums round by far less than this margin, even 1e5 m from the origin.
    const double magnitude_m =
        std::max(sphere_a.center.cwiseAbs().maxCoeff(), sphere_b.center.cwiseAbs().maxCoeff());
    result.error_bound_m = greatest_m - pair.gap_m + 1e-12 * (greatest_m + magnitude_m);
    best = result;
  }

  /// At the leaves, the pair's closest points, if closer than the best so far.
  void takePoints(const PendingPair& pair) {
    const NodeState& leaf_a = a.current(pair.node_a);
    const NodeState& leaf_b = b.current(pair.node_b);
    const auto& positions_a = a.leafPositions();
    const auto& positions_b = b.leafPositions();
    counters.point_tests += leaf_a.point_count * leaf_b.point_count;
    ++counters.leaf_pairs_tested;
    for (std::uint32_t s = leaf_a.first_point; s < leaf_a.first_point + leaf_a.point_count; ++s) {
      const Eigen::Vector3d x = positions_a.col(s);
      for (std::uint32_t t = leaf_b.first_point; t < leaf_b.first_point + leaf_b.point_count; ++t) {
        const double distance_m = (x - positions_b.col(t)).norm();
        if (distance_m > best_m || (best && distance_m >= best_m)) continue;
        ClosestPoints result;
        result.distance_m = distance_m;
        result.point_a = x;
        result.point_b = positions_b.col(t);
        result.normal = directionFrom(result.point_b, result.point_a);
        result.node_a = pair.node_a;
        result.node_b = pair.node_b;
        result.index_a = a.pointIndices()[s];
        result.index_b = b.pointIndices()[t];
        best = result;
        best_m = distance_m;
      }
    }
  }

  void run() {
    offer(0, 0, 0.0);
    while (!queue.empty()) {
      std::pop_heap(queue.begin(), queue.end(), later);
      const PendingPair pair = queue.back();
      queue.pop_back();
      // The queue gives the least gap first: nothing left can beat the best.
      if (best && pair.gap_m >= best_m) break;
      const bool ends = endsDescent(a.current(pair.node_a)) && endsDescent(b.current(pair.node_b));
      if (!ends) {
        split(pair);
      } else if (exact) {
        takePoints(pair);
      } else {
        takeSpheres(pair);
        break;
      }
    }
    queue.clear();
  }
};

std::optional<ClosestPoints> HierarchyDistance::closest(SphereTree& a, SphereTree& b, int level,
                                                        double max_distance_m,
                                                        QueryCounters& counters) {
  if (!(std::isfinite(max_distance_m) && max_distance_m >= 0.0)) {
    throw std::invalid_argument("the maximum distance " + std::to_string(max_distance_m) +
                                " m must be finite and >= 0");
  }
  const bool exact = level >= std::max(a.maxLevel(), b.maxLevel());
  Descent descent{a, b, level, exact, queue_, counters, max_distance_m, std::nullopt};
  descent.run();
  return descent.best;
}

}  // namespace deformable_collision
