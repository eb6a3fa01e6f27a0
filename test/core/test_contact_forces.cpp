// Contact forces (ContactForces, through the Scene) as physics, not wiring: a body resting on
// a floor presses it with its weight at every level and in every deformation mode, a floor
// carries the whole stack on it, two jaws squeezing a body push it equally and oppositely and
// harder the deeper they squeeze, a tracked body's force follows its indentation, and a
// tracked copy of a simulated body reads the simulation's force.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numeric>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "deformable_collision/core/response/contact_totals.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

/// The force on `object` through the contacts, summed (each contact's force is on its a).
Eigen::Vector3d forceOn(const std::vector<SceneContact>& contacts, std::size_t object) {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  for (const SceneContact& c : contacts) {
    if (c.object_a == object) force += c.force_n;
    if (c.object_b == object) force -= c.force_n;
  }
  return force;
}

bool allForcesFinite(const std::vector<SceneContact>& contacts) {
  for (const SceneContact& c : contacts) {
    if (!c.force_n.allFinite() || !std::isfinite(c.force_error_n) || c.force_error_n < 0.0) {
      return false;
    }
  }
  return true;
}

/// A 2 kg soft ball, 5 cm radius, 1500 points.
ObjectConfig ballConfig(DeformationMode mode, ObjectKind kind = ObjectKind::kDynamic) {
  ObjectConfig ball;
  ball.name = "ball";
  ball.kind = kind;
  ball.shape.mode = mode;
  ball.shape.clusters = mode == DeformationMode::kRigid ? 1 : 4;
  ball.shape.stiffness = 0.5;
  ball.shape.mass_kg = 2.0;
  return ball;
}

Points ballPoints(const Eigen::Vector3d& center) {
  Points points = sampleEllipsoid(1500, Eigen::Vector3d::Constant(0.05), 11);
  for (auto& p : points) p += center;
  return points;
}

// ---------------------------------------------------------------------------------------
// At rest on a floor, the floor carries the ball's weight: over the last 50 of 250 cycles
// the mean force on the ball is m g up, within 5%, at every level and in every mode.

class RestingForceTest : public ::testing::TestWithParam<std::tuple<DeformationMode, int>> {};

TEST_P(RestingForceTest, FloorCarriesTheWeight) {
  const auto [mode, level] = GetParam();
  auto scene = sceneOnFloor(level);
  const std::size_t ball = scene->addObject(ballConfig(mode), ballPoints({0.0, 0.0, 0.06}));
  if (level > scene->maxLevel()) GTEST_SKIP() << "the scene has " << scene->maxLevel() << " levels";
  scene->setLevel(level);
  constexpr int kCycles = 250, kLate = 50;
  Eigen::Vector3d late_sum = Eigen::Vector3d::Zero();
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    scene->cycle();
    ASSERT_TRUE(allForcesFinite(scene->contacts())) << "cycle " << cycle;
    if (cycle >= kCycles - kLate) late_sum += forceOn(scene->contacts(), ball);
  }
  const double weight = 2.0 * 9.81;
  const Eigen::Vector3d mean = late_sum / kLate;
  EXPECT_NEAR(mean.z(), weight, 0.05 * weight);
  EXPECT_LT(mean.head<2>().norm(), 0.05 * weight);
  // Third law: the floor gets the opposite.
  const Eigen::Vector3d on_floor = forceOn(scene->contacts(), 0);
  EXPECT_TRUE((on_floor + forceOn(scene->contacts(), ball)).isZero(1e-9));
}

std::vector<int> restingLevels() {
  auto scene = sceneOnFloor(-1);
  scene->addObject(ballConfig(DeformationMode::kLinear), ballPoints({0.0, 0.0, 0.06}));
  std::vector<int> levels(scene->maxLevel() + 1);
  std::iota(levels.begin(), levels.end(), 0);
  return levels;
}

TEST(RestingForceTest, NoneWhenSwitchedOff) {
  SceneConfig config;
  config.contact_forces = false;
  auto scene = sceneOnFloor(-1, config);
  scene->addObject(ballConfig(DeformationMode::kLinear), ballPoints({0.0, 0.0, 0.06}));
  for (int cycle = 0; cycle < 50; ++cycle) scene->cycle();
  ASSERT_FALSE(scene->contacts().empty());
  for (const SceneContact& c : scene->contacts()) EXPECT_TRUE(c.force_n.isZero());
}

INSTANTIATE_TEST_SUITE_P(ModesAndLevels, RestingForceTest,
                         ::testing::Combine(::testing::Values(DeformationMode::kRigid,
                                                              DeformationMode::kLinear,
                                                              DeformationMode::kQuadratic),
                                            ::testing::ValuesIn(restingLevels())),
                         [](const auto& info) {
                           return std::string(toString(std::get<0>(info.param))) + "_level_" +
                                  std::to_string(std::get<1>(info.param));
                         });

// ---------------------------------------------------------------------------------------
// A stack of rigid 1 kg boxes on the floor: each box's contacts hold up its own weight, and
// the floor carries the whole stack, though shock propagation lets each box act as fixed for
// the one above it.

class StackForceTest : public ::testing::TestWithParam<std::tuple<int, int>> {};

TEST_P(StackForceTest, FloorCarriesTheStack) {
  const auto [boxes, level] = GetParam();
  auto scene = sceneOnFloor(level);
  ObjectConfig box = droppedBoxConfig();
  for (int n = 0; n < boxes; ++n) {
    box.name = "box" + std::to_string(n);
    Points points = sampleBox(2000, {0.05, 0.05, 0.05}, 3 + n);
    for (auto& p : points) p.z() += 0.06 + 0.11 * n;
    scene->addObject(box, points);
  }
  if (level >= 0) scene->setLevel(std::min(level, scene->maxLevel()));
  constexpr int kCycles = 300, kLate = 50;
  std::vector<Eigen::Vector3d> late(boxes + 1, Eigen::Vector3d::Zero());
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    scene->cycle();
    if (cycle < kCycles - kLate) continue;
    for (int o = 0; o <= boxes; ++o) late[o] += forceOn(scene->contacts(), o) / kLate;
  }
  const double weight = 9.81;
  EXPECT_NEAR(-late[0].z(), boxes * weight, 0.05 * boxes * weight) << "the floor";
  for (int o = 1; o <= boxes; ++o) EXPECT_NEAR(late[o].z(), weight, 0.05 * weight) << "box " << o;
}

INSTANTIATE_TEST_SUITE_P(BoxesAndLevels, StackForceTest,
                         ::testing::Combine(::testing::Values(2, 3), ::testing::Values(0, 2, -1)),
                         [](const auto& info) {
                           const int level = std::get<1>(info.param);
                           return std::to_string(std::get<0>(info.param)) + "_boxes_" +
                                  (level < 0 ? std::string("finest")
                                             : "level_" + std::to_string(level));
                         });

// ---------------------------------------------------------------------------------------
// Two kinematic jaws squeeze a ball without gravity. Once the ball is still, the jaws'
// forces are equal and opposite within 5% (what the ball gets is their sum), and a deeper
// squeeze presses harder.

/// A jaw: a 1 cm thick plate, 12 cm square, its inner face at x = 0 before posing.
Points jawPoints(double side) {
  Points points = sampleBox(1200, {0.005, 0.06, 0.06}, side > 0 ? 5 : 6);
  for (auto& p : points) p.x() += side * 0.005;
  return points;
}

struct Squeeze {
  Eigen::Vector3d left = Eigen::Vector3d::Zero();
  Eigen::Vector3d right = Eigen::Vector3d::Zero();
};

/// The jaws' mean forces over the last 50 of 300 cycles, their faces `squeeze_m` inside the
/// ball's surface each.
/// A ball between two kinematic jaws, without gravity.
struct BallInJaws {
  std::unique_ptr<Scene> scene;
  std::size_t ball = 0, left = 0, right = 0;
};

BallInJaws ballInJaws(DeformationMode mode, int level) {
  SceneConfig config;
  config.gravity_mps2.setZero();
  config.contact_distance_m = 0.005;
  config.level = level;
  BallInJaws made{std::make_unique<Scene>(config)};
  made.ball = made.scene->addObject(ballConfig(mode), ballPoints(Eigen::Vector3d::Zero()));
  ObjectConfig jaw;
  jaw.kind = ObjectKind::kKinematic;
  jaw.name = "left";
  made.left = made.scene->addObject(jaw, jawPoints(-1.0));
  jaw.name = "right";
  made.right = made.scene->addObject(jaw, jawPoints(1.0));
  return made;
}

Squeeze squeezeBall(DeformationMode mode, int level, double squeeze_m) {
  BallInJaws made = ballInJaws(mode, level);
  Scene& scene = *made.scene;
  const std::size_t ball = made.ball, left = made.left, right = made.right;
  Squeeze mean;
  constexpr int kCycles = 300, kLate = 50;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    // The jaws close over the first 100 cycles.
    const double closed = std::min(1.0, cycle / 100.0);
    const double face = 0.05 + 0.02 - closed * (0.02 + squeeze_m);
    scene.setPose(left, Eigen::Isometry3d(Eigen::Translation3d(-face, 0.0, 0.0)));
    scene.setPose(right, Eigen::Isometry3d(Eigen::Translation3d(face, 0.0, 0.0)));
    scene.cycle();
    EXPECT_TRUE(allForcesFinite(scene.contacts()));
    if (cycle < kCycles - kLate) continue;
    mean.left += forceOn(scene.contacts(), left) / kLate;
    mean.right += forceOn(scene.contacts(), right) / kLate;
  }
  EXPECT_LT(scene.body(ball).meanVelocity().norm(), 1e-3) << "the ball is not still";
  return mean;
}

class SqueezeForceTest : public ::testing::TestWithParam<std::tuple<DeformationMode, int>> {};

TEST_P(SqueezeForceTest, JawsPushEquallyAndHarderDeeper) {
  const auto [mode, level] = GetParam();
  const Squeeze shallow = squeezeBall(mode, level, 0.004);
  const Squeeze deep = squeezeBall(mode, level, 0.010);
  for (const Squeeze& s : {shallow, deep}) {
    // Each jaw is pushed outwards.
    EXPECT_LT(s.left.x(), 0.0);
    EXPECT_GT(s.right.x(), 0.0);
    EXPECT_LT((s.left + s.right).norm(), 0.05 * s.right.norm());
  }
  EXPECT_GT(deep.right.x(), 1.3 * shallow.right.x());
  EXPECT_GT(-deep.left.x(), 1.3 * -shallow.left.x());
}

INSTANTIATE_TEST_SUITE_P(ModesAndLevels, SqueezeForceTest,
                         ::testing::Combine(::testing::Values(DeformationMode::kLinear,
                                                              DeformationMode::kQuadratic),
                                            ::testing::Values(0, 2, -1)),
                         [](const auto& info) {
                           const int level = std::get<1>(info.param);
                           return std::string(toString(std::get<0>(info.param))) +
                                  (level < 0 ? std::string("_finest")
                                             : "_level_" + std::to_string(level));
                         });

// ---------------------------------------------------------------------------------------
// A tracked cube pressed by a kinematic probe: its contact force is its stiffness times the
// indentation, grows in proportion to it and points away from the probe.

/// A 10 cm cube on a 5 mm grid, centred at the origin: its +x face lies at x = 0.05.
Points cubePoints() {
  Points points;
  for (int i = -10; i <= 10; ++i) {
    for (int j = -10; j <= 10; ++j) {
      for (int k = -10; k <= 10; ++k) points.emplace_back(0.005 * i, 0.005 * j, 0.005 * k);
    }
  }
  return points;
}

/// The cube as a 4 cm square probe pressing its +x face `depth_m` (< 5 mm) in leaves it.
Points indented(double depth_m) {
  Points points = cubePoints();
  for (auto& p : points) {
    if (std::abs(p.y()) <= 0.02 && std::abs(p.z()) <= 0.02) p.x() = std::min(p.x(), 0.05 - depth_m);
  }
  return points;
}

struct Pressed {
  std::unique_ptr<Scene> scene;
  std::size_t cube = 0;
  std::size_t probe = 0;
};

/// A tracked cube (linear, 4 clusters) seen indented by a kinematic probe, half the contact
/// distance off its face; one cycle.
Pressed pressTrackedCube(double depth_m, double stiffness_n_per_m) {
  SceneConfig config;
  config.contact_distance_m = 0.004;
  Pressed pressed{std::make_unique<Scene>(config)};
  ObjectConfig cube = ballConfig(DeformationMode::kLinear, ObjectKind::kTracked);
  cube.name = "cube";
  cube.contact_stiffness_n_per_m = stiffness_n_per_m;
  pressed.cube = pressed.scene->addObject(cube, cubePoints());
  ObjectConfig probe;
  probe.name = "probe";
  probe.kind = ObjectKind::kKinematic;
  Points plate = sampleBox(800, {0.005, 0.02, 0.02}, 9);
  for (auto& p : plate) p.x() += 0.05 - depth_m + 0.005 + 0.5 * config.contact_distance_m;
  pressed.probe = pressed.scene->addObject(probe, plate);
  pressed.scene->observe(pressed.cube, indented(depth_m));
  pressed.scene->cycle();
  return pressed;
}

TEST(TrackedForceTest, FollowsTheIndentation) {
  constexpr double kStiffness = 800.0;
  for (const double depth : {0.002, 0.004}) {
    SCOPED_TRACE("depth " + std::to_string(depth));
    Pressed pressed = pressTrackedCube(depth, kStiffness);
    const Eigen::Vector3d force = forceOn(pressed.scene->contacts(), pressed.cube);
    // Pushed away from the probe, by k times the depth (the clusters' fitted poses follow
    // the dent by a hair).
    EXPECT_NEAR(-force.x(), kStiffness * depth, 0.05 * kStiffness * depth);
    // Along the pair's mean normal, which the point pairs of a random plate tilt by degrees.
    EXPECT_LT(force.tail<2>().norm(), 0.15 * force.norm());
  }
  // No stiffness, no force.
  Pressed uncalibrated = pressTrackedCube(0.004, 0.0);
  EXPECT_TRUE(forceOn(uncalibrated.scene->contacts(), uncalibrated.cube).isZero());
}

// ---------------------------------------------------------------------------------------
// Bounds: on one state, every level's contacts cover the finest level's (each finest contact
// lies under exactly one contact of the level: its nodes hold the finest one's points), and
// each contact's force is within its force_error_n of the sum of the finest forces under it,
// for a ball resting on the floor, a ball squeezed between jaws and the pressed tracked cube.

/// Whether node `inner`'s points are among node `outer`'s.
bool holds(const SphereTree& tree, std::uint32_t outer, std::uint32_t inner) {
  const SphereNode& o = tree.node(outer);
  const SphereNode& i = tree.node(inner);
  return i.first_point >= o.first_point &&
         i.first_point + i.point_count <= o.first_point + o.point_count;
}

void expectBoundsHoldAgainstTheFinest(Scene& scene) {
  std::vector<SceneContact> finest;
  scene.contactsAt(scene.maxLevel(), std::nullopt, std::nullopt, finest);
  ASSERT_FALSE(finest.empty());
  for (int level = 0; level < scene.maxLevel(); ++level) {
    SCOPED_TRACE("level " + std::to_string(level));
    std::vector<SceneContact> coarse;
    scene.contactsAt(level, std::nullopt, std::nullopt, coarse);
    std::vector<Eigen::Vector3d> under(coarse.size(), Eigen::Vector3d::Zero());
    for (const SceneContact& f : finest) {
      int covering = 0;
      for (std::size_t k = 0; k < coarse.size(); ++k) {
        const SceneContact& c = coarse[k];
        if (c.object_a != f.object_a || c.object_b != f.object_b ||
            !holds(scene.tree(c.object_a), c.contact.node_a, f.contact.node_a) ||
            !holds(scene.tree(c.object_b), c.contact.node_b, f.contact.node_b)) {
          continue;
        }
        under[k] += f.force_n;
        ++covering;
      }
      ASSERT_EQ(covering, 1) << "a finest contact under " << covering << " contacts";
    }
    for (std::size_t k = 0; k < coarse.size(); ++k) {
      EXPECT_LE((coarse[k].force_n - under[k]).norm(), coarse[k].force_error_n + 1e-9)
          << "contact " << k;
    }
    // A pair's total is the finest level's (none where the finest level finds the pair apart,
    // as coarse spheres may not), up to its indentation's error.
    std::vector<PairSummary> coarse_pairs, finest_pairs;
    summarizePairs(coarse, coarse_pairs);
    summarizePairs(finest, finest_pairs);
    for (const PairSummary& pair : coarse_pairs) {
      Eigen::Vector3d total = Eigen::Vector3d::Zero();
      for (const PairSummary& f : finest_pairs) {
        if (f.object_a == pair.object_a && f.object_b == pair.object_b) total = f.force_n;
      }
      EXPECT_LE((pair.force_n - total).norm(), pair.force_error_n + 1e-9 * (1.0 + total.norm()))
          << "pair " << pair.object_a << ", " << pair.object_b;
    }
  }
}

// A query apart from the cycle, in either order of a pair's objects and after a detection
// ahead of the next cycle, shares the last cycle's force of the pair.
TEST(QueriedForceTest, TheLastCycleForceInEitherOrder) {
  auto scene = sceneOnFloor(-1);
  const std::size_t ball =
      scene->addObject(ballConfig(DeformationMode::kLinear), ballPoints({0.0, 0.0, 0.06}));
  for (int cycle = 0; cycle < 200; ++cycle) scene->cycle();
  const Eigen::Vector3d cycle_force = forceOn(scene->contacts(), ball);
  ASSERT_GT(cycle_force.z(), 0.5 * 2.0 * 9.81);
  std::vector<SceneContact> queried;
  for (const auto& [a, b] :
       {std::pair<std::optional<std::size_t>, std::optional<std::size_t>>{ball, std::nullopt},
        {std::nullopt, ball},
        {ball, 0},
        {0, ball}}) {
    scene->contactsAt(scene->maxLevel(), a, b, queried);
    EXPECT_TRUE(forceOn(queried, ball).isApprox(cycle_force, 1e-9));
    scene->contactsAt(0, a, b, queried);
    EXPECT_TRUE(forceOn(queried, ball).isApprox(cycle_force, 1e-9));
  }
  scene->detectAhead();
  scene->contactsAt(scene->maxLevel(), ball, std::nullopt, queried);
  EXPECT_TRUE(forceOn(queried, ball).isApprox(cycle_force, 1e-9)) << "after a detection ahead";
}

TEST(ForceBoundTest, RestingBall) {
  auto scene = sceneOnFloor(-1);
  scene->addObject(ballConfig(DeformationMode::kLinear), ballPoints({0.0, 0.0, 0.06}));
  for (int cycle = 0; cycle < 200; ++cycle) scene->cycle();
  expectBoundsHoldAgainstTheFinest(*scene);
}

TEST(ForceBoundTest, SqueezedBall) {
  BallInJaws made = ballInJaws(DeformationMode::kLinear, -1);
  Scene& scene = *made.scene;
  const std::size_t left = made.left, right = made.right;
  scene.setPose(left, Eigen::Isometry3d(Eigen::Translation3d(-0.045, 0.0, 0.0)));
  scene.setPose(right, Eigen::Isometry3d(Eigen::Translation3d(0.045, 0.0, 0.0)));
  for (int cycle = 0; cycle < 200; ++cycle) scene.cycle();
  expectBoundsHoldAgainstTheFinest(scene);
}

TEST(ForceBoundTest, PressedTrackedCube) {
  Pressed pressed = pressTrackedCube(0.003, 500.0);
  expectBoundsHoldAgainstTheFinest(*pressed.scene);
}

// ---------------------------------------------------------------------------------------
// Self-consistency: a soft cube simulated against a wall and pressed by a probe, then seen
// by a camera as a tracked copy of itself between the same wall and probe, with the stiffness
// the probe calibrated at 3 mm: at 2, 6 and 8 mm the copy's force on the probe agrees with
// the simulation's within 20%.

struct SqueezedCube {
  double force_n = 0.0;  ///< On the probe, along x.
  Points points;         ///< The cube at rest between the wall and the probe.
};

/// A kinematic object's face at x = `side` (0.05 - squeeze_m), posed: `squeeze_m` inside the
/// cube's face, less half the contact distance the response keeps.
Eigen::Isometry3d jawPose(double side, double squeeze_m) {
  return Eigen::Isometry3d(Eigen::Translation3d(side * (0.05 - squeeze_m), 0.0, 0.0));
}

/// A wall (a full jaw) behind the cube's -x face and a 4 cm square probe on its +x face,
/// both kinematic.
std::array<std::size_t, 2> addJaws(Scene& scene) {
  ObjectConfig jaw;
  jaw.kind = ObjectKind::kKinematic;
  jaw.name = "wall";
  const std::size_t wall = scene.addObject(jaw, jawPoints(-1.0));
  jaw.name = "probe";
  Points probe = sampleBox(600, {0.005, 0.02, 0.02}, 8);
  for (auto& p : probe) p.x() += 0.005;
  return {wall, scene.addObject(jaw, probe)};
}

SceneConfig squeezeConfig() {
  SceneConfig config;
  config.gravity_mps2.setZero();
  config.contact_distance_m = 0.004;
  return config;
}

/// The dynamic cube (linear, 8 clusters) pressed `squeeze_m` by the probe and the wall, once
/// at rest: the probe's mean force over the last 100 of 600 cycles.
SqueezedCube simulateSqueezedCube(double squeeze_m) {
  Scene scene(squeezeConfig());
  ObjectConfig cube = ballConfig(DeformationMode::kLinear);
  cube.shape.clusters = 8;
  cube.shape.damping = 0.3;
  const std::size_t index = scene.addObject(cube, cubePoints());
  const auto [wall, probe] = addJaws(scene);
  SqueezedCube squeezed;
  constexpr int kCycles = 600, kLate = 100;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    const double closing = squeeze_m * std::min(1.0, cycle / 150.0) - 0.002;
    scene.setPose(wall, jawPose(-1.0, closing));
    scene.setPose(probe, jawPose(1.0, closing));
    scene.cycle();
    if (cycle >= kCycles - kLate) squeezed.force_n += forceOn(scene.contacts(), probe).x() / kLate;
  }
  squeezed.points = scene.body(index).positions();
  return squeezed;
}

/// The force on the probe of a tracked copy of the cube seen as `points`.
double trackedForce(const Points& points, double squeeze_m, double stiffness_n_per_m) {
  Scene scene(squeezeConfig());
  ObjectConfig cube = ballConfig(DeformationMode::kLinear, ObjectKind::kTracked);
  cube.shape.clusters = 8;
  cube.contact_stiffness_n_per_m = stiffness_n_per_m;
  const std::size_t index = scene.addObject(cube, cubePoints());
  const auto [wall, probe] = addJaws(scene);
  scene.setPose(wall, jawPose(-1.0, squeeze_m - 0.002));
  scene.setPose(probe, jawPose(1.0, squeeze_m - 0.002));
  scene.observe(index, points);
  scene.cycle();
  return forceOn(scene.contacts(), probe).x();
}

TEST(SelfConsistencyTest, TrackedCopyReadsTheSimulatedForce) {
  // A probe's calibration: the simulated force at 3 mm over the copy's force at unit
  // stiffness there.
  const SqueezedCube calibration = simulateSqueezedCube(0.003);
  ASSERT_GT(calibration.force_n, 0.0);
  const double stiffness = calibration.force_n / trackedForce(calibration.points, 0.003, 1.0);
  ASSERT_TRUE(std::isfinite(stiffness) && stiffness > 0.0);
  for (const double squeeze : {0.002, 0.006, 0.008}) {
    SCOPED_TRACE("squeeze " + std::to_string(squeeze));
    const SqueezedCube simulated = simulateSqueezedCube(squeeze);
    const double tracked = trackedForce(simulated.points, squeeze, stiffness);
    EXPECT_NEAR(tracked, simulated.force_n, 0.2 * simulated.force_n);
  }
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
