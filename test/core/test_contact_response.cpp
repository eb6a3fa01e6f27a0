// Contact response seen through the Scene (response/contact_response.h is internal): a box
// dropped on a floor rests, soft balls are dented only where short of the surface, still
// objects carry no velocity, piles come to rest, and the jaws of a gripper hold a fruit.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

// ---------------------------------------------------------------------------------------
// A rigid box dropped on a floor comes to rest at every level of detail, 0 to the scene's
// finest: no penetration persists, it does not bounce or sink, and it rests at half the
// contact distance above the floor (up to the contact distance more at coarse levels, whose
// nodes are larger).

/// Every level of the floor and the dropped box, 0 to the finest.
std::vector<int> droppedBoxLevels() {
  auto scene = sceneOnFloor(-1);
  addDroppedBox(*scene);
  std::vector<int> levels(scene->maxLevel() + 1);
  std::iota(levels.begin(), levels.end(), 0);
  return levels;
}

class RestingBoxTest : public ::testing::TestWithParam<int> {};

TEST_P(RestingBoxTest, LandsAndRestsAtHalfTheContactDistance) {
  auto scene_on_floor = sceneOnFloor(GetParam());
  Scene& scene = *scene_on_floor;
  const std::size_t index = addDroppedBox(scene);
  scene.setLevel(GetParam());

  // Rest is still: over the last 50 cycles no cycle leaves the box moving, and it does not
  // creep (a response that stops a point twice sends a resting box up every cycle).
  double deepest = std::numeric_limits<double>::infinity();
  double late_fastest = 0.0;
  double late_lowest = std::numeric_limits<double>::infinity();
  double late_highest = -std::numeric_limits<double>::infinity();
  constexpr int kCycles = 150, kLateCycles = 50;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    scene.cycle();
    const double lowest = lowestZ(scene.body(index));
    deepest = std::min(deepest, lowest);
    if (cycle >= kCycles - kLateCycles) {
      late_fastest = std::max(late_fastest, scene.body(index).meanVelocity().norm());
      late_lowest = std::min(late_lowest, lowest);
      late_highest = std::max(late_highest, lowest);
    }
  }
  EXPECT_GE(deepest, 0.0) << "the box entered the floor";
  EXPECT_GE(lowestZ(scene.body(index)), 0.005);
  EXPECT_LE(lowestZ(scene.body(index)), 0.03);
  EXPECT_LT(late_fastest, 1e-3) << "m/s";
  EXPECT_LT(late_highest - late_lowest, 1e-4) << "m";
}

INSTANTIATE_TEST_SUITE_P(Levels, RestingBoxTest, ::testing::ValuesIn(droppedBoxLevels()),
                         [](const auto& info) { return "level_" + std::to_string(info.param); });

// ---------------------------------------------------------------------------------------
// A soft ball set 1 cm into the floor, without gravity, at levels above the leaves: one
// response clears every point of it to half the contact distance above the floor, and the
// points it dents are only those that its whole move left short of that. A coarse node holds
// hundreds of points, most of them above the floor: dented whole by its deepest point's
// depth, all of them would move.

class CoarseDentTest : public ::testing::TestWithParam<std::tuple<int, DeformationMode>> {};

TEST_P(CoarseDentTest, MovesOnlyThePointsShortOfTheSurface) {
  const auto [level, mode] = GetParam();
  SceneConfig weightless;
  weightless.gravity_mps2.setZero();
  auto scene_on_floor = sceneOnFloor(level, weightless);
  Scene& scene = *scene_on_floor;
  ObjectConfig ball;
  ball.name = "ball";
  ball.shape.mode = mode;
  ball.shape.stiffness = 0.2;
  Points points = sampleEllipsoid(1500, {0.08, 0.08, 0.08}, 21);
  for (auto& p : points) p.z() += 0.07;
  const std::size_t index = scene.addObject(ball, points);
  ASSERT_LT(level, scene.maxLevel());

  const double cleared_z = 0.5 * scene.config().contact_distance_m;
  scene.cycle();
  // The object's own move is its top point's, which nothing dents.
  const auto top = std::max_element(points.begin(), points.end(),
                                    [](const auto& p, const auto& q) { return p.z() < q.z(); });
  const double moved_up = scene.body(index).positions()[top - points.begin()].z() - top->z();
  EXPECT_GT(moved_up, 0.0);
  std::size_t moved_more = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (scene.body(index).positions()[i].z() - points[i].z() <= moved_up + 1e-9) continue;
    ++moved_more;
    // The floor's surface is its nodes' fitted planes, true to a fraction of a millimetre.
    EXPECT_LT(points[i].z() + moved_up, cleared_z + 1e-3) << "point " << i << " was clear";
  }
  EXPECT_GT(moved_more, 0u);
  EXPECT_LT(scene.stats().points_displaced, points.size() / 10);
  EXPECT_GE(lowestZ(scene.body(index)), cleared_z - 1e-9);
}

INSTANTIATE_TEST_SUITE_P(LevelsAndModes, CoarseDentTest,
                         ::testing::Combine(::testing::Values(1, 2, 3),
                                            ::testing::Values(DeformationMode::kLinear,
                                                              DeformationMode::kQuadratic)),
                         [](const auto& info) {
                           return "level_" + std::to_string(std::get<0>(info.param)) + "_" +
                                  toString(std::get<1>(info.param));
                         });

// ---------------------------------------------------------------------------------------
// An object that stays put carries no velocity. Where static friction holds a pair in place
// (its slip taken back), a sliding velocity along a coarse normal tilted past the friction
// cone used to stay: the object stood still while its velocity pointed down the slope at
// several cm/s, every cycle, and the objects it carried took that velocity on.

struct PileCase {
  std::size_t points;
  int level;
};

void PrintTo(const PileCase& c, std::ostream* os) {
  *os << c.points << " points, level " << c.level;
}

class StillObjectTest : public ::testing::TestWithParam<PileCase> {};

TEST_P(StillObjectTest, CarriesNoVelocity) {
  const auto& c = GetParam();
  auto scene = makeDemoScene(DemoScene::kPile, c.points);
  for (int cycle = 0; cycle < 150; ++cycle) scene->cycle();  // settles at the finest level
  scene->setLevel(c.level);
  // position[k], velocity[k]: each object's mean after k cycles at the level.
  std::vector<std::vector<Eigen::Vector3d>> position, velocity;
  const auto record = [&] {
    position.emplace_back();
    velocity.emplace_back();
    for (std::size_t o = 0; o < scene->objectCount(); ++o) {
      position.back().push_back(scene->body(o).meanPosition());
      velocity.back().push_back(scene->body(o).meanVelocity());
    }
  };
  constexpr int kCycles = 60;
  record();
  for (int cycle = 0; cycle <= kCycles; ++cycle) {
    scene->cycle();
    record();
  }
  const auto still = [&](int k, std::size_t o) {
    return (position[k + 1][o] - position[k][o]).norm() / scene->config().dt_s < 0.005;
  };
  // From cycle 40 (the level's first cycles move objects apart to its spheres). An object
  // that starts to move leaves a cycle with a velocity it has not moved by yet; one that
  // stays put in that cycle and in the next had nothing to move by.
  for (int k = 40; k <= kCycles; ++k) {
    for (std::size_t o = 0; o < scene->objectCount(); ++o) {
      if (scene->objectConfig(o).kind != ObjectKind::kDynamic) continue;
      if (!still(k - 1, o) || !still(k, o)) continue;
      EXPECT_LT(velocity[k][o].norm(), 0.05) << scene->objectConfig(o).name << " after cycle " << k;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Piles, StillObjectTest,
                         ::testing::Values(PileCase{30000, 2}, PileCase{60000, 2},
                                           PileCase{60000, 4}));

// A dropped pile comes to rest at the coarse levels: over the last 50 of 300 cycles its
// soft points move at less than 2.5 mm/s on the mean. At level 0 each object is one sphere,
// and a sphere wedged between tilted neighbours below it, each half carried by the other,
// kept a velocity into them that the pushes took back every cycle: 8 to 13 mm/s, with one
// pass over the pairs' velocities. At this pile's finest level its objects (100 points each)
// are sparser than the contact distance lets the leaves hold apart; the 131k-point pile of
// `bench_scene s2` rests there (bench/results/s2.md). Level 0 also runs with other leaf
// sizes, which reorder the points and so every sum: an object pushed into a wall by a
// neighbour was dented flat against it and then flapped at 2 m/s for good (7.8 mm/s on the
// mean with leaf_size 12, docs/design.md "Pushed into a wall"); whether a pile rests must not
// hang on the order of its points.
struct PileRestCase {
  int level;
  int leaf_size;
};

class PileRestTest : public ::testing::TestWithParam<PileRestCase> {};

TEST_P(PileRestTest, ComesToRest) {
  SceneConfig config;
  config.contact_distance_m = 0.03;
  config.tree.leaf_size = GetParam().leaf_size;
  auto scene = makeDemoScene(DemoScene::kPile, 30000, config);
  scene->setLevel(GetParam().level);
  constexpr int kCycles = 300, kLateCycles = 50;
  double late_mean_speed = 0.0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    scene->cycle();
    if (cycle < kCycles - kLateCycles) continue;
    late_mean_speed += meanDynamicPointSpeed(*scene) / kLateCycles;
  }
  EXPECT_LT(late_mean_speed, 0.0025) << "m/s";
}

INSTANTIATE_TEST_SUITE_P(Levels, PileRestTest,
                         ::testing::Values(PileRestCase{0, 8}, PileRestCase{1, 8},
                                           PileRestCase{2, 8}, PileRestCase{3, 8},
                                           PileRestCase{0, 6}, PileRestCase{0, 10},
                                           PileRestCase{0, 12}),
                         [](const auto& info) {
                           return "level_" + std::to_string(info.param.level) + "_leaf_size_" +
                                  std::to_string(info.param.leaf_size);
                         });

TEST(Scene, EnergyStaysBoundedWithoutExternalForces) {
  auto scene = makeDemoScene(DemoScene::kTwoObjects, 4000);
  const auto kinetic = [&] {
    double energy = 0.0;
    for (std::size_t o = 0; o < scene->objectCount(); ++o) {
      const auto& body = scene->body(o);
      for (const auto& v : body.velocities()) energy += 0.5 * body.pointMassKg() * v.squaredNorm();
    }
    return energy;
  };
  const double initial = kinetic();
  ASSERT_GT(initial, 0.0);
  bool touched = false;
  for (int cycle = 0; cycle < 200; ++cycle) {
    scene->cycle();
    touched = touched || scene->stats().contacts > 0;
    ASSERT_LE(kinetic(), initial * (1.0 + 1e-9)) << "cycle " << cycle;
  }
  EXPECT_TRUE(touched) << "the two objects must meet";
}

/// Every level of the gripper scene, 0 to the finest.
std::vector<int> gripperLevels() {
  std::vector<int> levels(makeDemoScene(DemoScene::kGripper)->maxLevel() + 1);
  std::iota(levels.begin(), levels.end(), 0);
  return levels;
}

/// The gripper scene as makeDemoScene builds it, with its jaws added in the given order: the
/// order in which their pairs with the fruit are resolved.
std::unique_ptr<Scene> gripperWithJaws(int level, const std::array<std::string, 2>& jaws) {
  SceneConfig config;
  config.level = level;
  const auto demo = makeDemoScene(DemoScene::kGripper, 0, config);
  auto scene = std::make_unique<Scene>(demo->config());
  for (const std::string& name : {std::string("floor"), std::string("fruit"), jaws[0], jaws[1]}) {
    const std::size_t object = *demo->findObject(name);
    scene->addObject(demo->objectConfig(object), demo->body(object).restPositions());
  }
  return scene;
}

/// How the fruit sits in the closed jaws: its extent across them at the end, and its centre
/// of mass across them over the last 60 of 350 cycles.
struct Squeezed {
  double low_m = 1.0;
  double high_m = -1.0;
  double least_center_m = 1.0;
  double most_center_m = -1.0;
};

Squeezed squeezeFruit(Scene& scene) {
  constexpr int kCycles = 350, kLateCycles = 60;
  const std::size_t fruit = *scene.findObject("fruit");
  Squeezed squeezed;
  for (int step = 0; step < kCycles; ++step) {
    driveDemoScene(DemoScene::kGripper, scene, step * scene.config().dt_s);
    scene.cycle();
    if (step < kCycles - kLateCycles) continue;
    const double center = scene.body(fruit).meanPosition().x();
    squeezed.least_center_m = std::min(squeezed.least_center_m, center);
    squeezed.most_center_m = std::max(squeezed.most_center_m, center);
  }
  for (const auto& p : scene.body(fruit).positions()) {
    squeezed.low_m = std::min(squeezed.low_m, p.x());
    squeezed.high_m = std::max(squeezed.high_m, p.x());
  }
  return squeezed;
}

class SqueezeTest : public ::testing::TestWithParam<int> {};

// Both jaws hold the fruit: pairs resolved later must not push it back through earlier ones.
// Neither jaw is favoured: resolved one after the other, the later jaw's pair took the fruit
// clear of its jaw and deep into the other, and the fruit sat 2.5 cm towards the jaw resolved
// first, at coarse levels swinging by 3 to 4 cm between the sides, out of the jaws with
// the jaws' order swapped (docs/design.md, "Fixed partners taken together").
TEST_P(SqueezeTest, FruitStaysBetweenTheClosedJawsWhicheverComesFirst) {
  const double contact_distance = makeDemoScene(DemoScene::kGripper)->config().contact_distance_m;
  const std::array<std::array<std::string, 2>, 2> jaw_orders{
      {{"jaw_left", "jaw_right"}, {"jaw_right", "jaw_left"}}};
  std::array<Squeezed, 2> squeezed;
  for (std::size_t order = 0; order < jaw_orders.size(); ++order) {
    SCOPED_TRACE(jaw_orders[order][0] + " added first");
    auto scene = gripperWithJaws(GetParam(), jaw_orders[order]);
    const Squeezed& fruit = squeezed[order] = squeezeFruit(*scene);
    // The jaws' inner faces are at x = -0.06 and 0.06 once closed.
    EXPECT_GT(fruit.low_m, -0.06 - 0.25 * contact_distance);
    EXPECT_LT(fruit.high_m, 0.06 + 0.25 * contact_distance);
    EXPECT_LT(fruit.most_center_m - fruit.least_center_m, 0.25 * contact_distance) << "swing";
  }
  // Where the fruit settles depends on its own sampled points and its path into the jaws
  // (millimetres off the middle, by how much with the compiler's rounding), not on which jaw
  // comes first: with the bias the two orders put it 5 cm apart.
  EXPECT_NEAR(squeezed[0].least_center_m, squeezed[1].least_center_m, 1e-3);
  EXPECT_NEAR(squeezed[0].most_center_m, squeezed[1].most_center_m, 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Levels, SqueezeTest, ::testing::ValuesIn(gripperLevels()),
                         [](const auto& info) { return "level_" + std::to_string(info.param); });

}  // namespace
}  // namespace test
}  // namespace deformable_collision
