// The Scene API: built-in scenes, object kinds, levels, the time step, bad configurations,
// objects checked by name and kind, rest shapes and prepared objects.
#include "deformable_collision/core/scene/scene.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

// ---------------------------------------------------------------------------------------
// Built-in scenes, small: nothing becomes NaN, nothing runs away, nothing goes through the
// floor, at a coarse, a middle and the finest level.

struct SceneCase {
  const char* name;
  DemoScene scene;
  std::size_t points;
  int cycles;
  int coarsest_level;
};

void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.name; }

class BuiltInSceneTest : public ::testing::TestWithParam<SceneCase> {};

TEST_P(BuiltInSceneTest, StaysFiniteBoundedAndAboveTheFloor) {
  const auto& c = GetParam();
  const int finest = makeDemoScene(c.scene, c.points)->maxLevel();
  for (const int level : {c.coarsest_level, finest / 2, finest}) {
    SceneConfig config;
    config.level = level;
    auto scene = makeDemoScene(c.scene, c.points, config);
    const auto floor = scene->findObject("floor");
    for (int cycle = 0; cycle < c.cycles; ++cycle) {
      driveDemoScene(c.scene, *scene, cycle * config.dt_s);
      scene->cycle();
      ASSERT_TRUE(allFinite(*scene)) << "level " << level << " cycle " << cycle;
      ASSERT_LT(fastestPoint(*scene), 20.0) << "level " << level << " cycle " << cycle;
    }
    if (!floor) continue;
    for (std::size_t o = 0; o < scene->objectCount(); ++o) {
      if (scene->objectConfig(o).kind != ObjectKind::kDynamic) continue;
      EXPECT_GT(lowestZ(scene->body(o)), -scene->config().contact_distance_m)
          << scene->objectConfig(o).name << " at level " << level;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, BuiltInSceneTest,
    ::testing::Values(SceneCase{"two_objects", DemoScene::kTwoObjects, 4000, 150, 1},
                      SceneCase{"three_objects", DemoScene::kThreeObjects, 9000, 200, 1},
                      SceneCase{"gripper", DemoScene::kGripper, 3000, 200, 1},
                      SceneCase{"pile", DemoScene::kPile, 15000, 120, 1}),
    [](const auto& info) { return std::string(info.param.name); });

// A pile of more objects than S2's 300 spreads over a wider box: every object starts and
// stays between the walls and below their tops, and only the pile's count is chosen.
TEST(Scene, ALargerPileStandsInAWiderBox) {
  auto scene = makeDemoScene(DemoScene::kPile, 12000, SceneConfig{}, 600);
  ASSERT_EQ(scene->objectCount(), 605u);
  const auto inside = [&](const char* wall, int axis, double side) {
    const auto& walls = scene->body(*scene->findObject(wall)).positions();
    double face = side * std::numeric_limits<double>::infinity();
    for (const auto& p : walls) face = side > 0 ? std::min(face, p[axis]) : std::max(face, p[axis]);
    for (std::size_t o = 5; o < scene->objectCount(); ++o) {
      for (const auto& p : scene->body(o).positions()) {
        if (side * (face - p[axis]) <= 0.0 || p.z() > 2.0) return false;
      }
    }
    return true;
  };
  const auto between_the_walls = [&] {
    return inside("wall_x_minus", 0, -1.0) && inside("wall_x_plus", 0, 1.0) &&
           inside("wall_y_minus", 1, -1.0) && inside("wall_y_plus", 1, 1.0);
  };
  EXPECT_TRUE(between_the_walls()) << "at the start";
  for (int cycle = 0; cycle < 60; ++cycle) scene->cycle();
  ASSERT_TRUE(allFinite(*scene));
  EXPECT_TRUE(between_the_walls()) << "after 60 cycles";
  EXPECT_THROW(makeDemoScene(DemoScene::kGripper, 0, SceneConfig{}, 2), std::invalid_argument);
  EXPECT_THROW(makeDemoScene(DemoScene::kPile, 0, SceneConfig{}, 20000), std::invalid_argument);
}

TEST(Scene, StaticObjectsNeverMove) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects, 9000);
  const std::size_t floor = *scene->findObject("floor");
  const Points before = scene->body(floor).positions();
  for (int cycle = 0; cycle < 100; ++cycle) scene->cycle();
  EXPECT_EQ(scene->body(floor).positions(), before);
}

// What a running node may change (its reconfiguration): friction, a dynamic object's
// material, a tracked object's contact stiffness; other kinds and bad values are refused.
TEST(Scene, FrictionAndMaterialsChangeBetweenCyclesAndBadValuesAreRefused) {
  auto scene = makeDemoScene(DemoScene::kGripper, 3000);
  const std::size_t fruit = *scene->findObject("fruit");
  const std::size_t floor = *scene->findObject("floor");
  scene->setFriction(0.9);
  EXPECT_EQ(scene->config().friction, 0.9);
  EXPECT_THROW(scene->setFriction(-0.1), std::invalid_argument);
  EXPECT_THROW(scene->setFriction(std::nan("")), std::invalid_argument);
  EXPECT_EQ(scene->config().friction, 0.9);
  scene->setMaterial(fruit, 0.7, 0.2);
  EXPECT_EQ(scene->body(fruit).config().stiffness, 0.7);
  EXPECT_EQ(scene->body(fruit).config().damping, 0.2);
  EXPECT_EQ(scene->objectConfig(fruit).shape.stiffness, 0.7);
  EXPECT_THROW(scene->setMaterial(fruit, 1.5, 0.2), std::invalid_argument);
  EXPECT_EQ(scene->body(fruit).config().stiffness, 0.7) << "a refused change keeps the old";
  EXPECT_THROW(scene->setMaterial(floor, 0.5, 0.1), std::invalid_argument);
  EXPECT_THROW(scene->setMaterial(99, 0.5, 0.1), std::out_of_range);
  EXPECT_THROW(scene->setContactStiffness(fruit, 100.0), std::invalid_argument)
      << "the fruit is dynamic, not tracked";
  for (int cycle = 0; cycle < 20; ++cycle) scene->cycle();
  EXPECT_TRUE(allFinite(*scene));
}

// A larger contact distance finds the contacts of two objects that did not move since the
// last cycle, which would otherwise keep that cycle's (none).
TEST(Scene, AContactDistanceChangeQueriesEveryPairAgain) {
  auto scene = sceneOnFloor(-1);
  ObjectConfig block;
  block.name = "block";
  block.kind = ObjectKind::kKinematic;
  // Three layers, the lowest 4 cm above the floor's top.
  scene->addObject(block, gridLayers(5, 3, 0.02));
  scene->setPose(1, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.08)));
  scene->cycle();
  scene->cycle();
  EXPECT_TRUE(scene->contacts().empty());
  EXPECT_THROW(scene->setContactDistance(0.0), std::invalid_argument);
  EXPECT_THROW(scene->setContactDistance(std::nan("")), std::invalid_argument);
  scene->setContactDistance(0.05);
  scene->cycle();
  EXPECT_FALSE(scene->contacts().empty());
  EXPECT_EQ(scene->config().contact_distance_m, 0.05);
}

TEST(Scene, LevelSwitchesBetweenCyclesAndQueriesLeaveItAlone) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects, 9000);
  for (int cycle = 0; cycle < 40; ++cycle) scene->cycle();  // the objects are on the floor
  scene->setLevel(2);
  scene->cycle();
  EXPECT_EQ(scene->stats().level, 2);
  for (const auto& c : scene->contacts()) {
    EXPECT_LE(c.contact.level, 2);
    EXPECT_EQ(c.contact.point_a, SphereContact::kNoPoint);  // a point pair only at the leaves
  }
  const auto kept = scene->contacts();

  std::vector<SceneContact> finest;
  scene->contactsAt(scene->maxLevel(), std::nullopt, std::nullopt, finest);
  EXPECT_FALSE(finest.empty());
  EXPECT_EQ(scene->level(), 2);
  EXPECT_EQ(scene->contacts().size(), kept.size());

  const std::size_t ball = *scene->findObject("ball");
  std::vector<SceneContact> with_ball;
  scene->contactsAt(scene->maxLevel(), ball, std::nullopt, with_ball);
  for (const auto& c : with_ball) EXPECT_EQ(c.object_a, ball);

  scene->setLevel(scene->maxLevel());
  scene->cycle();
  EXPECT_EQ(scene->stats().level, scene->maxLevel());
  EXPECT_THROW(scene->setLevel(scene->maxLevel() + 1), std::out_of_range);
  EXPECT_THROW(scene->setLevel(-2), std::out_of_range);
  EXPECT_EQ(scene->level(), scene->maxLevel());
  EXPECT_THROW(scene->contactsAt(0, 99, std::nullopt, finest), std::out_of_range);
}

// A level at or past a deforming object's leaves gains nothing from stopping a static
// object's descent there: the floor meets the ball at its own leaves, as at the finest
// level, and only a level above the ball's leaves gives coarse contacts.
TEST(Scene, AFixedObjectMeetsAnObjectAtItsLeavesAtItsOwnLeaves) {
  ObjectConfig ball;
  ball.name = "ball";
  Points points = sampleEllipsoid(300, {0.05, 0.05, 0.05}, 4);
  for (auto& p : points) p.z() += 0.055;  // 5 mm above the floor, within the contact distance
  auto scene = sceneOnFloor(-1);
  const int ball_leaves = scene->tree(scene->addObject(ball, points)).maxLevel();
  ASSERT_GT(scene->maxLevel(), ball_leaves) << "the floor must be the deeper tree";

  std::vector<SceneContact> finest, at_level;
  scene->contactsAt(scene->maxLevel(), std::nullopt, std::nullopt, finest);
  ASSERT_FALSE(finest.empty());
  for (int level = ball_leaves; level < scene->maxLevel(); ++level) {
    scene->contactsAt(level, std::nullopt, std::nullopt, at_level);
    ASSERT_EQ(at_level.size(), finest.size()) << "level " << level;
    for (std::size_t k = 0; k < finest.size(); ++k) {
      const SphereContact& got = at_level[k].contact;
      const SphereContact& want = finest[k].contact;
      EXPECT_EQ(std::tie(got.node_a, got.node_b, got.point_a, got.point_b, got.level),
                std::tie(want.node_a, want.node_b, want.point_a, want.point_b, want.level))
          << "level " << level << ", contact " << k;
      EXPECT_EQ(got.position, want.position) << "level " << level << ", contact " << k;
      EXPECT_EQ(got.depth_m, want.depth_m) << "level " << level << ", contact " << k;
    }
  }

  const int coarse = ball_leaves - 1;
  scene->contactsAt(coarse, std::nullopt, std::nullopt, at_level);
  ASSERT_FALSE(at_level.empty());
  for (const auto& c : at_level) {
    EXPECT_LE(c.contact.level, coarse);
    EXPECT_EQ(c.contact.point_a, SphereContact::kNoPoint) << "a point pair only at the leaves";
  }
}

TEST(Scene, LevelMinusOneStaysTheFinestWhenDeeperObjectsCome) {
  const auto add = [](Scene& scene, const std::string& name, std::size_t points) {
    ObjectConfig object;
    object.name = name;
    object.kind = ObjectKind::kStatic;
    scene.addObject(object, sampleEllipsoid(points, Eigen::Vector3d(0.1, 0.1, 0.1), 1));
  };
  Scene finest{SceneConfig{}}, fixed{SceneConfig{}};
  for (Scene* scene : {&finest, &fixed}) add(*scene, "small", 16);
  const int shallow = finest.maxLevel();
  finest.setLevel(0);
  finest.setLevel(-1);
  fixed.setLevel(shallow);
  for (Scene* scene : {&finest, &fixed}) add(*scene, "large", 4000);
  ASSERT_GT(finest.maxLevel(), shallow);
  EXPECT_EQ(finest.config().level, -1);
  EXPECT_EQ(finest.level(), finest.maxLevel());
  EXPECT_EQ(fixed.level(), shallow) << "a level set by number stays";
}

TEST(Scene, ASetTimeStepStepsLikeAConfiguredOne) {
  ObjectConfig box;
  box.name = "box";
  const Points points = sampleBox(200, Eigen::Vector3d(0.05, 0.05, 0.05), 3);
  SceneConfig long_steps;
  long_steps.dt_s = 0.02;
  Scene configured(long_steps), changed{SceneConfig{}};
  for (Scene* scene : {&configured, &changed}) scene->addObject(box, points);
  changed.setTimeStep(0.02);
  EXPECT_EQ(changed.config().dt_s, 0.02);
  configured.cycle();
  changed.cycle();
  EXPECT_EQ(configured.body(0).positions(), changed.body(0).positions());
  for (double bad : {0.0, -0.01, 0.2, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_THROW(changed.setTimeStep(bad), std::invalid_argument) << bad;
  }
  EXPECT_EQ(changed.config().dt_s, 0.02) << "a refused step changes nothing";
}

// ---------------------------------------------------------------------------------------
// Bad input: an exception that names the bad value.

struct BadSceneCase {
  const char* name;
  std::function<void(SceneConfig&)> spoil;
  const char* message_part;
};

void PrintTo(const BadSceneCase& c, std::ostream* os) { *os << c.name; }

class BadSceneConfigTest : public ::testing::TestWithParam<BadSceneCase> {};

TEST_P(BadSceneConfigTest, ThrowsNamingTheValue) {
  SceneConfig config;
  GetParam().spoil(config);
  try {
    Scene scene(config);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(GetParam().message_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadSceneConfigTest,
    ::testing::Values(
        BadSceneCase{"zero_dt", [](auto& c) { c.dt_s = 0.0; }, "dt_s = 0"},
        BadSceneCase{"dt_too_long", [](auto& c) { c.dt_s = 0.5; }, "dt_s = 0.5"},
        BadSceneCase{"negative_contact_distance", [](auto& c) { c.contact_distance_m = -1.0; },
                     "contact_distance_m = -1"},
        BadSceneCase{"negative_friction", [](auto& c) { c.friction = -0.3; }, "friction = -0.3"},
        BadSceneCase{"level_below_minus_one", [](auto& c) { c.level = -2; }, "level = -2"},
        BadSceneCase{"branching_one", [](auto& c) { c.tree.branching = 1; }, "branching 1"},
        BadSceneCase{"nan_gravity", [](auto& c) { c.gravity_mps2.z() = std::nan(""); },
                     "gravity_mps2"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Scene, ObjectsAreCheckedByNameAndKind) {
  Scene scene(SceneConfig{});
  ObjectConfig dynamic;
  dynamic.name = "ball";
  scene.addObject(dynamic, sampleBox(50, {0.1, 0.1, 0.1}, 1));
  EXPECT_THROW(scene.addObject(dynamic, sampleBox(50, {0.1, 0.1, 0.1}, 2)), std::invalid_argument);
  ObjectConfig unnamed;
  EXPECT_THROW(scene.addObject(unnamed, sampleBox(50, {0.1, 0.1, 0.1}, 3)), std::invalid_argument);
  ObjectConfig bad;
  bad.name = "bad";
  bad.shape.stiffness = 3.0;
  try {
    scene.addObject(bad, sampleBox(50, {0.1, 0.1, 0.1}, 4));
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("object 'bad'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(scene.setPose(0, Eigen::Isometry3d::Identity()), std::invalid_argument);
  EXPECT_THROW(scene.observe(0, scene.body(0).positions()), std::invalid_argument);
  Points not_tracked = scene.body(0).positions();
  EXPECT_THROW(scene.observeSwapping(0, not_tracked), std::invalid_argument);
  EXPECT_EQ(not_tracked, scene.body(0).positions());
  EXPECT_FALSE(scene.findObject("nothing").has_value());
  EXPECT_EQ(parseObjectKind("kinematic"), ObjectKind::kKinematic);
  EXPECT_FALSE(parseObjectKind("floating").has_value());
}

TEST(Scene, KinematicAndTrackedObjectsFollowTheirInputs) {
  Scene scene(SceneConfig{});
  ObjectConfig jaw;
  jaw.name = "jaw";
  jaw.kind = ObjectKind::kKinematic;
  const Points rest = sampleBox(100, {0.02, 0.05, 0.05}, 5);
  const std::size_t j = scene.addObject(jaw, rest);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(Eigen::Vector3d(1.0, 2.0, 3.0));
  pose.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  scene.setPose(j, pose);
  scene.cycle();
  for (std::size_t i = 0; i < rest.size(); ++i) {
    EXPECT_LT((scene.body(j).positions()[i] - pose * rest[i]).norm(), 1e-12);
  }
  ObjectConfig tracked;
  tracked.name = "tracked";
  tracked.kind = ObjectKind::kTracked;
  const std::size_t t = scene.addObject(tracked, rest);
  Points observed = rest;
  for (auto& p : observed) p += Eigen::Vector3d(0.0, 0.0, 0.5);
  observed[3].x() = std::nan("");
  EXPECT_EQ(scene.observe(t, observed), 1u);
  EXPECT_LT((scene.body(t).positions()[3] - (rest[3] + Eigen::Vector3d(0, 0, 0.5))).norm(), 1e-9);

  // Swapped in, a whole cloud becomes the positions and its buffer the previous ones.
  const Points previous = scene.body(t).positions();
  Points whole = rest;
  for (auto& p : whole) p += Eigen::Vector3d(0.0, 0.1, 0.5);
  const Points expected = whole;
  EXPECT_EQ(scene.observeSwapping(t, whole), 0u);
  EXPECT_EQ(scene.body(t).positions(), expected);
  EXPECT_EQ(whole, previous);
}

TEST(Scene, ResetRestShapeReplacesTheShapeOrNothing) {
  Scene scene(SceneConfig{});
  ObjectConfig ball;
  ball.name = "ball";
  ball.shape.clusters = 2;
  const std::size_t b = scene.addObject(ball, sampleBox(100, {0.1, 0.1, 0.1}, 6));
  scene.cycle();
  const Points before = scene.body(b).positions();
  EXPECT_THROW(scene.resetRestShape(b, Points(1, Eigen::Vector3d::Zero())), std::invalid_argument);
  EXPECT_THROW(scene.resetRestShape(b, Points{}), std::invalid_argument);
  EXPECT_EQ(scene.body(b).positions(), before);
  EXPECT_THROW(scene.resetRestShape(7, before), std::out_of_range);

  const Points bigger = sampleBox(300, {0.2, 0.2, 0.2}, 7);
  scene.resetRestShape(b, bigger);
  EXPECT_EQ(scene.body(b).positions(), bigger);
  EXPECT_GE(scene.tree(b).pointIndices().size(), bigger.size());  // seam points twice
  for (std::uint32_t n = 0; n < scene.tree(b).nodeCount(); ++n) {
    const Sphere& sphere = scene.currentSphere(b, n);
    const SphereNode& node = scene.tree(b).node(n);
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      EXPECT_LE((bigger[scene.tree(b).pointIndices()[s]] - sphere.center).norm(),
                sphere.radius * (1 + 1e-12));
    }
  }
  EXPECT_THROW(scene.currentSphere(b, static_cast<std::uint32_t>(scene.tree(b).nodeCount())),
               std::out_of_range);
}

// An object prepared apart (as the node's reader thread does) and added later is the object
// addObject makes: the same dropped box on the floor, added either way, falls and lands
// through the same states, to the bit.
TEST(Scene, APreparedObjectIsTheObjectAddObjectMakes) {
  auto direct = sceneOnFloor(-1);
  auto prepared = sceneOnFloor(-1);
  addDroppedBox(*direct);
  Scene::PreparedObject made = prepared->prepareObject(droppedBoxConfig(), droppedBoxPoints());
  EXPECT_EQ(prepared->objectCount(), 1u);  // preparing adds nothing
  EXPECT_EQ(prepared->addObject(std::move(made)), 1u);
  EXPECT_TRUE(made.empty());
  ASSERT_EQ(prepared->tree(1).nodeCount(), direct->tree(1).nodeCount());
  for (int step = 0; step < 60; ++step) {
    direct->cycle();
    prepared->cycle();
  }
  EXPECT_EQ(prepared->body(1).positions(), direct->body(1).positions());
  EXPECT_EQ(prepared->contacts().size(), direct->contacts().size());
  EXPECT_FALSE(direct->contacts().empty());
}

TEST(Scene, PreparedObjectsAreCheckedWhenAdded) {
  Scene scene(SceneConfig{});
  ObjectConfig ball;
  ball.name = "ball";
  ObjectConfig unnamed;
  EXPECT_THROW(scene.prepareObject(unnamed, sampleBox(50, {0.1, 0.1, 0.1}, 1)),
               std::invalid_argument);
  Scene::PreparedObject first = scene.prepareObject(ball, sampleBox(50, {0.1, 0.1, 0.1}, 1));
  Scene::PreparedObject second = scene.prepareObject(ball, sampleBox(80, {0.1, 0.1, 0.1}, 2));
  const std::size_t b = scene.addObject(std::move(first));
  EXPECT_THROW(scene.addObject(std::move(second)), std::invalid_argument);  // the name is used
  EXPECT_FALSE(second.empty());
  EXPECT_THROW(scene.addObject(std::move(first)), std::invalid_argument);  // empty now
  EXPECT_EQ(scene.objectCount(), 1u);

  // A new rest shape prepared for the object replaces its shape; one for another does not.
  scene.resetRestShape(b, std::move(second));
  EXPECT_EQ(scene.body(b).positions().size(), 80u);
  ObjectConfig other;
  other.name = "other";
  const Points before = scene.body(b).positions();
  EXPECT_THROW(
      scene.resetRestShape(b, scene.prepareObject(other, sampleBox(60, {0.1, 0.1, 0.1}, 3))),
      std::invalid_argument);
  EXPECT_THROW(scene.resetRestShape(b, Scene::PreparedObject()), std::invalid_argument);
  EXPECT_EQ(scene.body(b).positions(), before);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
