#include "deformable_collision/core/collision_query.h"

#include <algorithm>
#include <cmath>

namespace deformable_collision {
namespace {

/// Unit vector from b to a, or +z when the two coincide (any direction is then as good).
Eigen::Vector3d directionFrom(const Eigen::Vector3d& b, const Eigen::Vector3d& a) {
  const Eigen::Vector3d d = a - b;
  const double length = d.norm();
  return length > 0.0 ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitZ();
}

/// Closest point pair of two leaves closer than the contact distance, if any. Points of
/// leaf a are first tested against leaf b's sphere.
bool closestLeafPair(SphereTree& a, std::uint32_t leaf_a, SphereTree& b, std::uint32_t leaf_b,
                     double contact_distance_m, SphereContact& contact, QueryCounters& counters) {
  const SphereNode& na = a.node(leaf_a);
  const SphereNode& nb = b.node(leaf_b);
  const Sphere& sb = b.sphere(leaf_b);
  const auto& pa = a.body().positions();
  const auto& pb = b.body().positions();
  const auto& ia = a.pointIndices();
  const auto& ib = b.pointIndices();
  double best = contact_distance_m * contact_distance_m;
  bool found = false;
  const double reach = sb.radius + contact_distance_m;
  for (std::uint32_t s = na.first_point; s < na.first_point + na.point_count; ++s) {
    const Eigen::Vector3d& x = pa[ia[s]];
    ++counters.point_tests;
    if ((x - sb.center).squaredNorm() >= reach * reach) continue;
    for (std::uint32_t t = nb.first_point; t < nb.first_point + nb.point_count; ++t) {
      const Eigen::Vector3d& y = pb[ib[t]];
      ++counters.point_tests;
      const double distance_squared = (x - y).squaredNorm();
      if (distance_squared < best) {
        best = distance_squared;
        found = true;
        contact.point_a = ia[s];
        contact.point_b = ib[t];
      }
    }
  }
  if (!found) return false;
  const Eigen::Vector3d& x = pa[contact.point_a];
  const Eigen::Vector3d& y = pb[contact.point_b];
  contact.position = 0.5 * (x + y);
  contact.normal = directionFrom(y, x);
  contact.depth_m = contact_distance_m - std::sqrt(best);
  return true;
}

}  // namespace

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             std::vector<SphereContact>& contacts, QueryCounters& counters) {
  const bool to_leaves = level >= std::max(a.maxLevel(), b.maxLevel());
  const auto terminal = [level](const SphereNode& node) {
    return node.isLeaf() || static_cast<int>(node.level) >= level;
  };
  stack_.clear();
  stack_.emplace_back(0, 0);
  while (!stack_.empty()) {
    const auto [ia, ib] = stack_.back();
    stack_.pop_back();
    ++counters.node_pairs_tested;
    const Sphere& sa = a.sphere(ia);
    const Sphere& sb = b.sphere(ib);
    const double reach = sa.radius + sb.radius + contact_distance_m;
    const double distance_squared = (sa.center - sb.center).squaredNorm();
    if (!(distance_squared < reach * reach)) continue;

    const SphereNode& na = a.node(ia);
    const SphereNode& nb = b.node(ib);
    const bool stop_a = terminal(na);
    const bool stop_b = terminal(nb);
    if (stop_a && stop_b) {
      SphereContact contact;
      contact.node_a = ia;
      contact.node_b = ib;
      contact.level = std::max(na.level, nb.level);
      if (to_leaves) {
        if (closestLeafPair(a, ia, b, ib, contact_distance_m, contact, counters)) {
          contacts.push_back(contact);
        }
        continue;
      }
      contact.normal = directionFrom(sb.center, sa.center);
      const double distance = std::sqrt(distance_squared);
      contact.depth_m = reach - distance;
      // Midway between the surfaces (grown by half the contact distance each) along the normal.
      const Eigen::Vector3d surface_a = sa.center - (sa.radius + 0.5 * contact_distance_m) * contact.normal;
      const Eigen::Vector3d surface_b = sb.center + (sb.radius + 0.5 * contact_distance_m) * contact.normal;
      contact.position = 0.5 * (surface_a + surface_b);
      contacts.push_back(contact);
      continue;
    }
    // Descend the node that is not done, the larger one if both may go on.
    const bool split_a = !stop_a && (stop_b || sa.radius >= sb.radius);
    if (split_a) {
      for (std::uint32_t c = na.first_child + na.child_count; c-- > na.first_child;) {
        stack_.emplace_back(c, ib);
      }
    } else {
      for (std::uint32_t c = nb.first_child + nb.child_count; c-- > nb.first_child;) {
        stack_.emplace_back(ia, c);
      }
    }
  }
}

}  // namespace deformable_collision
