#include "deformable_collision/core/robot/surface_sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/common/nearest_point_index.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// Rounding allowed in "on the surface" and "within the spacing", relative to the shape.
constexpr double kRounding = 1e-12;
constexpr int kSurfaceProbes = 20000;

/// One shape of the table: how the sampler samples it, how far a point is from its true
/// surface, and a point drawn uniformly from that surface.
struct ShapeCase {
  std::string name;
  double spacing_m;
  std::function<Points(const SurfaceSampling&)> sample;
  std::function<double(const Eigen::Vector3d&)> distance;
  std::function<Eigen::Vector3d(std::mt19937&)> draw;
  /// The expected count, from the shape's area over a square of the spacing (loosely).
  std::size_t min_points, max_points;
};

double uniform(std::mt19937& random, double low = 0.0, double high = 1.0) {
  return std::uniform_real_distribution<double>(low, high)(random);
}

// ---- Box -------------------------------------------------------------------------------

double boxDistance(const Eigen::Vector3d& half, const Eigen::Vector3d& p) {
  const Eigen::Vector3d outside = (p.cwiseAbs() - half).cwiseMax(0.0);
  if (outside.squaredNorm() > 0.0) return outside.norm();
  return (half - p.cwiseAbs()).minCoeff();
}

Eigen::Vector3d drawOnBox(const Eigen::Vector3d& half, std::mt19937& random) {
  const Eigen::Vector3d area(half.y() * half.z(), half.z() * half.x(), half.x() * half.y());
  double pick = uniform(random, 0.0, area.sum());
  int axis = 0;
  while (axis < 2 && pick > area[axis]) pick -= area[axis++];
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) p[i] = uniform(random, -half[i], half[i]);
  p[axis] = uniform(random) < 0.5 ? -half[axis] : half[axis];
  return p;
}

ShapeCase boxCase(const std::string& name, const Eigen::Vector3d& size, double spacing,
                  std::size_t low, std::size_t high) {
  const Eigen::Vector3d half = size / 2.0;
  return {name,
          spacing,
          [size](const SurfaceSampling& s) { return sampleBoxSurface(size, s); },
          [half](const Eigen::Vector3d& p) { return boxDistance(half, p); },
          [half](std::mt19937& r) { return drawOnBox(half, r); },
          low,
          high};
}

// ---- Cylinder --------------------------------------------------------------------------

double cylinderDistance(double radius, double length, const Eigen::Vector3d& p) {
  const double rho = p.head<2>().norm(), h = length / 2.0;
  const double side = std::abs(rho - radius), cap = std::abs(std::abs(p.z()) - h);
  if (std::abs(p.z()) <= h && rho <= radius) return std::min(side, cap);
  return std::hypot(std::max(rho - radius, 0.0), std::max(std::abs(p.z()) - h, 0.0));
}

Eigen::Vector3d drawOnCylinder(double radius, double length, std::mt19937& random) {
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

ShapeCase cylinderCase(const std::string& name, double radius, double length, double spacing,
                       std::size_t low, std::size_t high) {
  return {name,
          spacing,
          [=](const SurfaceSampling& s) { return sampleCylinderSurface(radius, length, s); },
          [=](const Eigen::Vector3d& p) { return cylinderDistance(radius, length, p); },
          [=](std::mt19937& r) { return drawOnCylinder(radius, length, r); },
          low,
          high};
}

// ---- Sphere ----------------------------------------------------------------------------

ShapeCase sphereCase(const std::string& name, double radius, double spacing, std::size_t low,
                     std::size_t high) {
  auto draw = [radius](std::mt19937& random) {
    std::normal_distribution<double> normal;
    Eigen::Vector3d d(normal(random), normal(random), normal(random));
    return Eigen::Vector3d(radius * d.normalized());
  };
  return {name,
          spacing,
          [=](const SurfaceSampling& s) { return sampleSphereSurface(radius, s); },
          [=](const Eigen::Vector3d& p) { return std::abs(p.norm() - radius); },
          draw,
          low,
          high};
}

// ---- Mesh ------------------------------------------------------------------------------

/// Distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
double triangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
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

double meshDistance(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : mesh.triangles) {
    best = std::min(
        best, triangleDistance(p, mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]));
  }
  return best;
}

Eigen::Vector3d drawOnMesh(const TriangleMesh& mesh, std::mt19937& random) {
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

/// A finger-like closed wedge (a triangular prism, 3 cm long, sides split into two
/// triangles each) and, apart from it, a sliver 4 cm long and 0.2 mm wide and a large
/// obtuse triangle: the triangles a coarse or careless sampler would leave uncovered.
TriangleMesh testMesh() {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0},      {0.02, 0, 0},           {0.01, 0.015, 0},
                   {0, 0, 0.03},   {0.02, 0, 0.03},        {0.01, 0.015, 0.03},
                   {0.05, 0, 0},   {0.09, 0.0002, 0.0001}, {0.07, 0.0001, 0.0},
                   {0.0, 0.05, 0}, {0.12, 0.05, 0},        {0.06, 0.056, 0.004}};
  mesh.triangles = {{0, 2, 1}, {3, 4, 5}, {0, 1, 4}, {0, 4, 3}, {1, 2, 5},
                    {1, 5, 4}, {2, 0, 3}, {2, 3, 5}, {6, 7, 8}, {9, 10, 11}};
  return mesh;
}

ShapeCase meshCase(const std::string& name, double spacing, std::size_t low, std::size_t high) {
  const TriangleMesh mesh = testMesh();
  return {name,
          spacing,
          [mesh](const SurfaceSampling& s) { return sampleMeshSurface(mesh, s); },
          [mesh](const Eigen::Vector3d& p) { return meshDistance(mesh, p); },
          [mesh](std::mt19937& r) { return drawOnMesh(mesh, r); },
          low,
          high};
}

std::vector<ShapeCase> shapeCases() {
  // Counts: a surface of area A at spacing s takes about A / s^2 points; the bounds allow
  // a factor of 2 to 3 either way.
  return {boxCase("finger_box", {0.02, 0.01, 0.04}, 0.004, 100, 600),
          boxCase("thin_plate", {0.1, 0.06, 0.0005}, 0.005, 200, 1000),
          boxCase("box_smaller_than_spacing", {0.001, 0.002, 0.0015}, 0.004, 8, 8),
          cylinderCase("finger_cylinder", 0.008, 0.04, 0.004, 100, 600),
          cylinderCase("thin_rod", 0.0005, 0.2, 0.003, 60, 400),
          cylinderCase("flat_disk", 0.05, 0.001, 0.004, 300, 1500),
          sphereCase("fingertip_sphere", 0.01, 0.004, 50, 300),
          sphereCase("large_sphere", 0.3, 0.01, 8000, 25000),
          sphereCase("sphere_smaller_than_spacing", 0.0005, 0.004, 2, 2),
          meshCase("mesh_4mm", 0.004, 150, 1000),
          meshCase("mesh_1mm", 0.001, 1500, 15000)};
}

/// The largest distance from a point drawn on the shape's surface to its nearest sample, over
/// kSurfaceProbes such points (a fixed seed).
double farthestProbe(const ShapeCase& shape, const Points& points) {
  NearestPointIndex index;
  index.build(points);
  std::mt19937 random(57);
  double worst = 0.0;
  for (int i = 0; i < kSurfaceProbes; ++i) {
    const Eigen::Vector3d probe = shape.draw(random);
    EXPECT_LE(shape.distance(probe), 1e-9) << "the probe is on the surface";
    NearestPointIndex::Nearest nearest;
    EXPECT_TRUE(index.nearest(probe, nearest));
    worst = std::max(worst, std::sqrt(nearest.squared_distance_m2));
  }
  return worst;
}

class SurfaceSamplingTest : public ::testing::TestWithParam<ShapeCase> {};

TEST_P(SurfaceSamplingTest, EveryPointLiesOnTheSurface) {
  const ShapeCase& shape = GetParam();
  const Points points = shape.sample({shape.spacing_m, 1000000});
  ASSERT_FALSE(points.empty());
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_LE(shape.distance(points[i]), kRounding)
        << "point " << i << ": " << points[i].transpose();
  }
}

TEST_P(SurfaceSamplingTest, EverySurfacePointIsWithinTheSpacingOfASample) {
  const ShapeCase& shape = GetParam();
  const Points points = shape.sample({shape.spacing_m, 1000000});
  const double worst = farthestProbe(shape, points);
  EXPECT_LE(worst, shape.spacing_m * (1.0 + kRounding));
  std::printf("[ MEASURED ] %s: %zu points, farthest probe %.3f of the spacing\n",
              shape.name.c_str(), points.size(), worst / shape.spacing_m);
}

TEST_P(SurfaceSamplingTest, CountIsAboutTheAreaOverTheSpacingSquared) {
  const ShapeCase& shape = GetParam();
  const std::size_t count = shape.sample({shape.spacing_m, 1000000}).size();
  EXPECT_GE(count, shape.min_points);
  EXPECT_LE(count, shape.max_points);
}

TEST_P(SurfaceSamplingTest, IsDeterministicAndHoldsNoPointTwice) {
  const ShapeCase& shape = GetParam();
  const Points first = shape.sample({shape.spacing_m, 1000000});
  EXPECT_EQ(first, shape.sample({shape.spacing_m, 1000000}));
  Points sorted = first;
  std::sort(sorted.begin(), sorted.end(), [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end());
}

TEST_P(SurfaceSamplingTest, MorePointsThanAllowedAreRefusedBeforeMakingThem) {
  const ShapeCase& shape = GetParam();
  const std::size_t count = shape.sample({shape.spacing_m, 1000000}).size();
  EXPECT_EQ(shape.sample({shape.spacing_m, count}).size(), count) << "exactly the cap fits";
  EXPECT_THROW(shape.sample({shape.spacing_m, count - 1}), std::length_error);
  // A spacing a millionth of the shape would take about 1e12 points: refused at once.
  EXPECT_THROW(shape.sample({shape.spacing_m * 1e-6, 1000000}), std::length_error);
}

INSTANTIATE_TEST_SUITE_P(Shapes, SurfaceSamplingTest, ::testing::ValuesIn(shapeCases()),
                         [](const ::testing::TestParamInfo<ShapeCase>& info) {
                           return info.param.name;
                         });

TEST(SurfaceSampling, TheCoverageCheckCatchesSparseOrMissingSamples) {
  const ShapeCase shape = boxCase("box", {0.02, 0.01, 0.04}, 0.004, 0, 0);
  EXPECT_GT(farthestProbe(shape, shape.sample({2.0 * shape.spacing_m, 1000000})), shape.spacing_m);
  Points without_top = shape.sample({shape.spacing_m, 1000000});
  without_top.erase(std::remove_if(without_top.begin(), without_top.end(),
                                   [](const Eigen::Vector3d& p) { return p.z() > 0.0199; }),
                    without_top.end());
  EXPECT_GT(farthestProbe(shape, without_top), shape.spacing_m);
}

TEST(SurfaceSampling, BadArgumentsAreRefusedNamingThem) {
  const SurfaceSampling good{0.004, 1000};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const double spacing : {0.0, -1.0, nan, std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(sampleSphereSurface(0.01, {spacing, 1000}), std::invalid_argument) << spacing;
  }
  EXPECT_THROW(sampleBoxSurface({0.01, 0.0, 0.01}, good), std::invalid_argument);
  EXPECT_THROW(sampleBoxSurface({0.01, nan, 0.01}, good), std::invalid_argument);
  EXPECT_THROW(sampleCylinderSurface(-0.01, 0.02, good), std::invalid_argument);
  EXPECT_THROW(sampleCylinderSurface(0.01, 0.0, good), std::invalid_argument);
  EXPECT_THROW(sampleSphereSurface(0.0, good), std::invalid_argument);
  try {
    sampleCylinderSurface(0.01, -2.0, good);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cylinder length = -2"), std::string::npos) << e.what();
  }
  TriangleMesh mesh = testMesh();
  mesh.triangles.push_back({0, 1, 12});
  EXPECT_THROW(sampleMeshSurface(mesh, good), std::invalid_argument) << "index out of range";
  mesh = testMesh();
  mesh.vertices[3].x() = nan;
  EXPECT_THROW(sampleMeshSurface(mesh, good), std::invalid_argument) << "not finite";
  EXPECT_THROW(sampleMeshSurface(TriangleMesh{}, good), std::invalid_argument) << "no triangle";
}

TEST(SurfaceSampling, DegenerateTrianglesAreTheirSegmentOrPoint) {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {0.01, 0, 0}, {0.004, 0, 0}, {0.5, 0.5, 0.5}};
  mesh.triangles = {{0, 1, 2}, {3, 3, 3}};
  const Points points = sampleMeshSurface(mesh, {0.004, 1000});
  // The segment from 0 to 1 cm in 4 steps (3 segments of 3.3 mm, both ends), the apex
  // at 4 mm, and the point.
  ASSERT_EQ(points.size(), 6u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(points[i].y(), 0.0);
    EXPECT_EQ(points[i].z(), 0.0);
  }
  EXPECT_EQ(points.back(), Eigen::Vector3d(0.5, 0.5, 0.5));
}

}  // namespace
}  // namespace deformable_collision
