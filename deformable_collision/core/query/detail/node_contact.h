// Internal to the core: the contact of two nodes above the leaves, from their spheres, as
// the pair query and the self-collision query report it. Not installed.
#pragma once

#include <algorithm>
#include <cstdint>

#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/query/collision_query.h"
#include "deformable_collision/core/query/detail/direction.h"

namespace deformable_collision {
namespace detail {

/// SphereContact::error_bound_m of a contact of two nodes above the leaves, from their
/// spheres, which hold a closest pair (x, y) of their points: (x + y) / 2 lies within
/// (r_a + r_b) / 2 of the centres' midpoint, from which `position` lies |r_b - r_a| / 2
/// along the normal; |x - y| lies between the spheres' gap (or 0) and the centres' distance
/// plus both radii, and the depth's error is at most its distance to the farther end.
inline double nodeContactErrorBound(const Sphere& a, const Sphere& b, double depth_m,
                                    double contact_distance_m) {
  const double centres_m = (a.center - b.center).norm();
  const double least_distance_m = std::max(0.0, centres_m - a.radius - b.radius);
  const double greatest_distance_m = centres_m + a.radius + b.radius;
  const double depth_error_m = std::max(depth_m - (contact_distance_m - greatest_distance_m),
                                        contact_distance_m - least_distance_m - depth_m);
  const double bound_m = std::max({a.radius, b.radius, depth_error_m});
  // The few sums above round by far less than this margin, even 1e5 m from the origin.
  const double magnitude_m =
      std::max(a.center.cwiseAbs().maxCoeff(), b.center.cwiseAbs().maxCoeff());
  return bound_m + 1e-12 * (bound_m + magnitude_m);
}

/// The contact of nodes `node_a` and `node_b` (spheres `sa`, `sb`, the deeper at `level`)
/// with depth `depth_m`: midway between their surfaces grown by half the contact distance,
/// along the normal from b's centre to a's.
inline SphereContact nodeContact(std::uint32_t node_a, std::uint32_t node_b, std::uint16_t level,
                                 const Sphere& sa, const Sphere& sb, double depth_m,
                                 double contact_distance_m) {
  SphereContact contact;
  contact.node_a = node_a;
  contact.node_b = node_b;
  contact.level = level;
  contact.normal = directionFrom(sb.center, sa.center);
  contact.depth_m = depth_m;
  const Eigen::Vector3d surface_a =
      sa.center - (sa.radius + 0.5 * contact_distance_m) * contact.normal;
  const Eigen::Vector3d surface_b =
      sb.center + (sb.radius + 0.5 * contact_distance_m) * contact.normal;
  contact.position = 0.5 * (surface_a + surface_b);
  contact.error_bound_m = nodeContactErrorBound(sa, sb, depth_m, contact_distance_m);
  return contact;
}

}  // namespace detail
}  // namespace deformable_collision
