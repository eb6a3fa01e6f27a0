#include "deformable_collision/core/common/nearest_point_index.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

struct IndexCase {
  std::string name;
  std::size_t count;
  /// The k-th of `count` points, from a generator seeded per case. The generators name
  /// their return type: a deduced one would be an Eigen expression of their temporaries.
  std::function<Eigen::Vector3d(std::size_t k, std::mt19937& random)> point;
};

void PrintTo(const IndexCase& c, std::ostream* os) { *os << c.name; }

double uniform(std::mt19937& random, double low, double high) {
  return std::uniform_real_distribution<double>(low, high)(random);
}

Eigen::Vector3d inCube(std::mt19937& random, double half) {
  return {uniform(random, -half, half), uniform(random, -half, half), uniform(random, -half, half)};
}

class NearestPointIndexTest : public ::testing::TestWithParam<IndexCase> {};

// Every query's answer is as near as the nearest point found by trying them all, and is
// that near: queries on the points, near them and far outside them.
TEST_P(NearestPointIndexTest, FindsThePointBruteForceFinds) {
  const IndexCase& c = GetParam();
  std::mt19937 random(42);
  Points points;
  for (std::size_t k = 0; k < c.count; ++k) points.push_back(c.point(k, random));
  Eigen::AlignedBox3d box;
  for (const auto& p : points) box.extend(p);
  const Eigen::Vector3d centre = box.center();
  const double size = std::max(box.diagonal().norm(), 1e-300);
  NearestPointIndex index;
  index.build(points);
  ASSERT_EQ(index.size(), points.size());
  for (int q = 0; q < 300; ++q) {
    Eigen::Vector3d query;
    switch (q % 3) {
      case 0:
        query = points[q % points.size()];
        break;
      case 1:
        query = points[q % points.size()] + 0.01 * size * inCube(random, 1.0);
        break;
      default:
        query = centre + 2.0 * size * inCube(random, 1.0);
        break;
    }
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : points) best = std::min(best, (p - query).squaredNorm());
    NearestPointIndex::Nearest found;
    ASSERT_TRUE(index.nearest(query, found));
    ASSERT_LT(found.index, points.size());
    EXPECT_EQ(found.squared_distance_m2, best) << "query " << q;
    EXPECT_EQ((points[found.index] - query).squaredNorm(), found.squared_distance_m2);
    // Bounded: found exactly when the nearest lies below the bound, and then as near.
    const double infinity = std::numeric_limits<double>::infinity();
    for (const double bound :
         {0.5 * best, best, std::nextafter(best, infinity), 4.0 * best + 1e-300}) {
      NearestPointIndex::Nearest within;
      ASSERT_EQ(index.nearestWithin(query, bound, within), best < bound)
          << "query " << q << ", bound " << bound;
      if (best < bound) EXPECT_EQ(within.squared_distance_m2, best) << "query " << q;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, NearestPointIndexTest,
    ::testing::Values(IndexCase{"OnePoint", 1,
                                [](std::size_t, std::mt19937&) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(1, 2, 3);
                                }},
                      IndexCase{"ALeafFull", 8,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return inCube(r, 1.0);
                                }},
                      IndexCase{"OneMoreThanALeaf", 9,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return inCube(r, 1.0);
                                }},
                      IndexCase{"Cube", 5000,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return inCube(r, 0.1);
                                }},
                      IndexCase{"Plane", 3000,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(uniform(r, -1, 1), uniform(r, -1, 1), 0.0);
                                }},
                      IndexCase{"Line", 2000,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(0.0, uniform(r, -1, 1), 0.0);
                                }},
                      IndexCase{"AllTheSamePoint", 500,
                                [](std::size_t, std::mt19937&) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(0.3, 0.3, 0.3);
                                }},
                      IndexCase{"GridWithTies", 1000,
                                [](std::size_t k, std::mt19937&) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(0.01 * (k % 10), 0.01 * (k / 10 % 10),
                                                         0.01 * (k / 100));
                                }},
                      IndexCase{"TwoClustersFarApart", 2000,
                                [](std::size_t k, std::mt19937& r) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(k % 2 ? 10.0 : -10.0, 0, 0) +
                                         inCube(r, 0.01);
                                }},
                      IndexCase{"FarFromTheOrigin", 2000,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return Eigen::Vector3d(1e5, -1e5, 1e5) + inCube(r, 0.1);
                                }},
                      IndexCase{"TinyScale", 2000,
                                [](std::size_t, std::mt19937& r) -> Eigen::Vector3d {
                                  return inCube(r, 1e-4);
                                }}),
    [](const auto& info) { return info.param.name; });

TEST(NearestPointIndex, EmptyIndexFindsNothing) {
  NearestPointIndex index;
  NearestPointIndex::Nearest found;
  EXPECT_FALSE(index.nearest(Eigen::Vector3d::Zero(), found));
  const Points none;
  index.build(none);
  EXPECT_FALSE(index.nearest(Eigen::Vector3d::Zero(), found));
}

// A rebuild over other, fewer points answers for those alone.
TEST(NearestPointIndex, RebuildReplacesThePoints) {
  std::mt19937 random(5);
  Points many;
  for (int k = 0; k < 1000; ++k) many.push_back(inCube(random, 1.0));
  NearestPointIndex index;
  index.build(many);
  const Points few{{5, 5, 5}, {6, 6, 6}};
  index.build(few);
  NearestPointIndex::Nearest found;
  ASSERT_TRUE(index.nearest(Eigen::Vector3d::Zero(), found));
  EXPECT_EQ(found.index, 0u);
  EXPECT_DOUBLE_EQ(found.squared_distance_m2, 75.0);
}

}  // namespace
}  // namespace deformable_collision
