#include "deformable_collision/core/query/self_collision_query.h"

#include "deformable_collision/scenes/shapes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

constexpr double kContact = 0.005;
constexpr double kRestDistance = 4.0 * kContact;

Points rigidlyMoved(const Points& points) {
  const Eigen::Isometry3d pose =
      Eigen::Translation3d(0.3, -0.2, 0.1) *
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, -0.5).normalized());
  Points moved;
  for (const auto& p : points) moved.push_back(pose * p);
  return moved;
}

/// A body in state `deformed` of rest shape `rest`, and its tree.
struct Object {
  Object(const Points& rest, const Points& deformed, DeformationMode mode, int clusters)
      : body(rest, config(mode, clusters)),
        tree((body.setPositions(deformed), body), {2, 8}),
        rest_spheres(tree) {
    tree.beginCycle();
  }
  static ShapeMatchingConfig config(DeformationMode mode, int clusters) {
    ShapeMatchingConfig c;
    c.mode = mode;
    c.clusters = clusters;
    return c;
  }
  ShapeMatchingBody body;
  SphereTree tree;
  RestSpheres rest_spheres;
};

std::vector<SphereContact> selfContacts(Object& object, int level, QueryCounters* counts = nullptr,
                                        VectorWidth width = widestVectors()) {
  std::vector<SphereContact> contacts;
  struct Sink final : ContactSink {
    explicit Sink(std::vector<SphereContact>& c) : c(c) {}
    void add(const SphereContact& contact) override { c.push_back(contact); }
    std::vector<SphereContact>& c;
  } sink(contacts);
  QueryCounters counters;
  SelfCollisionQuery query(width);
  object.tree.beginCycle();
  query.collide(object.tree, object.rest_spheres, level, kContact, kRestDistance, sink, counters);
  if (counts) *counts = counters;
  return contacts;
}

using PointPair = std::pair<std::uint32_t, std::uint32_t>;

/// Every pair of points closer than the contact distance and farther than the rest distance
/// at rest, by brute force.
std::vector<PointPair> bruteForcePairs(const ShapeMatchingBody& body) {
  std::vector<PointPair> pairs;
  const Points& x = body.positions();
  const Points& rest = body.restPositions();
  for (std::uint32_t i = 0; i < x.size(); ++i) {
    for (std::uint32_t j = i + 1; j < x.size(); ++j) {
      // Squares, as the query compares them: a grid's rest distances hit the threshold.
      if ((x[i] - x[j]).squaredNorm() < kContact * kContact &&
          (rest[i] - rest[j]).squaredNorm() > kRestDistance * kRestDistance) {
        pairs.emplace_back(i, j);
      }
    }
  }
  return pairs;
}

std::vector<std::uint32_t> pointsOf(const SphereTree& tree, std::uint32_t node) {
  const SphereNode& n = tree.node(node);
  return {tree.pointIndices().begin() + n.first_point,
          tree.pointIndices().begin() + n.first_point + n.point_count};
}

/// The unordered leaf pairs (a leaf with itself too) holding a brute-force pair.
std::set<PointPair> leafPairsHolding(const SphereTree& tree, const std::set<PointPair>& pairs) {
  std::set<PointPair> leaf_pairs;
  std::vector<std::uint32_t> leaves;
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    if (tree.node(n).isLeaf()) leaves.push_back(n);
  }
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    for (std::size_t j = i; j < leaves.size(); ++j) {
      bool holds = false;
      for (const std::uint32_t p : pointsOf(tree, leaves[i])) {
        for (const std::uint32_t q : pointsOf(tree, leaves[j])) {
          holds = holds || pairs.count({std::min(p, q), std::max(p, q)}) > 0;
        }
      }
      if (holds) leaf_pairs.insert({leaves[i], leaves[j]});
    }
  }
  return leaf_pairs;
}

struct Case {
  std::string name;
  Points rest;
  Points deformed;
};

std::vector<Case> foldedShapes() {
  const Points bar = gridBox(49, 7, 7, 0.005);     // 24 x 3 x 3 cm
  const Points plate = gridBox(41, 21, 2, 0.005);  // 20 x 10 cm, two layers
  const Points cable = gridBox(121, 2, 2, 0.004);  // 48 cm, 4 mm thick
  // Centre-line radii that bring the arms' inner faces within half a contact distance.
  return {{"bar", bar, bentIntoU(bar, 0.5 * (0.030 + 0.5 * kContact))},
          {"plate", plate, bentIntoU(plate, 0.5 * (0.005 + 0.5 * kContact))},
          {"cable", cable, bentIntoU(cable, 0.5 * (0.004 + 0.5 * kContact))}};
}

class FoldedShape : public ::testing::TestWithParam<std::tuple<DeformationMode, int>> {};

TEST_P(FoldedShape, LeafContactsAreExactlyTheBruteForcePairs) {
  const auto [mode, clusters] = GetParam();
  for (const Case& c : foldedShapes()) {
    Object object(c.rest, c.deformed, mode, clusters);
    const std::vector<PointPair> brute = bruteForcePairs(object.body);
    ASSERT_FALSE(brute.empty()) << c.name << ": the fold brings no points together";
    const std::set<PointPair> expected =
        leafPairsHolding(object.tree, std::set<PointPair>(brute.begin(), brute.end()));
    std::set<PointPair> found;
    for (const SphereContact& contact : selfContacts(object, -1)) {
      const PointPair leaves{std::min(contact.node_a, contact.node_b),
                             std::max(contact.node_a, contact.node_b)};
      EXPECT_TRUE(found.insert(leaves).second) << c.name << ": a leaf pair reported twice";
      const auto& x = object.body.positions();
      const auto& rest = object.body.restPositions();
      EXPECT_LT((x[contact.point_a] - x[contact.point_b]).norm(), kContact) << c.name;
      EXPECT_GT((rest[contact.point_a] - rest[contact.point_b]).squaredNorm(),
                kRestDistance * kRestDistance)
          << c.name;
      EXPECT_NEAR(contact.depth_m, kContact - (x[contact.point_a] - x[contact.point_b]).norm(),
                  1e-15)
          << c.name;
    }
    EXPECT_EQ(found, expected) << c.name;
  }
}

TEST_P(FoldedShape, EveryLevelCoversEveryBruteForcePair) {
  const auto [mode, clusters] = GetParam();
  for (const Case& c : foldedShapes()) {
    Object object(c.rest, c.deformed, mode, clusters);
    const std::vector<PointPair> brute = bruteForcePairs(object.body);
    for (int level = 0; level <= object.tree.maxLevel(); ++level) {
      std::set<PointPair> covered;
      for (const SphereContact& contact : selfContacts(object, level)) {
        EXPECT_NE(contact.node_a, contact.node_b);
        EXPECT_GT(contact.depth_m, 0.0);
        EXPECT_NEAR(contact.normal.norm(), 1.0, 1e-12);
        for (const std::uint32_t p : pointsOf(object.tree, contact.node_a)) {
          for (const std::uint32_t q : pointsOf(object.tree, contact.node_b)) {
            covered.insert({std::min(p, q), std::max(p, q)});
          }
        }
      }
      for (const PointPair& pair : brute) {
        ASSERT_TRUE(covered.count(pair)) << c.name << " level " << level << ": points "
                                         << pair.first << " and " << pair.second << " missed";
      }
    }
  }
}

TEST_P(FoldedShape, NoSelfContactsAtRestOrMovedRigidlyAtAnyLevel) {
  const auto [mode, clusters] = GetParam();
  for (const Case& c : foldedShapes()) {
    for (const Points& state : {c.rest, rigidlyMoved(c.rest)}) {
      Object object(c.rest, state, mode, clusters);
      for (int level = 0; level <= object.tree.maxLevel(); ++level) {
        EXPECT_TRUE(selfContacts(object, level).empty()) << c.name << " level " << level;
      }
    }
  }
}

TEST_P(FoldedShape, NoSelfContactsWhenMildlyBentOrSqueezed) {
  const auto [mode, clusters] = GetParam();
  for (const Case& c : foldedShapes()) {
    Points squeezed = c.rest;
    for (auto& p : squeezed)
      p = Eigen::Vector3d(0.8 * p.x(), 1.1 * p.y(), p.z() + 2.0 * p.x() * p.x());
    Object object(c.rest, bentIntoU(squeezed, 0.15), mode, clusters);
    EXPECT_TRUE(selfContacts(object, -1).empty()) << c.name;
  }
}

INSTANTIATE_TEST_SUITE_P(ModesAndClusters, FoldedShape,
                         ::testing::Combine(::testing::Values(DeformationMode::kRigid,
                                                              DeformationMode::kLinear,
                                                              DeformationMode::kQuadratic),
                                            ::testing::Values(1, 4)));

TEST(SelfCollisionQuery, RandomlyShakenBlobsMatchBruteForce) {
  // Points moved up to two contact distances each: neighbours cross, and pairs farther apart
  // than the rest distance meet, in every mode and cluster count.
  for (std::uint64_t seed = 0; seed < 12; ++seed) {
    std::mt19937_64 engine(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    const Points rest = gridBox(12, 9, 6, 0.004);
    Points shaken = rest;
    for (auto& p : shaken) {
      p += 2.0 * kContact * Eigen::Vector3d(unit(engine), unit(engine), unit(engine));
      p.z() += 3.0 * p.x() * p.x();
    }
    Object object(rest, shaken, static_cast<DeformationMode>(seed % 3), 1 + seed % 4);
    const std::vector<PointPair> brute = bruteForcePairs(object.body);
    ASSERT_FALSE(brute.empty()) << "seed " << seed;
    std::set<PointPair> found;
    for (const SphereContact& contact : selfContacts(object, -1)) {
      found.insert(
          {std::min(contact.node_a, contact.node_b), std::max(contact.node_a, contact.node_b)});
    }
    EXPECT_EQ(found, leafPairsHolding(object.tree, {brute.begin(), brute.end()}))
        << "seed " << seed;
  }
}

bool sameBits(const SphereContact& a, const SphereContact& b) {
  return a.node_a == b.node_a && a.node_b == b.node_b && a.point_a == b.point_a &&
         a.point_b == b.point_b && a.level == b.level && a.position == b.position &&
         a.normal == b.normal && a.depth_m == b.depth_m && a.error_bound_m == b.error_bound_m;
}

TEST(SelfCollisionQuery, WideVectorsFindTheSameContactsBitForBit) {
  if (widestVectors() == VectorWidth::kPortable) GTEST_SKIP() << "no AVX2 on this CPU";
  std::vector<Case> cases = foldedShapes();
  for (std::uint64_t seed = 0; seed < 4; ++seed) {
    std::mt19937_64 engine(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    Case blob{"blob " + std::to_string(seed), gridBox(12, 9, 6, 0.004), {}};
    for (const auto& p : blob.rest) {
      blob.deformed.push_back(p + 2.0 * kContact * Eigen::Vector3d(unit(engine), unit(engine), 0));
    }
    cases.push_back(blob);
  }
  for (const Case& c : cases) {
    for (const int clusters : {1, 4}) {
      Object object(c.rest, c.deformed, DeformationMode::kQuadratic, clusters);
      QueryCounters counters;
      const std::vector<SphereContact> portable =
          selfContacts(object, -1, &counters, VectorWidth::kPortable);
      const std::vector<SphereContact> wide =
          selfContacts(object, -1, &counters, VectorWidth::kAvx2);
      ASSERT_EQ(wide.size(), portable.size()) << c.name;
      ASSERT_FALSE(wide.empty()) << c.name;
      for (std::size_t i = 0; i < wide.size(); ++i) {
        EXPECT_TRUE(sameBits(wide[i], portable[i])) << c.name << ", contact " << i;
      }
    }
  }
}

TEST(SelfCollisionQuery, ANodeAgainstItselfIsNeverAContactAboveTheLeaves) {
  const Case bar = foldedShapes()[0];
  Object object(bar.rest, bar.deformed, DeformationMode::kLinear, 1);
  for (int level = 0; level < object.tree.maxLevel(); ++level) {
    for (const SphereContact& contact : selfContacts(object, level)) {
      EXPECT_NE(contact.node_a, contact.node_b) << "level " << level;
    }
  }
}

TEST(SelfCollisionQuery, CostFollowsTheFoldNotThePoints) {
  // The same bar at rest: the node pairs tested are those near each other at rest.
  const Case bar = foldedShapes()[0];
  Object resting(bar.rest, bar.rest, DeformationMode::kLinear, 1);
  QueryCounters at_rest;
  selfContacts(resting, -1, &at_rest);
  EXPECT_EQ(at_rest.point_tests, 0u);
  Object folded(bar.rest, bar.deformed, DeformationMode::kLinear, 1);
  QueryCounters at_fold;
  selfContacts(folded, -1, &at_fold);
  EXPECT_GT(at_fold.point_tests, 0u);
}

TEST(SelfCollisionQuery, AbsurdPointsGiveNoNaN) {
  const Case bar = foldedShapes()[0];
  Points broken = bar.deformed;
  broken[17] = Eigen::Vector3d::Constant(1e300);
  broken[300] = Eigen::Vector3d(1e300, -1e300, 1e300);
  Object object(bar.rest, bar.deformed, DeformationMode::kLinear, 2);
  object.body.setPositions(broken);
  for (int level = 0; level <= object.tree.maxLevel(); ++level) {
    for (const SphereContact& contact : selfContacts(object, level)) {
      EXPECT_TRUE(contact.position.allFinite() && contact.normal.allFinite() &&
                  std::isfinite(contact.depth_m) && std::isfinite(contact.error_bound_m));
    }
  }
}

}  // namespace
}  // namespace deformable_collision
