#include "deformable_collision/core/robot/surface_sampling.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_set>

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// Rows of a triangle at most this share of the spacing apart: a point between two rows is
/// then at most sqrt(3)/2 s from the row nearer its longest edge and s/2 along it, within s.
const double kRowStepShare = std::sqrt(3.0) / 2.0;

void checkPositive(double value, const std::string& what) {
  if (std::isfinite(value) && value > 0.0) return;
  std::ostringstream out;
  out << "surface sampling: " << what << " = " << value << " must be finite and > 0";
  throw std::invalid_argument(out.str());
}

void checkCount(double count, const SurfaceSampling& sampling, const std::string& what) {
  if (count <= static_cast<double>(sampling.max_points)) return;
  std::ostringstream out;
  out << "surface sampling: " << what << " would take " << count << " points at spacing "
      << sampling.spacing_m << " m, more than the " << sampling.max_points << " allowed";
  throw std::length_error(out.str());
}

/// Segments of at most `spacing` on a length > 0 (at least one), as a double so that a
/// count too large for an integer is still compared with max_points.
double segments(double length, double spacing) {
  return std::max(1.0, std::ceil(length / spacing));
}

/// Points on a circle of radius `radius` at most `spacing` apart along it; one at its centre
/// for radius 0.
double ringPoints(double radius, double spacing) {
  return std::max(1.0, std::ceil(2.0 * M_PI * radius / spacing));
}

void addRing(double radius, double z, int count, Points& out) {
  for (int j = 0; j < count; ++j) {
    const double angle = 2.0 * M_PI * j / count;
    out.emplace_back(radius * std::cos(angle), radius * std::sin(angle), z);
  }
}

/// A cylinder cap's points inside its rim: the centre and `radial` - 1 concentric rings.
double capPoints(double radius, double radial, double spacing) {
  double count = 1.0;
  for (int k = 1; k < radial; ++k) count += ringPoints(radius * k / radial, spacing);
  return count;
}

void addCap(double radius, double z, double radial, double spacing, Points& out) {
  out.emplace_back(0.0, 0.0, z);
  for (int k = 1; k < radial; ++k) {
    const double ring = radius * k / radial;
    addRing(ring, z, static_cast<int>(ringPoints(ring, spacing)), out);
  }
}

/// (1 - t) a + t b, exactly a at t = 0 and b at t = 1, so that corners shared by triangles
/// come out alike.
Eigen::Vector3d mix(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t) {
  return (1.0 - t) * a + t * b;
}

}  // namespace

std::vector<Eigen::Vector3d> sampleBoxSurface(const Eigen::Vector3d& size_m,
                                              const SurfaceSampling& sampling) {
  checkPositive(sampling.spacing_m, "spacing_m");
  Eigen::Array3d steps;
  for (int axis = 0; axis < 3; ++axis) {
    checkPositive(size_m[axis], "box size");
    steps[axis] = segments(size_m[axis], sampling.spacing_m);
  }
  checkCount((steps + 1.0).prod() - (steps - 1.0).prod(), sampling, "the box");
  const Eigen::Array3i n = steps.cast<int>();
  auto at = [&](int axis, int i) {
    return size_m[axis] * (static_cast<double>(i) / n[axis] - 0.5);
  };
  Points points;
  for (int i = 0; i <= n.x(); ++i) {
    for (int j = 0; j <= n.y(); ++j) {
      // Inside the x and y faces' rims only the two z faces hold points.
      const bool rim = i == 0 || i == n.x() || j == 0 || j == n.y();
      for (int k = 0; k <= n.z(); k += rim ? 1 : n.z())
        points.emplace_back(at(0, i), at(1, j), at(2, k));
    }
  }
  return points;
}

std::vector<Eigen::Vector3d> sampleCylinderSurface(double radius_m, double length_m,
                                                   const SurfaceSampling& sampling) {
  const double s = sampling.spacing_m;
  checkPositive(s, "spacing_m");
  checkPositive(radius_m, "cylinder radius");
  checkPositive(length_m, "cylinder length");
  const double around = ringPoints(radius_m, s);
  const double rings = segments(length_m, s);
  const double radial = segments(radius_m, s);
  // Each cap ring holds a point at least: more rings than max_points cannot fit.
  checkCount(2.0 * radial, sampling, "the cylinder");
  checkCount((rings + 1.0) * around + 2.0 * capPoints(radius_m, radial, s), sampling,
             "the cylinder");
  Points points;
  for (int k = 0; k <= rings; ++k) {
    addRing(radius_m, length_m * (k / rings - 0.5), static_cast<int>(around), points);
  }
  // The caps' rims are the side's end rings.
  addCap(radius_m, -0.5 * length_m, radial, s, points);
  addCap(radius_m, 0.5 * length_m, radial, s, points);
  return points;
}

std::vector<Eigen::Vector3d> sampleSphereSurface(double radius_m, const SurfaceSampling& sampling) {
  const double s = sampling.spacing_m;
  checkPositive(s, "spacing_m");
  checkPositive(radius_m, "sphere radius");
  const double bands = segments(M_PI * radius_m, s);
  checkCount(bands + 1.0, sampling, "the sphere");
  auto ring = [&](int k) {
    const double polar = M_PI * k / bands;
    const bool pole = k == 0 || k == bands;
    return std::make_pair(polar, pole ? 1.0 : ringPoints(radius_m * std::sin(polar), s));
  };
  double count = 0.0;
  for (int k = 0; k <= bands; ++k) count += ring(k).second;
  checkCount(count, sampling, "the sphere");
  Points points;
  for (int k = 0; k <= bands; ++k) {
    const auto [polar, around] = ring(k);
    addRing(radius_m * std::sin(polar), radius_m * std::cos(polar), static_cast<int>(around),
            points);
  }
  return points;
}

namespace {

/// A triangle as sampled: rows parallel to the base (its longest edge), from the base
/// (row 0) to the apex (row `rows`). The base angles are then at most 90 degrees, so the
/// foot of a point on the row below it lies on that row.
struct TriangleRows {
  Eigen::Vector3d base_start, base_end, apex;
  double rows;
};

TriangleRows triangleRows(const TriangleMesh& mesh, std::size_t triangle, double spacing) {
  const auto& t = mesh.triangles[triangle];
  const Eigen::Vector3d corner[3] = {mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]};
  int base = 0;  // The edge from corner[base] to corner[base + 1].
  double longest = -1.0;
  for (int e = 0; e < 3; ++e) {
    const double length = (corner[(e + 1) % 3] - corner[e]).norm();
    if (length > longest) longest = length, base = e;
  }
  TriangleRows rows{corner[base], corner[(base + 1) % 3], corner[(base + 2) % 3], 1.0};
  if (longest > 0.0) {
    const double height =
        (rows.apex - rows.base_start).cross(rows.base_end - rows.base_start).norm() / longest;
    rows.rows = segments(height, kRowStepShare * spacing);
  }
  return rows;
}

/// Row k's ends; its points are at most `spacing` apart, both ends included.
double rowPoints(const TriangleRows& rows, int k, double spacing, Eigen::Vector3d& start,
                 Eigen::Vector3d& end) {
  const double t = k / rows.rows;
  start = mix(rows.base_start, rows.apex, t);
  end = mix(rows.base_end, rows.apex, t);
  const double length = (end - start).norm();
  return length > 0.0 ? std::ceil(length / spacing) + 1.0 : 1.0;
}

double trianglePoints(const TriangleRows& rows, double spacing) {
  double count = 0.0;
  Eigen::Vector3d start, end;
  for (int k = 0; k <= rows.rows; ++k) count += rowPoints(rows, k, spacing, start, end);
  return count;
}

void addTriangle(const TriangleRows& rows, double spacing, Points& out) {
  Eigen::Vector3d start, end;
  for (int k = 0; k <= rows.rows; ++k) {
    const double count = rowPoints(rows, k, spacing, start, end);
    if (count == 1.0) out.push_back(start);
    for (int j = 0; count > 1.0 && j < count; ++j)
      out.push_back(mix(start, end, j / (count - 1.0)));
  }
}

void checkMesh(const TriangleMesh& mesh) {
  if (mesh.triangles.empty())
    throw std::invalid_argument("surface sampling: the mesh has no triangle");
  for (const Eigen::Vector3d& v : mesh.vertices) {
    if (!v.allFinite())
      throw std::invalid_argument("surface sampling: a mesh vertex is not finite");
  }
  for (const auto& triangle : mesh.triangles) {
    for (const std::uint32_t index : triangle) {
      if (index >= mesh.vertices.size()) {
        throw std::invalid_argument("surface sampling: vertex index " + std::to_string(index) +
                                    " is out of range (" + std::to_string(mesh.vertices.size()) +
                                    " vertices)");
      }
    }
  }
}

struct PointHash {
  std::size_t operator()(const Eigen::Vector3d& p) const {
    std::size_t h = 0;
    for (int axis = 0; axis < 3; ++axis) {
      h ^= std::hash<double>()(p[axis]) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    }
    return h;
  }
};

}  // namespace

std::vector<Eigen::Vector3d> sampleMeshSurface(const TriangleMesh& mesh,
                                               const SurfaceSampling& sampling) {
  const double s = sampling.spacing_m;
  checkPositive(s, "spacing_m");
  checkMesh(mesh);
  Points points, triangle_points;
  std::unordered_set<Eigen::Vector3d, PointHash> seen;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const TriangleRows rows = triangleRows(mesh, t, s);
    // Each row holds a point at least: a triangle is refused before its points are made.
    checkCount(rows.rows + 1.0, sampling, "a triangle of the mesh");
    checkCount(trianglePoints(rows, s), sampling, "a triangle of the mesh");
    triangle_points.clear();
    addTriangle(rows, s, triangle_points);
    for (const Eigen::Vector3d& p : triangle_points) {
      if (seen.insert(p).second) points.push_back(p);
    }
    checkCount(static_cast<double>(points.size()), sampling, "the mesh");
  }
  return points;
}

}  // namespace deformable_collision
