#include "deformable_collision/core/robot/surface_sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>

#include "surface_test_support.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;
using test::Surface;

/// Rounding allowed in "on the surface" and "within the spacing", relative to the shape.
constexpr double kRounding = 1e-12;

/// One shape of the table: how the sampler samples it and its true surface.
struct ShapeCase {
  std::string name;
  double spacing_m;
  std::function<Points(const SurfaceSampling&)> sample;
  Surface surface;
  /// The expected count, from the shape's area over a square of the spacing (loosely).
  std::size_t min_points, max_points;
};

ShapeCase boxCase(const std::string& name, const Eigen::Vector3d& size, double spacing,
                  std::size_t low, std::size_t high) {
  const Eigen::Vector3d half = size / 2.0;
  return {name,
          spacing,
          [size](const SurfaceSampling& s) { return sampleBoxSurface(size, s); },
          {[half](const Eigen::Vector3d& p) { return test::boxDistance(half, p); },
           [half](std::mt19937& r) { return test::drawOnBox(half, r); }},
          low,
          high};
}

ShapeCase cylinderCase(const std::string& name, double radius, double length, double spacing,
                       std::size_t low, std::size_t high) {
  return {name,
          spacing,
          [=](const SurfaceSampling& s) { return sampleCylinderSurface(radius, length, s); },
          {[=](const Eigen::Vector3d& p) { return test::cylinderDistance(radius, length, p); },
           [=](std::mt19937& r) { return test::drawOnCylinder(radius, length, r); }},
          low,
          high};
}

ShapeCase sphereCase(const std::string& name, double radius, double spacing, std::size_t low,
                     std::size_t high) {
  return {name,
          spacing,
          [=](const SurfaceSampling& s) { return sampleSphereSurface(radius, s); },
          {[=](const Eigen::Vector3d& p) { return std::abs(p.norm() - radius); },
           [=](std::mt19937& r) { return test::drawOnSphere(radius, r); }},
          low,
          high};
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
          {[mesh](const Eigen::Vector3d& p) { return test::meshDistance(mesh, p); },
           [mesh](std::mt19937& r) { return test::drawOnMesh(mesh, r); }},
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

class SurfaceSamplingTest : public ::testing::TestWithParam<ShapeCase> {};

TEST_P(SurfaceSamplingTest, EveryPointLiesOnTheSurface) {
  const ShapeCase& shape = GetParam();
  const Points points = shape.sample({shape.spacing_m, 1000000});
  ASSERT_FALSE(points.empty());
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_LE(shape.surface.distance(points[i]), kRounding)
        << "point " << i << ": " << points[i].transpose();
  }
}

TEST_P(SurfaceSamplingTest, EverySurfacePointIsWithinTheSpacingOfASample) {
  const ShapeCase& shape = GetParam();
  const Points points = shape.sample({shape.spacing_m, 1000000});
  const double worst = test::farthestProbe(shape.surface, points);
  EXPECT_LE(worst, shape.spacing_m * (1.0 + kRounding));
  std::printf("[ MEASURED ] %s: %zu points, farthest probe %.3f of the spacing\n",
              shape.name.c_str(), points.size(), worst / shape.spacing_m);
}

TEST_P(SurfaceSamplingTest, TheProbesLieOnTheSurface) {
  const ShapeCase& shape = GetParam();
  std::mt19937 random(57);
  for (int i = 0; i < 1000; ++i)
    ASSERT_LE(shape.surface.distance(shape.surface.draw(random)), 1e-9);
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
  EXPECT_GT(test::farthestProbe(shape.surface, shape.sample({2.0 * shape.spacing_m, 1000000})),
            shape.spacing_m);
  Points without_top = shape.sample({shape.spacing_m, 1000000});
  without_top.erase(std::remove_if(without_top.begin(), without_top.end(),
                                   [](const Eigen::Vector3d& p) { return p.z() > 0.0199; }),
                    without_top.end());
  EXPECT_GT(test::farthestProbe(shape.surface, without_top), shape.spacing_m);
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
