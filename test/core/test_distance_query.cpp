// HierarchyDistance through Scene::closestPoints against brute force on the objects' points,
// for every pair of objects at every level of several deformed scenes: exact at the finest
// level, within the reported bound above it; disjoint, touching and far-apart pairs, and
// objects 1e5 m from the origin.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// The least distance of two point sets.
double bruteForceDistance(const Points& a, const Points& b) {
  double least = std::numeric_limits<double>::infinity();
  for (const auto& x : a) {
    for (const auto& y : b) least = std::min(least, (x - y).norm());
  }
  return least;
}

Points shifted(Points points, const Eigen::Vector3d& offset) {
  for (auto& p : points) p += offset;
  return points;
}

ObjectConfig softObject(const char* name, DeformationMode mode, int clusters) {
  ObjectConfig object;
  object.name = name;
  object.shape.mode = mode;
  object.shape.clusters = clusters;
  object.shape.stiffness = 0.3;
  return object;
}

/// A quadratic box and a linear ball dropped onto a static plate at `origin`, run for
/// `cycles` cycles: deformed by shape matching and the response.
std::unique_ptr<Scene> dropped(const Eigen::Vector3d& origin, int cycles) {
  SceneConfig config;
  config.contact_distance_m = 0.02;
  auto scene = std::make_unique<Scene>(config);
  ObjectConfig plate;
  plate.name = "plate";
  plate.kind = ObjectKind::kStatic;
  scene->addObject(plate, shifted(sampleBox(1500, {0.3, 0.3, 0.01}, 1), origin));
  scene->addObject(
      softObject("box", DeformationMode::kQuadratic, 3),
      shifted(sampleBox(700, {0.08, 0.06, 0.05}, 2), origin + Eigen::Vector3d(0.05, 0, 0.1)));
  scene->addObject(softObject("ball", DeformationMode::kLinear, 2),
                   shifted(sampleEllipsoid(600, {0.07, 0.07, 0.07}, 3),
                           origin + Eigen::Vector3d(-0.15, 0.05, 0.3)));
  for (int cycle = 0; cycle < cycles; ++cycle) scene->cycle();
  return scene;
}

/// S1's two soft balls thrown at each other, after `cycles` cycles.
std::unique_ptr<Scene> thrownBalls(int cycles) {
  auto scene = makeDemoScene(DemoScene::kTwoObjects, 3000);
  for (int cycle = 0; cycle < cycles; ++cycle) scene->cycle();
  return scene;
}

struct DistanceCase {
  const char* name;
  std::function<std::unique_ptr<Scene>()> make;
};

const DistanceCase kCases[] = {
    {"balls_apart", [] { return thrownBalls(0); }},
    {"balls_meeting", [] { return thrownBalls(60); }},
    {"dropped_at_rest_shape", [] { return dropped(Eigen::Vector3d::Zero(), 0); }},
    {"dropped_and_deformed", [] { return dropped(Eigen::Vector3d::Zero(), 50); }},
    {"dropped_1e5_m_away", [] { return dropped(Eigen::Vector3d(1e5, -1e5, 1e5), 50); }},
};

class DistanceQuery : public ::testing::TestWithParam<DistanceCase> {};

// Every pair at every level: the least distance of the points lies in [distance_m,
// distance_m + error_bound_m], equal to distance_m at the finest level, where the points are
// a closest pair of the objects' own points.
TEST_P(DistanceQuery, MatchesBruteForceWithinItsBoundAtEveryLevel) {
  auto scene = GetParam().make();
  for (std::size_t a = 0; a < scene->objectCount(); ++a) {
    for (std::size_t b = a + 1; b < scene->objectCount(); ++b) {
      const Points& points_a = scene->body(a).positions();
      const Points& points_b = scene->body(b).positions();
      const double truth = bruteForceDistance(points_a, points_b);
      const double magnitude = std::max(points_a.front().cwiseAbs().maxCoeff(), 1.0);
      const double rounding = 1e-12 * magnitude;
      for (int level = 0; level <= scene->maxLevel(); ++level) {
        const std::string where = "objects " + std::to_string(a) + ", " + std::to_string(b) +
                                  " at level " + std::to_string(level);
        const auto closest = scene->closestPoints(a, b, level, 10.0);
        ASSERT_TRUE(closest) << where;
        EXPECT_NEAR(closest->normal.norm(), 1.0, 1e-12) << where;
        EXPECT_LE(closest->distance_m, truth + rounding) << where;
        EXPECT_GE(closest->distance_m + closest->error_bound_m, truth - rounding) << where;
        if (level < scene->maxLevel()) continue;
        EXPECT_NEAR(closest->distance_m, truth, rounding) << where;
        EXPECT_EQ(closest->error_bound_m, 0.0) << where;
        ASSERT_LT(closest->index_a, points_a.size()) << where;
        ASSERT_LT(closest->index_b, points_b.size()) << where;
        EXPECT_EQ(closest->point_a, points_a[closest->index_a]) << where;
        EXPECT_EQ(closest->point_b, points_b[closest->index_b]) << where;
        EXPECT_NEAR((closest->point_a - closest->point_b).norm(), truth, rounding) << where;
      }
    }
  }
}

// A maximum below the least distance: nothing at the finest level; above it, at most a lower
// bound within the maximum.
TEST_P(DistanceQuery, FindsNothingBeyondTheMaximumDistance) {
  auto scene = GetParam().make();
  for (std::size_t a = 0; a < scene->objectCount(); ++a) {
    for (std::size_t b = a + 1; b < scene->objectCount(); ++b) {
      const double truth =
          bruteForceDistance(scene->body(a).positions(), scene->body(b).positions());
      const double max_distance = 0.9 * truth;
      EXPECT_FALSE(scene->closestPoints(a, b, scene->maxLevel(), max_distance));
      for (int level = 0; level < scene->maxLevel(); ++level) {
        const auto closest = scene->closestPoints(a, b, level, max_distance);
        if (closest) {
          EXPECT_LE(closest->distance_m, max_distance);
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, DistanceQuery, ::testing::ValuesIn(kCases),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(DistanceQuery, RefusesBadArguments) {
  auto scene = dropped(Eigen::Vector3d::Zero(), 0);
  EXPECT_THROW(scene->closestPoints(0, 0, 0, 1.0), std::invalid_argument);
  EXPECT_THROW(scene->closestPoints(0, 3, 0, 1.0), std::out_of_range);
  EXPECT_THROW(scene->closestPoints(0, 1, scene->maxLevel() + 1, 1.0), std::out_of_range);
  EXPECT_THROW(scene->closestPoints(0, 1, -1, 1.0), std::out_of_range);
  EXPECT_THROW(scene->closestPoints(0, 1, 0, -1.0), std::invalid_argument);
  EXPECT_THROW(scene->closestPoints(0, 1, 0, std::nan("")), std::invalid_argument);
}

/// Two randomly deformed bodies from `seed` (a random mode and stiffness, noise and a bend,
/// then steps), `gap_m` apart before the deformation: overlapping when negative.
std::pair<ShapeMatchingBody, ShapeMatchingBody> randomBodies(std::uint64_t seed, double gap_m) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  ShapeMatchingConfig config;
  config.mode = static_cast<DeformationMode>(seed % 3);
  config.clusters = 1 + static_cast<int>(seed % 4);
  config.stiffness = unit(engine);
  std::pair<ShapeMatchingBody, ShapeMatchingBody> bodies{
      ShapeMatchingBody(sampleEllipsoid(500, {0.2, 0.15, 0.1}, 2 * seed + 1), config),
      ShapeMatchingBody(shifted(sampleEllipsoid(400, {0.1, 0.2, 0.15}, 2 * seed + 2),
                                {0.3 + gap_m, 0.05 * unit(engine), 0.0}),
                        config)};
  std::normal_distribution<double> noise(0.0, 0.01);
  for (ShapeMatchingBody* body : {&bodies.first, &bodies.second}) {
    Points p = body->restPositions();
    for (auto& x : p) {
      x += Eigen::Vector3d(noise(engine), noise(engine), noise(engine) + 0.5 * x.y() * x.y());
    }
    body->setPositions(p);
    for (int s = 0; s < 4; ++s) body->step(0.02, Eigen::Vector3d(0.0, 0.0, -1.0));
  }
  return bodies;
}

// Random deformed pairs, apart, near and overlapping, at every level of their trees.
TEST(DistanceQuery, RandomDeformedPairsMatchBruteForceAtEveryLevel) {
  HierarchyDistance distance;
  for (std::uint64_t seed = 0; seed < 12; ++seed) {
    const double gap_m = 0.1 * static_cast<double>(seed % 4) - 0.1;
    auto [body_a, body_b] = randomBodies(seed, gap_m);
    SphereTree a(body_a, {2, 4});
    SphereTree b(body_b, {3, 6});
    a.beginCycle();
    b.beginCycle();
    const double truth = bruteForceDistance(body_a.positions(), body_b.positions());
    const int finest = std::max(a.maxLevel(), b.maxLevel());
    for (int level = 0; level <= finest; ++level) {
      QueryCounters counters;
      const auto closest = distance.closest(a, b, level, 10.0, counters);
      const std::string where = "seed " + std::to_string(seed) + ", level " + std::to_string(level);
      ASSERT_TRUE(closest) << where;
      EXPECT_LE(closest->distance_m, truth + 1e-12) << where;
      EXPECT_GE(closest->distance_m + closest->error_bound_m, truth - 1e-12) << where;
      if (level == finest) {
        EXPECT_NEAR(closest->distance_m, truth, 1e-12) << where;
      }
    }
  }
}

// The finest answer visits a small part of the leaf pairs: the work follows the pairs near
// the closest, not the points.
TEST(DistanceQuery, ExactAnswerVisitsFewLeafPairs) {
  const ShapeMatchingBody body_a(sampleEllipsoid(8000, {0.2, 0.15, 0.1}, 5), {});
  const ShapeMatchingBody body_b(
      shifted(sampleEllipsoid(8000, {0.1, 0.2, 0.15}, 6), {0.5, 0.1, 0.0}), {});
  SphereTree a(body_a, {});
  SphereTree b(body_b, {});
  a.beginCycle();
  b.beginCycle();
  HierarchyDistance distance;
  QueryCounters counters;
  const int finest = std::max(a.maxLevel(), b.maxLevel());
  const auto closest = distance.closest(a, b, finest, 10.0, counters);
  ASSERT_TRUE(closest);
  EXPECT_NEAR(closest->distance_m, bruteForceDistance(body_a.positions(), body_b.positions()),
              1e-12);
  const double leaf_pairs =
      static_cast<double>(a.leafSpheres().x.size()) * static_cast<double>(b.leafSpheres().x.size());
  EXPECT_LT(static_cast<double>(counters.leaf_pairs_tested), 1e-3 * leaf_pairs);
}

}  // namespace
}  // namespace deformable_collision
