#pragma once

#include <Eigen/Core>
#include <vector>

namespace deformable_collision {

struct Sphere {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// Smallest sphere enclosing `points` (Welzl's algorithm in its iterative form, over a
/// fixed pseudo-random order, so the same input always gives the same sphere). Robust to
/// duplicates and to collinear, coplanar, tiny and huge point sets: the work is done in
/// coordinates centred on the set, degenerate support sets fall back to the smallest of
/// their sub-spheres, and the final radius is the exact largest distance from the centre,
/// so every point is enclosed whatever the rounding. `order` is scratch (resized).
/// An empty set gives a zero sphere at the origin.
Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points,
                               std::vector<std::uint32_t>& order);

/// Convenience overload with its own scratch.
Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points);

/// A sphere enclosing all `spheres` (not necessarily the smallest): centred on the
/// radius-weighted mean of the centres, radius the largest reach from there.
Sphere enclosingSphereOfSpheres(const Sphere* spheres, std::size_t count);

}  // namespace deformable_collision
