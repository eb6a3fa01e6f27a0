#pragma once
// True surfaces for the tests of surface sampling (test_surface_sampling.cpp,
// test_robot_links.cpp): the distance of a point to a shape's surface, and points drawn
// uniformly from that surface.

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "deformable_collision/core/common/nearest_point_index.h"
#include "deformable_collision/core/robot/surface_sampling.h"

namespace deformable_collision {
namespace test {

/// A true surface: the distance of a point to it, and a point drawn uniformly from it.
struct Surface {
  std::function<double(const Eigen::Vector3d&)> distance;
  std::function<Eigen::Vector3d(std::mt19937&)> draw;
};

inline double uniform(std::mt19937& random, double low = 0.0, double high = 1.0) {
  return std::uniform_real_distribution<double>(low, high)(random);
}

/// Box of half extents `half` centred at the origin.
inline double boxDistance(const Eigen::Vector3d& half, const Eigen::Vector3d& p) {
  const Eigen::Vector3d outside = (p.cwiseAbs() - half).cwiseMax(0.0);
  if (outside.squaredNorm() > 0.0) return outside.norm();
  return (half - p.cwiseAbs()).minCoeff();
}

inline Eigen::Vector3d drawOnBox(const Eigen::Vector3d& half, std::mt19937& random) {
  const Eigen::Vector3d area(half.y() * half.z(), half.z() * half.x(), half.x() * half.y());
  double pick = uniform(random, 0.0, area.sum());
  int axis = 0;
  while (axis < 2 && pick > area[axis]) pick -= area[axis++];
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) p[i] = uniform(random, -half[i], half[i]);
  p[axis] = uniform(random) < 0.5 ? -half[axis] : half[axis];
  return p;
}

/// Cylinder along z centred at the origin.
inline double cylinderDistance(double radius, double length, const Eigen::Vector3d& p) {
  const double rho = p.head<2>().norm(), h = length / 2.0;
  const double side = std::abs(rho - radius), cap = std::abs(std::abs(p.z()) - h);
  if (std::abs(p.z()) <= h && rho <= radius) return std::min(side, cap);
  return std::hypot(std::max(rho - radius, 0.0), std::max(std::abs(p.z()) - h, 0.0));
}

inline Eigen::Vector3d drawOnCylinder(double radius, double length, std::mt19937& random) {
  const double side_area = 2.0 * M_PI * radius * length, cap_area = M_PI * radius * radius;
  const double angle = uniform(random, 0.0, 2.0 * M_PI);
  if (uniform(random, 0.0, side_area + 2.0 * cap_area) < side_area) {
    return {radius * std::cos(angle), radius * std::sin(angle),
            uniform(random, -length / 2, length / 2)};
  }
  const double rho = radius * std::sqrt(uniform(random));
  return {rho * std::cos(angle), rho * std::sin(angle),
          uniform(random) < 0.5 ? -length / 2 : length / 2};
}

inline Eigen::Vector3d drawOnSphere(double radius, std::mt19937& random) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d d(normal(random), normal(random), normal(random));
  return radius * d.normalized();
}

/// Distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
inline double triangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  }
  const double denominator = 1.0 / (va + vb + vc);
  return (p - (a + ab * vb * denominator + ac * vc * denominator)).norm();
}

inline double meshDistance(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : mesh.triangles) {
    best = std::min(
        best, triangleDistance(p, mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]));
  }
  return best;
}

inline Eigen::Vector3d drawOnMesh(const TriangleMesh& mesh, std::mt19937& random) {
  std::vector<double> areas;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[t[0]];
    areas.push_back((mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).norm());
  }
  std::discrete_distribution<std::size_t> pick(areas.begin(), areas.end());
  const auto& t = mesh.triangles[pick(random)];
  double u = uniform(random), v = uniform(random);
  if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
  const Eigen::Vector3d& a = mesh.vertices[t[0]];
  return a + u * (mesh.vertices[t[1]] - a) + v * (mesh.vertices[t[2]] - a);
}

/// `surface` seen through `pose` (the shape's frame in the frame of the points).
inline Surface placed(const Surface& surface, const Eigen::Isometry3d& pose) {
  return {[=](const Eigen::Vector3d& p) { return surface.distance(pose.inverse() * p); },
          [=](std::mt19937& random) { return Eigen::Vector3d(pose * surface.draw(random)); }};
}

/// The largest distance from a point drawn on `surface` to its nearest point of `points`,
/// over `probes` such points (a fixed seed).
inline double farthestProbe(const Surface& surface, const std::vector<Eigen::Vector3d>& points,
                            int probes = 20000) {
  NearestPointIndex index;
  index.build(points);
  std::mt19937 random(57);
  double worst = 0.0;
  for (int i = 0; i < probes; ++i) {
    const Eigen::Vector3d probe = surface.draw(random);
    NearestPointIndex::Nearest nearest;
    if (!index.nearest(probe, nearest)) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, std::sqrt(nearest.squared_distance_m2));
  }
  return worst;
}

}  // namespace test
}  // namespace deformable_collision
