#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>

#include "deformable_collision/core/common/nearest_point_index.h"
#include "deformable_collision/core/registration/detail/spread_points.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

struct SpreadCase {
  std::string name;
  Points points;
  std::size_t target;
};

std::vector<SpreadCase> spreadCases() {
  Points line;
  for (int i = 0; i < 5000; ++i) line.emplace_back(1e-4 * i, 0.0, 0.0);
  return {
      {"sphere_surface", sampleNoisySurface(8000, {0.05, 0.05, 0.05}, 0.0, 3), 3000},
      {"thin_long_surface", sampleNoisySurface(8000, {0.1, 0.02, 0.004}, 0.0, 4), 3000},
      {"box_volume", sampleBox(8000, {0.05, 0.03, 0.02}, 5), 3000},
      // Cells sized for a volume of 1000 cut an 11^3 grid into 11^3 cells, not 10^3.
      {"grid_volume", gridLayers(11, 11, 0.01), 1000},
      {"line", line, 500},
      {"few_of_many", sampleBox(20000, {0.05, 0.05, 0.05}, 6), 50},
  };
}

class SpreadPoints : public ::testing::TestWithParam<SpreadCase> {};

TEST_P(SpreadPoints, ChoosesNearlyTheTargetEvenlyOverTheShape) {
  const SpreadCase& c = GetParam();
  const std::vector<std::uint32_t> chosen = detail::spreadPoints(c.points, c.target);
  // Whatever the shape's dimension: 90% to 100% of the target, not a volume's share of it.
  EXPECT_LE(chosen.size(), c.target);
  EXPECT_GE(chosen.size(), 0.9 * c.target);
  EXPECT_TRUE(std::is_sorted(chosen.begin(), chosen.end()));
  EXPECT_EQ(std::set<std::uint32_t>(chosen.begin(), chosen.end()).size(), chosen.size());
  // Evenly: no point is much farther from a chosen one than the chosen ones are apart (the
  // mean distance from each to its nearest other chosen point).
  Points kept;
  for (const auto i : chosen) kept.push_back(c.points[i]);
  NearestPointIndex index;
  index.build(kept);
  double apart = 0.0;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t other = 0; other < kept.size(); ++other) {
      if (other != k) nearest = std::min(nearest, (kept[k] - kept[other]).norm());
    }
    apart += nearest / static_cast<double>(kept.size());
  }
  double largest = 0.0;
  for (const auto& p : c.points) {
    NearestPointIndex::Nearest nearest;
    index.nearest(p, nearest);
    largest = std::max(largest, std::sqrt(nearest.squared_distance_m2));
  }
  EXPECT_LT(largest, 2.5 * apart);
}

INSTANTIATE_TEST_SUITE_P(Shapes, SpreadPoints, ::testing::ValuesIn(spreadCases()),
                         [](const auto& info) { return info.param.name; });

TEST(SpreadPointsTest, AllOfFewPointsAndOneOfCoincidentOnes) {
  const Points few = sampleBox(10, {1, 1, 1}, 1);
  EXPECT_EQ(detail::spreadPoints(few, 10).size(), 10u);
  const Points same(100, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(detail::spreadPoints(same, 10), std::vector<std::uint32_t>{0});
}

}  // namespace
}  // namespace deformable_collision
