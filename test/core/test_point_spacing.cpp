#include "deformable_collision/core/common/point_spacing.h"

#include <gtest/gtest.h>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

std::vector<Eigen::Vector3d> grid(int n, double spacing) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) points.emplace_back(spacing * i, spacing * j, spacing * k);
    }
  }
  return points;
}

TEST(PointSpacing, IsTheGridStepOfAGrid) {
  for (const double spacing : {1e-4, 0.02, 3.0}) {
    EXPECT_NEAR(typicalPointSpacing(grid(12, spacing)), spacing, 1e-9 * spacing) << spacing;
  }
}

TEST(PointSpacing, FollowsTheDensityOfRandomClouds) {
  // n points in a box of volume V are about (V / n)^(1/3) apart; the nearest neighbour is
  // closer, about 0.55 of that for uniform random points.
  const auto sparse = sampleBox(1000, {0.5, 0.5, 0.5}, 1);
  const auto dense = sampleBox(8000, {0.5, 0.5, 0.5}, 1);
  const double sparse_spacing = typicalPointSpacing(sparse, 200);
  EXPECT_GT(sparse_spacing, 0.4 * 0.1);
  EXPECT_LT(sparse_spacing, 0.8 * 0.1);
  EXPECT_NEAR(typicalPointSpacing(dense, 200) / sparse_spacing, 0.5, 0.1);
}

TEST(PointSpacing, DegenerateCloudsGiveZero) {
  EXPECT_EQ(typicalPointSpacing({}), 0.0);
  EXPECT_EQ(typicalPointSpacing({Eigen::Vector3d::Ones()}), 0.0);
  EXPECT_EQ(typicalPointSpacing(std::vector<Eigen::Vector3d>(5, Eigen::Vector3d::Zero())), 0.0);
}

}  // namespace
}  // namespace deformable_collision
