#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {

struct Sphere {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// What smallestEnclosingSphere works in, resized to the points: a caller that keeps it
/// measures without allocating once it has held the largest set.
struct EnclosingSphereScratch {
  std::vector<std::uint32_t> order;
  /// The points in that order, centred: the passes over the points read them in order,
  /// not scattered over memory (a large set's points each miss the cache otherwise).
  std::vector<Eigen::Vector3d> shuffled;
};

/// Smallest sphere enclosing `points` (Welzl's algorithm in its iterative form, over a
/// fixed pseudo-random order, so the same input always gives the same sphere). Robust to
/// duplicates and to collinear, coplanar, tiny and huge point sets: the work is done in
/// coordinates centred on the set, degenerate support sets fall back to the smallest of
/// their sub-spheres, and the final radius is the exact largest distance from the centre,
/// so every point is enclosed whatever the rounding. An empty set gives a zero sphere at
/// the origin.
Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points,
                               EnclosingSphereScratch& scratch);

/// Convenience overload with its own scratch.
Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points);

/// A sphere enclosing all `spheres` (not necessarily the smallest): centred on the
/// radius-weighted mean of the centres, radius the largest reach from there.
Sphere enclosingSphereOfSpheres(const Sphere* spheres, std::size_t count);

}  // namespace deformable_collision
