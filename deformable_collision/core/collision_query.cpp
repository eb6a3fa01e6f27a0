#include "deformable_collision/core/collision_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace deformable_collision {
namespace {

/// Unit vector from b to a, or +z when the two coincide (any direction is then as good).
Eigen::Vector3d directionFrom(const Eigen::Vector3d& b, const Eigen::Vector3d& a) {
  const Eigen::Vector3d d = a - b;
  const double length = d.norm();
  return length > 0.0 ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitZ();
}

/// Squared distance from (x, y, z) to the nearest of `count` points given by their
/// coordinate arrays.
double nearestSquaredDistance(const double* xs, const double* ys, const double* zs,
                              std::uint32_t count, double x, double y, double z) {
  double nearest = std::numeric_limits<double>::infinity();
  std::uint32_t t = 0;
#if defined(__SSE2__)
  // Two points per instruction: this is the query's innermost loop. The sums are formed in
  // the scalar loop's order, so both give the same bits.
  const __m128d px = _mm_set1_pd(x);
  const __m128d py = _mm_set1_pd(y);
  const __m128d pz = _mm_set1_pd(z);
  __m128d pair_nearest = _mm_set1_pd(nearest);
  for (; t + 2 <= count; t += 2) {
    const __m128d dx = _mm_sub_pd(px, _mm_loadu_pd(xs + t));
    const __m128d dy = _mm_sub_pd(py, _mm_loadu_pd(ys + t));
    const __m128d dz = _mm_sub_pd(pz, _mm_loadu_pd(zs + t));
    const __m128d squared = _mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)), _mm_mul_pd(dz, dz));
    pair_nearest = _mm_min_pd(pair_nearest, squared);
  }
  nearest = std::min(_mm_cvtsd_f64(pair_nearest), _mm_cvtsd_f64(_mm_unpackhi_pd(pair_nearest, pair_nearest)));
#endif
  for (; t < count; ++t) {
    const double dx = x - xs[t], dy = y - ys[t], dz = z - zs[t];
    nearest = std::min(nearest, dx * dx + dy * dy + dz * dz);
  }
  return nearest;
}

/// Closest point pair of two leaves closer than the contact distance, if any. Points of
/// leaf a are first tested against leaf b's sphere.
bool closestLeafPair(const SphereTree& a, const NodeState& leaf_a, const SphereTree& b,
                     const NodeState& leaf_b, double contact_distance_m, SphereContact& contact,
                     QueryCounters& counters) {
  const std::uint32_t count_b = leaf_b.point_count;
  const auto& pa = a.leafPositions();
  const auto& pb = b.leafPositions();
  const double* bx = &pb(0, leaf_b.first_point);
  const double* by = &pb(1, leaf_b.first_point);
  const double* bz = &pb(2, leaf_b.first_point);
  const Sphere& sphere_b = leaf_b.sphere;
  const double reach = sphere_b.radius + contact_distance_m;
  double best = contact_distance_m * contact_distance_m;
  std::uint32_t best_a = leaf_a.first_point + leaf_a.point_count;
  for (std::uint32_t s = leaf_a.first_point; s < leaf_a.first_point + leaf_a.point_count; ++s) {
    const double x = pa(0, s), y = pa(1, s), z = pa(2, s);
    if ((Eigen::Vector3d(x, y, z) - sphere_b.center).squaredNorm() >= reach * reach) continue;
    counters.point_tests += count_b;
    const double nearest = nearestSquaredDistance(bx, by, bz, count_b, x, y, z);
    if (nearest < best) {
      best = nearest;
      best_a = s;
    }
  }
  counters.point_tests += leaf_a.point_count;
  if (best_a == leaf_a.first_point + leaf_a.point_count) return false;
  // Which of b's points is nearest to the closest point of a: the first at that distance.
  std::uint32_t best_b = 0;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::uint32_t t = 0; t < count_b; ++t) {
    const double dx = pa(0, best_a) - bx[t], dy = pa(1, best_a) - by[t], dz = pa(2, best_a) - bz[t];
    const double distance_squared = dx * dx + dy * dy + dz * dz;
    if (distance_squared < nearest) {
      nearest = distance_squared;
      best_b = t;
    }
  }
  contact.point_a = a.pointIndices()[best_a];
  contact.point_b = b.pointIndices()[leaf_b.first_point + best_b];
  const Eigen::Vector3d& x = a.body().positions()[contact.point_a];
  const Eigen::Vector3d& y = b.body().positions()[contact.point_b];
  contact.position = 0.5 * (x + y);
  contact.normal = directionFrom(y, x);
  contact.depth_m = contact_distance_m - std::sqrt(best);
  return true;
}

/// Whether two spheres come closer than the contact distance.
bool withinReach(const Sphere& a, const Sphere& b, double contact_distance_m) {
  const double reach = a.radius + b.radius + contact_distance_m;
  return (a.center - b.center).squaredNorm() < reach * reach;
}

}  // namespace

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             std::vector<SphereContact>& contacts, QueryCounters& counters) {
  const bool to_leaves = level >= std::max(a.maxLevel(), b.maxLevel());
  // Branch-free where the outcome is a coin toss: which pairs end, which are in reach.
  const auto terminal = [level](const NodeState& node) {
    return node.isLeaf() | (static_cast<int>(node.level) >= level);
  };
  // Pairs are tested before they are stacked, so the stack holds only pairs within reach.
  ++counters.node_pairs_tested;
  if (!withinReach(a.sphere(0), b.sphere(0), contact_distance_m)) return;
  if (stack_.empty()) stack_.resize(1);
  stack_[0] = {0, 0};
  std::size_t stacked = 1;
  while (stacked > 0) {
    const auto [ia, ib] = stack_[--stacked];
    const NodeState& na = a.current(ia);
    const NodeState& nb = b.current(ib);
    const bool stop_a = terminal(na);
    const bool stop_b = terminal(nb);
    if (stop_a && stop_b) {
      SphereContact contact;
      contact.node_a = ia;
      contact.node_b = ib;
      contact.level = std::max(na.level, nb.level);
      if (to_leaves) {
        if (closestLeafPair(a, na, b, nb, contact_distance_m, contact, counters)) {
          contacts.push_back(contact);
        }
        continue;
      }
      const Sphere& sa = na.sphere;
      const Sphere& sb = nb.sphere;
      contact.normal = directionFrom(sb.center, sa.center);
      const double distance = (sa.center - sb.center).norm();
      contact.depth_m = sa.radius + sb.radius + contact_distance_m - distance;
      // Midway between the surfaces (grown by half the contact distance each) along the normal.
      const Eigen::Vector3d surface_a = sa.center - (sa.radius + 0.5 * contact_distance_m) * contact.normal;
      const Eigen::Vector3d surface_b = sb.center + (sb.radius + 0.5 * contact_distance_m) * contact.normal;
      contact.position = 0.5 * (surface_a + surface_b);
      contacts.push_back(contact);
      continue;
    }
    // Descend the node that is not done, the larger one if both may go on. Children are
    // stacked last first, so that contacts come in depth-first order; each is written on
    // top and kept if it is within reach. The stack grows only in the first queries.
    const bool split_a = !stop_a && (stop_b || na.sphere.radius >= nb.sphere.radius);
    const NodeState& split = split_a ? na : nb;
    if (stack_.size() < stacked + split.child_count) {
      stack_.resize(std::max(2 * stack_.size(), stacked + split.child_count));
    }
    counters.node_pairs_tested += split.child_count;
    if (split_a) {
      for (std::uint32_t c = na.first_child + na.child_count; c-- > na.first_child;) {
        stack_[stacked] = {c, ib};
        stacked += withinReach(a.sphere(c), nb.sphere, contact_distance_m);
      }
    } else {
      for (std::uint32_t c = nb.first_child + nb.child_count; c-- > nb.first_child;) {
        stack_[stacked] = {ia, c};
        stacked += withinReach(na.sphere, b.sphere(c), contact_distance_m);
      }
    }
  }
}

}  // namespace deformable_collision
