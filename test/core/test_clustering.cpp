#include "deformable_collision/core/shape_matching/clustering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

struct PartitionCase {
  const char* name;
  std::size_t points;
  int clusters;
  double overlap_ratio;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const PartitionCase& c, std::ostream* os) { *os << c.name; }

class PartitionTest : public ::testing::TestWithParam<PartitionCase> {};

TEST_P(PartitionTest, CoversEveryPointBalancedAndDeterministic) {
  const auto& c = GetParam();
  const auto points = sampleBox(c.points, {1.0, 0.3, 0.2}, 7);
  const auto clusters = partitionIntoClusters(points, c.clusters, c.overlap_ratio);
  ASSERT_EQ(clusters.size(), static_cast<std::size_t>(c.clusters));
  EXPECT_EQ(clusters, partitionIntoClusters(points, c.clusters, c.overlap_ratio));

  std::vector<int> holders(points.size(), 0);
  for (const auto& cluster : clusters) {
    EXPECT_TRUE(std::is_sorted(cluster.begin(), cluster.end()));
    EXPECT_FALSE(cluster.empty());
    for (const auto i : cluster) ++holders[i];
  }
  EXPECT_GE(*std::min_element(holders.begin(), holders.end()), 1) << "a point in no cluster";
  if (c.overlap_ratio == 0.0) {
    EXPECT_EQ(*std::max_element(holders.begin(), holders.end()), 1);
    std::size_t smallest = points.size();
    std::size_t largest = 0;
    for (const auto& cluster : clusters) {
      smallest = std::min(smallest, cluster.size());
      largest = std::max(largest, cluster.size());
    }
    EXPECT_LE(largest - smallest, static_cast<std::size_t>(c.clusters));
  } else if (c.clusters > 1) {
    EXPECT_GT(*std::max_element(holders.begin(), holders.end()), 1) << "no seam was shared";
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, PartitionTest,
                         ::testing::Values(PartitionCase{"one_cluster", 500, 1, 0.1},
                                           PartitionCase{"two_disjoint", 500, 2, 0.0},
                                           PartitionCase{"three_disjoint", 501, 3, 0.0},
                                           PartitionCase{"seven_disjoint", 1000, 7, 0.0},
                                           PartitionCase{"four_overlapping", 1000, 4, 0.1},
                                           PartitionCase{"one_point_per_cluster", 5, 5, 0.0}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Partition, CoincidentPointsSplitDeterministically) {
  const std::vector<Eigen::Vector3d> points(10, Eigen::Vector3d(1.0, 2.0, 3.0));
  const auto clusters = partitionIntoClusters(points, 3, 0.0);
  ASSERT_EQ(clusters.size(), 3u);
  std::set<std::uint32_t> all;
  for (const auto& cluster : clusters) all.insert(cluster.begin(), cluster.end());
  EXPECT_EQ(all.size(), 10u);
}

struct BadPartitionCase {
  const char* name;
  int clusters;
  double overlap_ratio;
  const char* message_part;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const BadPartitionCase& c, std::ostream* os) { *os << c.name; }

class BadPartitionTest : public ::testing::TestWithParam<BadPartitionCase> {};

TEST_P(BadPartitionTest, ThrowsNamingTheValue) {
  const auto& c = GetParam();
  const auto points = sampleBox(10, {1.0, 1.0, 1.0}, 1);
  try {
    partitionIntoClusters(points, c.clusters, c.overlap_ratio);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(c.message_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadPartitionTest,
    ::testing::Values(BadPartitionCase{"zero_clusters", 0, 0.1, "cluster count 0"},
                      BadPartitionCase{"more_clusters_than_points", 11, 0.1, "cluster count 11"},
                      BadPartitionCase{"negative_overlap", 2, -0.5, "-0.5"}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace deformable_collision
