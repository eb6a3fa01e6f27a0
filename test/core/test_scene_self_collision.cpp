// Self-collision in a scene: a soft U whose arms are thrown at each other stays apart with
// self_collision on and passes through itself with it off; tracked objects report their
// folds; undeformed objects of every built-in scene have no self-contacts at any level.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

constexpr double kContact = 0.005;

/// A 30 x 1.5 x 1.5 cm bar bent into a U whose arms' inner faces are 2.5 cm apart: more
/// than the rest distance of self-contacts (four contact distances).
Points restU() { return bentIntoU(gridBox(61, 4, 4, 0.005), 0.5 * (0.025 + 0.015)); }

bool inUpperArm(const Eigen::Vector3d& rest) { return rest.x() < -0.01 && rest.y() > 0.0; }
bool inLowerArm(const Eigen::Vector3d& rest) { return rest.x() < -0.01 && rest.y() < 0.0; }

/// The least height of an upper arm's point over a lower arm's point below or above it
/// (within half a point spacing across): negative once one arm is inside the other.
double armsGap(const Scene& scene, std::size_t index) {
  const auto& rest = scene.body(index).restPositions();
  const auto& x = scene.body(index).positions();
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!inUpperArm(rest[i])) continue;
    for (std::size_t j = 0; j < x.size(); ++j) {
      const Eigen::Vector2d across(x[i].x() - x[j].x(), x[i].z() - x[j].z());
      if (inLowerArm(rest[j]) && across.norm() < 0.0025) gap = std::min(gap, x[i].y() - x[j].y());
    }
  }
  return gap;
}
/// The U's arms thrown at each other, each 2 mm a step: discrete detection meets them
/// before they pass (a point that crossed a whole face in one step would not be seen).
struct ThrownU {
  ThrownU(bool self_collision, double dt_s) : scene(config(dt_s)) {
    ObjectConfig u;
    u.name = "u";
    u.kind = ObjectKind::kDynamic;
    u.shape.mode = DeformationMode::kLinear;
    u.shape.clusters = 6;
    u.shape.stiffness = 0.001;  // soft: the arms meet before the material holds them
    u.self_collision = self_collision;
    index = scene.addObject(u, restU());
    std::vector<Eigen::Vector3d> velocities;
    for (const auto& p : scene.body(index).restPositions()) {
      const double speed_mps = 0.002 / dt_s;
      const double closing = inUpperArm(p) ? -speed_mps : inLowerArm(p) ? speed_mps : 0.0;
      velocities.emplace_back(0.0, closing, 0.0);
    }
    scene.setVelocities(index, velocities);
  }
  static SceneConfig config(double dt_s) {
    SceneConfig c;
    c.gravity_mps2.setZero();
    c.contact_distance_m = kContact;
    c.dt_s = dt_s;
    return c;
  }
  double armsGap() const { return deformable_collision::armsGap(scene, index); }
  Scene scene;
  std::size_t index = 0;
};

TEST(SceneSelfCollision, ThrownArmsStayApartOnlyWithSelfCollision) {
  ThrownU on(true, 0.01);
  ThrownU off(false, 0.01);
  double least_on = std::numeric_limits<double>::infinity();
  double least_off = least_on;
  std::size_t self_contacts = 0;
  for (int cycle = 0; cycle < 100; ++cycle) {
    on.scene.cycle();
    off.scene.cycle();
    least_on = std::min(least_on, on.armsGap());
    least_off = std::min(least_off, off.armsGap());
    for (const SceneContact& c : on.scene.contacts()) self_contacts += c.object_a == c.object_b;
    EXPECT_TRUE(off.scene.contacts().empty());
  }
  EXPECT_GT(self_contacts, 0u);
  // The arms stop about the contact distance apart; without self-collision one enters the
  // other by more than that.
  EXPECT_GT(least_on, 0.5 * kContact);
  EXPECT_LT(least_off, -kContact) << "without self-collision the arms pass through each other";
}

class SelfCollisionStability : public ::testing::TestWithParam<double> {};

TEST_P(SelfCollisionStability, ArmsPressedTogetherStayFiniteAndApartFor1000Cycles) {
  ThrownU u(true, GetParam());
  for (int cycle = 0; cycle < 1000; ++cycle) {
    u.scene.cycle();
    ASSERT_TRUE(std::all_of(u.scene.body(u.index).positions().begin(),
                            u.scene.body(u.index).positions().end(),
                            [](const Eigen::Vector3d& p) { return p.allFinite(); }))
        << "cycle " << cycle;
    ASSERT_GT(u.armsGap(), -kContact) << "cycle " << cycle;
  }
}

// Cloth-like: a thin plate folded in two (its rest shape, halves 2.5 cm apart) lies on a floor
// and a rigid press comes down until the stack has room for the two layers and one contact
// distance between them, then holds it there.
TEST_P(SelfCollisionStability, FoldedPlatePressedFlatKeepsItsHalvesApart) {
  const double dt_s = GetParam();
  Scene scene(ThrownU::config(dt_s));
  constexpr double kLayer = 0.005;  // two layers of points 5 mm apart
  constexpr double kRadius = 0.5 * (0.025 + kLayer);
  const double bottom_m = -kRadius - 0.5 * kLayer;
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  Points floor_points = gridBox(50, 1, 25, 0.005);
  for (auto& p : floor_points) p.y() = bottom_m - 0.5 * kContact;
  scene.addObject(floor, floor_points);
  ObjectConfig press = floor;
  press.name = "press";
  press.kind = ObjectKind::kKinematic;
  const double press_from_m = kRadius + 0.5 * kLayer + kContact;
  const double press_to_m = bottom_m + 2.0 * kLayer + 2.0 * kContact;
  Points press_points = gridBox(50, 1, 25, 0.005);
  for (auto& p : press_points) p.y() = press_from_m;
  const std::size_t press_index = scene.addObject(press, press_points);
  ObjectConfig plate;
  plate.name = "plate";
  plate.shape.clusters = 6;
  plate.shape.stiffness = 0.05;
  plate.self_collision = true;
  const std::size_t index = scene.addObject(plate, bentIntoU(gridBox(41, 2, 21, kLayer), kRadius));
  for (int cycle = 0; cycle < 1000; ++cycle) {
    const double share = std::min(1.0, cycle / 100.0);
    scene.setPose(press_index, Eigen::Isometry3d(Eigen::Translation3d(
                                   0.0, share * (press_to_m - press_from_m), 0.0)));
    scene.cycle();
    const auto& positions = scene.body(index).positions();
    ASSERT_TRUE(std::all_of(positions.begin(), positions.end(),
                            [](const Eigen::Vector3d& p) { return p.allFinite(); }))
        << "cycle " << cycle;
    ASSERT_GT(armsGap(scene, index), 0.0) << "cycle " << cycle;
  }
  EXPECT_LT(armsGap(scene, index), 2.0 * kContact) << "the press must have closed the fold";
}

INSTANTIATE_TEST_SUITE_P(TimeSteps, SelfCollisionStability, ::testing::Values(0.01, 0.1));

TEST(SceneSelfCollision, TrackedFoldIsReportedAndQueried) {
  Scene scene(ThrownU::config(0.01));
  ObjectConfig strip;
  strip.name = "strip";
  strip.kind = ObjectKind::kTracked;
  strip.shape.clusters = 4;
  strip.self_collision = true;
  const Points rest = gridBox(41, 21, 2, 0.005);
  const std::size_t index = scene.addObject(strip, rest);
  scene.cycle();
  EXPECT_TRUE(scene.contacts().empty()) << "a flat strip does not touch itself";
  scene.observe(index, bentIntoU(rest, 0.5 * (0.005 + 0.5 * kContact)));
  scene.cycle();
  ASSERT_FALSE(scene.contacts().empty());
  for (const SceneContact& c : scene.contacts()) {
    EXPECT_EQ(c.object_a, index);
    EXPECT_EQ(c.object_b, index);
  }
  const std::size_t reported = scene.contacts().size();
  for (int level = 0; level <= scene.maxLevel(); ++level) {
    std::vector<SceneContact> queried;
    scene.contactsAt(level, index, index, queried);
    EXPECT_FALSE(queried.empty()) << "level " << level;
    if (level == scene.maxLevel()) {
      EXPECT_EQ(queried.size(), reported);
    }
  }
}

TEST(SceneSelfCollision, UndeformedObjectsOfEveryBuiltInSceneHaveNoSelfContacts) {
  for (const auto& [scene_kind, scene_name] : kDemoSceneNames) {
    const std::unique_ptr<Scene> demo = makeDemoScene(scene_kind);
    for (std::size_t i = 0; i < demo->objectCount(); ++i) {
      ObjectConfig config = demo->objectConfig(i);
      if (config.kind != ObjectKind::kDynamic && config.kind != ObjectKind::kTracked) continue;
      config.self_collision = true;
      Scene alone(demo->config());
      const std::size_t index = alone.addObject(config, demo->body(i).restPositions());
      for (int level = 0; level <= alone.maxLevel(); ++level) {
        std::vector<SceneContact> contacts;
        alone.contactsAt(level, index, index, contacts);
        EXPECT_TRUE(contacts.empty()) << scene_name << " " << config.name << " level " << level;
      }
    }
  }
}

TEST(SceneSelfCollision, ConfigurationIsCheckedNamingTheKey) {
  Scene scene(ThrownU::config(0.01));
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  floor.self_collision = true;
  try {
    scene.addObject(floor, gridBox(5, 5, 1, 0.01));
    FAIL() << "a static object cannot self-collide";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("self_collision"), std::string::npos) << e.what();
  }
  ObjectConfig soft;
  soft.name = "soft";
  soft.self_rest_distance_m = -0.01;
  try {
    scene.addObject(soft, gridBox(5, 5, 2, 0.01));
    FAIL() << "a negative rest distance";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("self_rest_distance_m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deformable_collision
