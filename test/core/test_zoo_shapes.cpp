#include <gtest/gtest.h>

#include <stdexcept>

#include "deformable_collision/scenes/zoo_shapes.h"

namespace deformable_collision {
namespace {

class ZooShapes : public ::testing::TestWithParam<ZooShape> {};

TEST_P(ZooShapes, AreCentredSurfacesOfTheirSize) {
  const ZooSurface s = zooShapeSurface(GetParam(), 3000, 5);
  ASSERT_EQ(s.points.size(), 3000u);
  ASSERT_EQ(s.normals.size(), 3000u);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), half = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_NEAR(s.normals[i].norm(), 1.0, 1e-9);
    mean += s.points[i];
    half = half.cwiseMax(s.points[i].cwiseAbs());
  }
  EXPECT_LT((mean / 3000.0).norm(), 1e-12);
  // Long along x, 10 to 25 cm; spacing as the area says (a 3000-sample surface of such a
  // size is a few millimetres apart).
  EXPECT_GE(2 * half.x(), 0.09);
  EXPECT_LE(2 * half.x(), 0.25);
  EXPECT_GE(half.x(), half.y());
  EXPECT_GT(s.spacing_m, 0.001);
  EXPECT_LT(s.spacing_m, 0.006);
}

TEST_P(ZooShapes, AreTheSameForTheSameSeed) {
  const ZooSurface a = zooShapeSurface(GetParam(), 500, 9);
  const ZooSurface b = zooShapeSurface(GetParam(), 500, 9);
  const ZooSurface c = zooShapeSurface(GetParam(), 500, 10);
  EXPECT_EQ(a.points, b.points);
  EXPECT_NE(a.points, c.points);
}

INSTANTIATE_TEST_SUITE_P(Shapes, ZooShapes, ::testing::ValuesIn(kZooShapes),
                         [](const auto& info) { return std::string(zooShapeName(info.param)); });

TEST(ZooShapeSurface, RefusesTooFewPoints) {
  EXPECT_THROW(zooShapeSurface(ZooShape::kFruit, 99, 1), std::invalid_argument);
}

}  // namespace
}  // namespace deformable_collision
