#include "deformable_collision/core/hierarchy/bounding_sphere.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace deformable_collision {
namespace {

/// Sphere through its support points, with the squared radius for the inside tests.
struct Ball {
  Ball() = default;
  Ball(const Eigen::Vector3d& c, double r2) : center(c), radius_squared(r2), limit(limitOf(r2)) {}

  /// The inside tests' bound, once per ball rather than per test. The relative slack
  /// absorbs rounding in the support computations; the exact radius is recomputed at the
  /// end, so the slack never costs enclosure.
  static double limitOf(double r2) {
    return r2 * (1.0 + 1e-12) + std::numeric_limits<double>::min();
  }

  bool contains(const Eigen::Vector3d& p) const { return (p - center).squaredNorm() <= limit; }

  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius_squared = -1.0;  // empty
  double limit = limitOf(-1.0);
};

Ball pointBall(const Eigen::Vector3d& a) { return {a, 0.0}; }

Ball diametralBall(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d center = 0.5 * (a + b);
  return {center, (a - center).squaredNorm()};
}

Ball farthestPairBall(const Eigen::Vector3d* p, int count) {
  Ball best = pointBall(p[0]);
  for (int i = 0; i < count; ++i) {
    for (int j = i + 1; j < count; ++j) {
      const Ball ball = diametralBall(p[i], p[j]);
      if (ball.radius_squared > best.radius_squared) best = ball;
    }
  }
  return best;
}

/// Smallest ball with a, b, c on its boundary: their circumcircle. Near-collinear points
/// have no meaningful circumcircle; their smallest enclosing ball is then the diametral
/// ball of the farthest pair.
Ball circumBall(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d normal = ab.cross(ac);
  const double normal_squared = normal.squaredNorm();
  if (!(normal_squared > 1e-20 * ab.squaredNorm() * ac.squaredNorm())) {
    const Eigen::Vector3d p[3] = {a, b, c};
    return farthestPairBall(p, 3);
  }
  const Eigen::Vector3d offset =
      (ab.squaredNorm() * ac - ac.squaredNorm() * ab).cross(normal) / (2.0 * normal_squared);
  return {a + offset, offset.squaredNorm()};
}

/// Smallest ball with a, b, c, d on its boundary: their circumsphere. For near-coplanar
/// points the smallest of the balls through three of them that holds the fourth is used.
Ball circumBall(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                const Eigen::Vector3d& d) {
  Eigen::Matrix3d edges;
  edges.row(0) = b - a;
  edges.row(1) = c - a;
  edges.row(2) = d - a;
  const double det = edges.determinant();
  const double scale = edges.row(0).norm() * edges.row(1).norm() * edges.row(2).norm();
  if (std::abs(det) > 1e-10 * scale) {
    const Eigen::Vector3d rhs(0.5 * edges.row(0).squaredNorm(), 0.5 * edges.row(1).squaredNorm(),
                              0.5 * edges.row(2).squaredNorm());
    const Eigen::Vector3d offset = edges.partialPivLu().solve(rhs);
    if (offset.allFinite()) return {a + offset, offset.squaredNorm()};
  }
  const Eigen::Vector3d p[4] = {a, b, c, d};
  Ball best(Eigen::Vector3d::Zero(), std::numeric_limits<double>::infinity());
  for (int skip = 0; skip < 4; ++skip) {
    Eigen::Vector3d q[3];
    for (int i = 0, n = 0; i < 4; ++i) {
      if (i != skip) q[n++] = p[i];
    }
    const Ball ball = circumBall(q[0], q[1], q[2]);
    if (ball.contains(p[skip]) && ball.radius_squared < best.radius_squared) best = ball;
  }
  return std::isfinite(best.radius_squared) ? best : farthestPairBall(p, 4);
}

/// The points less `origin`, in a fixed pseudo-random order, into scratch.shuffled.
void shuffleCentred(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& origin,
                    EnclosingSphereScratch& scratch) {
  const std::size_t n = points.size();
  std::vector<std::uint32_t>& order = scratch.order;
  order.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
  std::uint64_t state = 0x9E3779B97F4A7C15ull;
  for (std::size_t i = n; i > 1; --i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    std::swap(order[i - 1], order[(state >> 33) % i]);
  }
  scratch.shuffled.resize(n);
  for (std::size_t i = 0; i < n; ++i) scratch.shuffled[i] = points[order[i]] - origin;
}

}  // namespace

Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points,
                               EnclosingSphereScratch& scratch) {
  Sphere result;
  if (points.empty()) return result;
  const std::size_t n = points.size();
  // Centring on one of the points keeps the support computations exact to the set's own
  // size, not to its distance from the origin.
  const Eigen::Vector3d origin = points[0];
  shuffleCentred(points, origin, scratch);
  const auto at = [&](std::size_t i) -> const Eigen::Vector3d& { return scratch.shuffled[i]; };

  Ball ball = pointBall(at(0));
  for (std::size_t i = 1; i < n; ++i) {
    const Eigen::Vector3d pi = at(i);
    if (ball.contains(pi)) continue;
    ball = pointBall(pi);
    for (std::size_t j = 0; j < i; ++j) {
      const Eigen::Vector3d pj = at(j);
      if (ball.contains(pj)) continue;
      ball = diametralBall(pi, pj);
      for (std::size_t k = 0; k < j; ++k) {
        const Eigen::Vector3d pk = at(k);
        if (ball.contains(pk)) continue;
        ball = circumBall(pi, pj, pk);
        for (std::size_t l = 0; l < k; ++l) {
          const Eigen::Vector3d pl = at(l);
          if (ball.contains(pl)) continue;
          ball = circumBall(pi, pj, pk, pl);
        }
      }
    }
  }
  // The radius is measured from the stored centre in the callers' coordinates, so that the
  // sphere encloses every point as they will test it.
  result.center = origin + ball.center;
  double radius_squared = 0.0;
  for (const auto& p : points) {
    radius_squared = std::max(radius_squared, (p - result.center).squaredNorm());
  }
  // One root: a rounded root is monotone, so it is the largest of the points' distances.
  result.radius = std::sqrt(radius_squared);
  return result;
}

Sphere smallestEnclosingSphere(const std::vector<Eigen::Vector3d>& points) {
  EnclosingSphereScratch scratch;
  return smallestEnclosingSphere(points, scratch);
}

Sphere enclosingSphereOfSpheres(const Sphere* spheres, std::size_t count) {
  Sphere result;
  if (count == 0) return result;
  const Eigen::Vector3d origin = spheres[0].center;
  Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (std::size_t i = 0; i < count; ++i) {
    const double w = spheres[i].radius + std::numeric_limits<double>::min();
    weighted += w * (spheres[i].center - origin);
    weight += w;
  }
  result.center = origin + weighted / weight;
  for (std::size_t i = 0; i < count; ++i) {
    result.radius =
        std::max(result.radius, (spheres[i].center - result.center).norm() + spheres[i].radius);
  }
  return result;
}

}  // namespace deformable_collision
