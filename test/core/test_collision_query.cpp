#include "deformable_collision/core/query/collision_query.h"

#include <gtest/gtest.h>

#include <random>
#include <set>
#include <string>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;
using PointPair = std::pair<std::uint32_t, std::uint32_t>;

Points shifted(Points points, const Eigen::Vector3d& offset) {
  for (auto& p : points) p += offset;
  return points;
}

std::set<PointPair> bruteForcePairs(const Points& a, const Points& b, double distance) {
  std::set<PointPair> pairs;
  for (std::uint32_t i = 0; i < a.size(); ++i) {
    for (std::uint32_t j = 0; j < b.size(); ++j) {
      if ((a[i] - b[j]).norm() < distance) pairs.emplace(i, j);
    }
  }
  return pairs;
}

/// Point pairs (i in node a, j in node b) covered by the contacts.
std::set<PointPair> coveredPairs(const SphereTree& a, const SphereTree& b,
                                 const std::vector<SphereContact>& contacts) {
  std::set<PointPair> pairs;
  for (const auto& c : contacts) {
    const auto& na = a.node(c.node_a);
    const auto& nb = b.node(c.node_b);
    for (std::uint32_t s = na.first_point; s < na.first_point + na.point_count; ++s) {
      for (std::uint32_t t = nb.first_point; t < nb.first_point + nb.point_count; ++t) {
        pairs.emplace(a.pointIndices()[s], b.pointIndices()[t]);
      }
    }
  }
  return pairs;
}

/// Two deformed objects overlapping over part of their volume, from a seed. An object of
/// 250 or 200 points has few enough leaves that the query tests all its buckets at once; its
/// points lie about 6 cm apart, so its scenes take the contact distance kSparseContact.
struct TwoBodies {
  ShapeMatchingBody a;
  ShapeMatchingBody b;
};

constexpr double kSparseContact = 0.06;

/// Each width a query may be asked for; a CPU without it gives the next narrower.
constexpr VectorWidth kVectorWidths[] = {VectorWidth::kPortable, VectorWidth::kAvx2,
                                         VectorWidth::kAvx512};

TwoBodies randomScene(std::uint64_t seed, std::size_t points_a = 700, std::size_t points_b = 600) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  ShapeMatchingConfig ca;
  ca.mode = static_cast<DeformationMode>(seed % 3);
  ca.clusters = 1 + static_cast<int>(seed % 3);
  ca.stiffness = unit(engine);
  ShapeMatchingConfig cb = ca;
  cb.mode = static_cast<DeformationMode>((seed + 1) % 3);
  const Points rest_a = sampleEllipsoid(points_a, {0.3, 0.2, 0.2}, seed * 2 + 1);
  const Points rest_b = shifted(sampleEllipsoid(points_b, {0.25, 0.25, 0.15}, seed * 2 + 2),
                                {0.35 + 0.1 * unit(engine), 0.05 * unit(engine), 0.0});
  TwoBodies scene{ShapeMatchingBody(rest_a, ca), ShapeMatchingBody(rest_b, cb)};
  std::normal_distribution<double> noise(0.0, 0.02);
  for (ShapeMatchingBody* body : {&scene.a, &scene.b}) {
    Points p = body->restPositions();
    for (auto& x : p) {
      x += Eigen::Vector3d(noise(engine), noise(engine), noise(engine)) +
           Eigen::Vector3d(0.0, 0.0, 0.3 * x.x() * x.x());
    }
    body->setPositions(p);
    for (int s = 0; s < 5; ++s) body->step(0.02, Eigen::Vector3d(0, 0, -1.0));
  }
  return scene;
}

class NoMissedContactTest : public ::testing::TestWithParam<SphereUpdate> {};

TEST_P(NoMissedContactTest, LeafContactsCoverExactlyTheBruteForcePairs) {
  // Seeds 12 to 17: both objects small; 18 to 20: a small, b not.
  for (std::uint64_t seed = 0; seed < 21; ++seed) {
    const bool small_a = seed >= 12;
    const bool small_b = seed >= 12 && seed < 18;
    const double contact_distance = small_a ? kSparseContact : 0.02;
    TwoBodies scene = randomScene(seed, small_a ? 250 : 700, small_b ? 200 : 600);
    SphereTree ta(scene.a, {2, 6});
    SphereTree tb(scene.b, small_b ? SphereTreeConfig{2, 5} : SphereTreeConfig{3, 4});
    std::vector<SphereContact> contacts;
    QueryCounters counters;
    // A second cycle after the bodies moved on: nothing of the first cycle's points may
    // stay in the trees (the leaves' gathered positions are per cycle). The cycles are
    // queried with each vector width in turn, as far as the CPU has them.
    for (int cycle = 0; cycle < 4; ++cycle) {
      if (cycle == 2) {
        for (ShapeMatchingBody* body : {&scene.a, &scene.b}) {
          for (int s = 0; s < 3; ++s) body->step(0.02, Eigen::Vector3d(0, 0, -1.0));
        }
        scene.b.moveRigidly({-0.01, 0.0, 0.0}, Eigen::Vector3d::Zero());
      }
      ta.beginCycle(GetParam());
      tb.beginCycle(GetParam());
      contacts.clear();
      HierarchyQuery query(kVectorWidths[cycle % 3]);
      query.collide(ta, tb, std::max(ta.maxLevel(), tb.maxLevel()), contact_distance, contacts,
                    counters);

      const auto truth =
          bruteForcePairs(scene.a.positions(), scene.b.positions(), contact_distance);
      ASSERT_FALSE(truth.empty()) << "seed " << seed << ": the scene must touch";
      const auto covered = coveredPairs(ta, tb, contacts);
      for (const auto& pair : truth) {
        ASSERT_TRUE(covered.count(pair)) << "seed " << seed << ", cycle " << cycle
                                         << " missed pair " << pair.first << ", " << pair.second;
      }
      for (const auto& c : contacts) {
        ASSERT_TRUE(truth.count({c.point_a, c.point_b}))
            << "seed " << seed << ", cycle " << cycle << ": a contact without a close point pair";
        EXPECT_GT(c.depth_m, 0.0);
        EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
        EXPECT_TRUE(ta.node(c.node_a).isLeaf() && tb.node(c.node_b).isLeaf());
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, NoMissedContactTest,
                         ::testing::Values(SphereUpdate::kDeformation, SphereUpdate::kExactRefit,
                                           SphereUpdate::kBottomUpRefit),
                         [](const auto& info) {
                           switch (info.param) {
                             case SphereUpdate::kDeformation:
                               return std::string("deformation");
                             case SphereUpdate::kExactRefit:
                               return std::string("exact_refit");
                             default:
                               return std::string("bottom_up_refit");
                           }
                         });

/// The same contacts in the same order, to the bit.
void expectSameContacts(const std::vector<SphereContact>& found,
                        const std::vector<SphereContact>& expected) {
  ASSERT_EQ(found.size(), expected.size());
  for (std::size_t k = 0; k < found.size(); ++k) {
    EXPECT_EQ(found[k].node_a, expected[k].node_a) << "contact " << k;
    EXPECT_EQ(found[k].node_b, expected[k].node_b) << "contact " << k;
    EXPECT_EQ(found[k].point_a, expected[k].point_a) << "contact " << k;
    EXPECT_EQ(found[k].point_b, expected[k].point_b) << "contact " << k;
    EXPECT_EQ(found[k].depth_m, expected[k].depth_m) << "contact " << k;
    EXPECT_EQ(found[k].position, expected[k].position) << "contact " << k;
    EXPECT_EQ(found[k].normal, expected[k].normal) << "contact " << k;
  }
}

class VectorWidthTest : public ::testing::TestWithParam<VectorWidth> {};

// The vector leaf tests (four or eight leaves or points per instruction) find the same
// contacts as the portable ones, bit for bit, for leaves of up to eight points and larger.
TEST_P(VectorWidthTest, FindsTheSameContactsBitForBit) {
  if (widestVectors() < GetParam()) GTEST_SKIP() << "this CPU has not these vectors";
  for (const auto& [config_a, config_b] :
       {std::pair<SphereTreeConfig, SphereTreeConfig>{{2, 8}, {2, 5}}, {{2, 20}, {3, 13}}}) {
    for (std::uint64_t seed = 0; seed < 11; ++seed) {
      TwoBodies scene = randomScene(seed, seed >= 6 ? 250 : 700, seed >= 6 && seed < 9 ? 200 : 600);
      const double contact_distance = seed >= 6 ? kSparseContact : 0.02;
      SphereTree ta(scene.a, config_a);
      SphereTree tb(scene.b, config_b);
      std::vector<SphereContact> portable;
      std::vector<SphereContact> wide;
      QueryCounters counters;
      const int leaves = std::max(ta.maxLevel(), tb.maxLevel());
      HierarchyQuery(VectorWidth::kPortable)
          .collide(ta, tb, leaves, contact_distance, portable, counters);
      HierarchyQuery(GetParam()).collide(ta, tb, leaves, contact_distance, wide, counters);
      ASSERT_FALSE(portable.empty()) << "seed " << seed;
      SCOPED_TRACE("seed " + std::to_string(seed));
      expectSameContacts(wide, portable);
    }
  }
}

// Two blocks of points on grids of 1/128 m, the second offset by half a step across the gap,
// so that coordinates and squared distances are exact: a point of the first block has four
// points of the second at its least distance, many of its neighbours have too, and each width
// reports the first such pair in the leaves' row-major order, as the portable test does.
TEST_P(VectorWidthTest, BreaksTiesAsThePortableTestDoes) {
  if (widestVectors() < GetParam()) GTEST_SKIP() << "this CPU has not these vectors";
  const auto block = [](const Eigen::Vector3d& corner) {
    Points points;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 8; ++j) {
        for (int k = 0; k < 8; ++k) points.push_back(corner + Eigen::Vector3d(i, j, k) / 128.0);
      }
    }
    return points;
  };
  TwoBodies scene{
      ShapeMatchingBody(block(Eigen::Vector3d::Zero()), ShapeMatchingConfig{}),
      ShapeMatchingBody(block(Eigen::Vector3d(7.0, 0.5, 0.5) / 128.0), ShapeMatchingConfig{})};
  for (const SphereTreeConfig& config : {SphereTreeConfig{2, 8}, SphereTreeConfig{2, 5}}) {
    SphereTree ta(scene.a, config);
    SphereTree tb(scene.b, config);
    const int leaves = std::max(ta.maxLevel(), tb.maxLevel());
    std::vector<SphereContact> portable;
    std::vector<SphereContact> wide;
    QueryCounters counters;
    HierarchyQuery(VectorWidth::kPortable).collide(ta, tb, leaves, 0.02, portable, counters);
    HierarchyQuery(GetParam()).collide(ta, tb, leaves, 0.02, wide, counters);
    ASSERT_FALSE(portable.empty());
    expectSameContacts(wide, portable);
  }
}

INSTANTIATE_TEST_SUITE_P(Widths, VectorWidthTest,
                         ::testing::Values(VectorWidth::kAvx2, VectorWidth::kAvx512),
                         [](const auto& info) {
                           return std::string(info.param == VectorWidth::kAvx2 ? "avx2" : "avx512");
                         });

TEST(LevelOfDetail, EveryLevelCoversTheClosePointPairs) {
  const double contact_distance = 0.02;
  TwoBodies scene = randomScene(7);
  SphereTree ta(scene.a, {2, 6});
  SphereTree tb(scene.b, {2, 6});
  const auto truth = bruteForcePairs(scene.a.positions(), scene.b.positions(), contact_distance);
  HierarchyQuery query;
  for (int level = 0; level <= std::max(ta.maxLevel(), tb.maxLevel()); ++level) {
    ta.beginCycle();
    tb.beginCycle();
    std::vector<SphereContact> contacts;
    QueryCounters counters;
    query.collide(ta, tb, level, contact_distance, contacts, counters);
    const auto covered = coveredPairs(ta, tb, contacts);
    for (const auto& pair : truth) ASSERT_TRUE(covered.count(pair)) << "level " << level;
    for (const auto& c : contacts) {
      EXPECT_LE(c.level, level);
      EXPECT_GT(c.depth_m, 0.0);
    }
  }
}

// A contact names a point pair only at the leaves, where it is the closest pair of its two
// leaves; above them the record keeps its default points.
TEST(LevelOfDetail, ContactsNameTheirClosestPairOnlyAtTheLeaves) {
  const double contact_distance = 0.02;
  TwoBodies scene = randomScene(7);
  SphereTree ta(scene.a, {2, 6});
  SphereTree tb(scene.b, {2, 6});
  const int leaves = std::max(ta.maxLevel(), tb.maxLevel());
  HierarchyQuery query;
  for (const int level : {0, leaves / 2, leaves - 1, leaves}) {
    ta.beginCycle();
    tb.beginCycle();
    std::vector<SphereContact> contacts;
    QueryCounters counters;
    query.collide(ta, tb, level, contact_distance, contacts, counters);
    ASSERT_FALSE(contacts.empty()) << "level " << level;
    for (const auto& c : contacts) {
      if (level < leaves) {
        EXPECT_EQ(c.point_a, SphereContact::kNoPoint) << "level " << level;
        EXPECT_EQ(c.point_b, SphereContact::kNoPoint) << "level " << level;
        continue;
      }
      ASSERT_LT(c.point_a, scene.a.pointCount());
      ASSERT_LT(c.point_b, scene.b.pointCount());
      const Eigen::Vector3d& x = scene.a.positions()[c.point_a];
      const Eigen::Vector3d& y = scene.b.positions()[c.point_b];
      EXPECT_NEAR((x - y).norm(), contact_distance - c.depth_m, 1e-12);
      EXPECT_TRUE(c.position.isApprox(0.5 * (x + y), 1e-12));
    }
  }
}

/// A static floor (two layers of points 2 cm apart, as the demo scenes' floors) and a
/// deformed object resting on it, from a seed: `points` of the object (250: few enough
/// buckets to be tested as a set).
struct FloorScene {
  ShapeMatchingBody floor;
  ShapeMatchingBody object;
};

FloorScene floorScene(std::uint64_t seed, std::size_t points) {
  Points floor;
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 40; ++j) {
      for (int k = 0; k < 2; ++k) floor.emplace_back(-0.4 + 0.02 * i, -0.4 + 0.02 * j, -0.02 * k);
    }
  }
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  ShapeMatchingConfig config;
  config.mode = static_cast<DeformationMode>(seed % 3);
  config.clusters = 1 + static_cast<int>(seed % 2);
  // Its lowest points sink up to 1 cm into the floor's top layer or hover up to 1 cm above.
  const Points rest = shifted(sampleEllipsoid(points, {0.15, 0.1, 0.08}, seed + 3),
                              {0.1 * unit(engine), 0.1 * unit(engine), 0.08 + 0.01 * unit(engine)});
  FloorScene scene{ShapeMatchingBody(floor, ShapeMatchingConfig{}),
                   ShapeMatchingBody(rest, config)};
  std::normal_distribution<double> noise(0.0, 0.005);
  Points deformed = scene.object.restPositions();
  for (auto& x : deformed) x += Eigen::Vector3d(noise(engine), noise(engine), noise(engine));
  scene.object.setPositions(deformed);
  return scene;
}

// A static object's slabs prune the descent to the leaves without changing a contact: the
// same contacts, in the same order, to the bit, for either object first, every vector width
// and an object small enough to be tested as a set of buckets or not; and fewer point tests.
TEST(NodeSlabsInTheQuery, FindTheSameLeafContactsWithFewerPointTests) {
  for (std::uint64_t seed = 0; seed < 6; ++seed) {
    const std::size_t points = seed < 3 ? 250 : 3000;
    FloorScene scene = floorScene(seed, points);
    SphereTree floor(scene.floor, {2, 8});
    SphereTree object(scene.object, {2, 8});
    NodeSlabs slabs;
    slabs.compute(floor, scene.floor.positions());
    const double contact_distance = 0.02;
    const int leaves = std::max(floor.maxLevel(), object.maxLevel());
    for (const VectorWidth width : kVectorWidths) {
      for (const bool floor_first : {true, false}) {
        SCOPED_TRACE("seed " + std::to_string(seed) + ", width " +
                     std::to_string(static_cast<int>(width)) +
                     (floor_first ? ", floor first" : ""));
        SphereTree& a = floor_first ? floor : object;
        SphereTree& b = floor_first ? object : floor;
        const PairSlabs pair_slabs{floor_first ? &slabs : nullptr, floor_first ? nullptr : &slabs};
        std::vector<SphereContact> without, with;
        QueryCounters counted_without, counted_with;
        HierarchyQuery query(width);
        query.collide(a, b, leaves, contact_distance, without, counted_without);
        query.collide(a, b, leaves, contact_distance, with, counted_with, pair_slabs);
        ASSERT_FALSE(without.empty());
        expectSameContacts(with, without);
        EXPECT_LT(counted_with.point_tests, counted_without.point_tests);
        const auto truth = floor_first ? bruteForcePairs(scene.floor.positions(),
                                                         scene.object.positions(), contact_distance)
                                       : bruteForcePairs(scene.object.positions(),
                                                         scene.floor.positions(), contact_distance);
        const auto covered = coveredPairs(a, b, with);
        for (const auto& pair : truth) ASSERT_TRUE(covered.count(pair));
      }
    }
  }
}

// Above the leaves a contact is two overlapping spheres, whatever their points: the slabs
// change nothing there.
TEST(NodeSlabsInTheQuery, LeaveTheCoarseLevelsAlone) {
  FloorScene scene = floorScene(4, 3000);
  SphereTree floor(scene.floor, {2, 8});
  SphereTree object(scene.object, {2, 8});
  NodeSlabs slabs;
  slabs.compute(floor, scene.floor.positions());
  HierarchyQuery query;
  for (int level = 0; level < std::max(floor.maxLevel(), object.maxLevel()); ++level) {
    std::vector<SphereContact> without, with;
    QueryCounters counters;
    query.collide(floor, object, level, 0.02, without, counters);
    query.collide(floor, object, level, 0.02, with, counters, PairSlabs{&slabs, nullptr});
    ASSERT_FALSE(without.empty()) << "level " << level;
    SCOPED_TRACE("level " + std::to_string(level));
    expectSameContacts(with, without);
  }
}

/// The work of one leaf-level query between two bodies, on fresh trees.
struct Work {
  std::size_t nodes;
  std::size_t spheres_updated;
  std::size_t pairs_tested;
  std::size_t contacts;
};

Work leafQuery(const ShapeMatchingBody& a, const ShapeMatchingBody& b, double contact_distance) {
  SphereTree ta(a, {2, 8});
  SphereTree tb(b, {2, 8});
  ta.beginCycle();
  tb.beginCycle();
  HierarchyQuery query;
  std::vector<SphereContact> contacts;
  QueryCounters counters;
  query.collide(ta, tb, 1000, contact_distance, contacts, counters);
  return {ta.nodeCount() + tb.nodeCount(),
          ta.counters().spheres_updated + tb.counters().spheres_updated, counters.node_pairs_tested,
          contacts.size()};
}

TEST(LevelOfDetail, SeparatedObjectsCostOneSphereTest) {
  ShapeMatchingConfig config;
  config.mode = DeformationMode::kQuadratic;
  const ShapeMatchingBody a(sampleBox(5000, {0.2, 0.2, 0.2}, 1), config);
  const ShapeMatchingBody b(shifted(sampleBox(5000, {0.2, 0.2, 0.2}, 2), {2, 0, 0}), config);
  const Work work = leafQuery(a, b, 0.01);
  EXPECT_EQ(work.contacts, 0u);
  EXPECT_EQ(work.pairs_tested, 1u);
  EXPECT_EQ(work.spheres_updated, 2u);
}

// Output sensitivity, counted: two balls 0.1 m apart touch through a fixed bump of 20
// points each. The nodes updated and the pairs tested must stay about the same from 8k to
// 160k points per object, while the hierarchies grow 20-fold.
Points ballWithBump(std::size_t n, std::uint64_t seed, double bump_from, double bump_to) {
  Points points = sampleEllipsoid(n, {0.5, 0.5, 0.5}, seed);
  for (int i = 0; i < 20; ++i) {
    const double t = i / 19.0;
    points.emplace_back(bump_from + t * (bump_to - bump_from), 0.002 * std::cos(i),
                        0.002 * std::sin(i));
  }
  return points;
}

Work touchingBalls(std::size_t points_per_object) {
  ShapeMatchingConfig config;
  config.mode = DeformationMode::kQuadratic;
  ShapeMatchingBody a(ballWithBump(points_per_object, 1, 0.5, 0.55), config);
  ShapeMatchingBody b(shifted(ballWithBump(points_per_object, 2, -0.5, -0.55), {1.1, 0, 0}),
                      config);
  for (ShapeMatchingBody* body : {&a, &b}) body->step(0.01, Eigen::Vector3d(0, 0, -9.81));
  return leafQuery(a, b, 0.004);
}

TEST(OutputSensitivity, WorkFollowsTheContactsNotThePoints) {
  const Work small = touchingBalls(8000);
  const Work large = touchingBalls(160000);
  ASSERT_GT(small.contacts, 0u);
  ASSERT_GT(large.contacts, 0u);
  EXPECT_GT(large.nodes, 15 * small.nodes);
  EXPECT_LE(large.spheres_updated, 2 * small.spheres_updated)
      << small.spheres_updated << " -> " << large.spheres_updated;
  EXPECT_LE(large.pairs_tested, 2 * small.pairs_tested)
      << small.pairs_tested << " -> " << large.pairs_tested;
  RecordProperty("spheres_updated_8k", static_cast<int>(small.spheres_updated));
  RecordProperty("spheres_updated_160k", static_cast<int>(large.spheres_updated));
  RecordProperty("pairs_tested_8k", static_cast<int>(small.pairs_tested));
  RecordProperty("pairs_tested_160k", static_cast<int>(large.pairs_tested));
}

}  // namespace
}  // namespace deformable_collision
