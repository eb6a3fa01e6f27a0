// Contact response seen through the Scene: stacks of boxes and of soft objects on a floor
// stand still and stay apart, in every mode and at every level.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>
#include <ostream>
#include <string>
#include <tuple>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

// ---------------------------------------------------------------------------------------
// A stiff stack (alpha = 1) at a long step (h = 0.05 s): three boxes dropped onto each other
// on a floor stand still for 1000 cycles, in every mode, at every level: 0 to 5 and the
// finest (the boxes' hierarchies end at level 6, where the floor meets them at its leaves).
// At this step gravity alone takes a resting box 2.5 cm down per cycle, more than the contact
// distance, and a pushed box walks sideways by its contact normals' tilt unless friction holds it.
// At coarse levels a contact must not end before the push that clears it is done, or the
// top box hops and slides off.

struct StackMode {
  const char* name;
  DeformationMode mode;
  int clusters;
};

void PrintTo(const StackMode& m, std::ostream* os) { *os << m.name; }

class StiffStackTest : public ::testing::TestWithParam<std::tuple<StackMode, int>> {};

TEST_P(StiffStackTest, StandsStillForAThousandLongSteps) {
  const auto& [c, level] = GetParam();
  SceneConfig config;
  config.contact_distance_m = 0.02;
  config.dt_s = 0.05;
  config.level = level;
  Scene scene(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  scene.addObject(floor, floorPoints());
  constexpr int kBoxes = 3;
  constexpr double kHalfSide = 0.06;
  std::vector<std::size_t> boxes;
  for (int k = 0; k < kBoxes; ++k) {
    ObjectConfig box;
    box.name = "box_" + std::to_string(k);
    box.shape.mode = c.mode;
    box.shape.clusters = c.clusters;
    box.shape.stiffness = 1.0;
    Points points = sampleBox(500, {kHalfSide, kHalfSide, kHalfSide}, 3 + k);
    for (auto& p : points)
      p.z() += kHalfSide + config.contact_distance_m / 2 + k * (2 * kHalfSide + 0.02);
    boxes.push_back(scene.addObject(box, points));
  }

  constexpr int kCycles = 1000, kLateCycles = 500;
  std::vector<Eigen::Vector3d> late_start(kBoxes);
  double late_fastest = 0.0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    if (cycle == kCycles - kLateCycles) {
      for (int k = 0; k < kBoxes; ++k) late_start[k] = meanPosition(scene.body(boxes[k]));
    }
    scene.cycle();
    ASSERT_TRUE(allFinite(scene)) << "cycle " << cycle;
    if (cycle >= kCycles - kLateCycles) late_fastest = std::max(late_fastest, fastestPoint(scene));
  }
  EXPECT_LT(late_fastest, 1e-3) << "m/s over the last " << kLateCycles << " cycles";
  for (int k = 0; k < kBoxes; ++k) {
    const Eigen::Vector3d at = meanPosition(scene.body(boxes[k]));
    EXPECT_LT((at - late_start[k]).norm(), 1e-3) << "box " << k << " crept (m)";
    if (k == 0) {
      EXPECT_GT(lowestZ(scene.body(boxes[k])), 0.0) << "the bottom box entered the floor";
      continue;
    }
    // Still on the box below: its centre above the lower box's top face, and not beyond
    // its sides.
    const Eigen::Vector3d below = meanPosition(scene.body(boxes[k - 1]));
    EXPECT_GT(at.z() - below.z(), 2 * kHalfSide - config.contact_distance_m)
        << "box " << k << " sank in";
    EXPECT_LT((at - below).head<2>().norm(), kHalfSide) << "box " << k << " slid off";
  }
}

INSTANTIATE_TEST_SUITE_P(
    ModesAndLevels, StiffStackTest,
    ::testing::Combine(
        ::testing::Values(StackMode{"rigid", DeformationMode::kRigid, 1},
                          StackMode{"linear_2_clusters", DeformationMode::kLinear, 2},
                          StackMode{"quadratic_3_clusters", DeformationMode::kQuadratic, 3}),
        ::testing::Values(0, 1, 2, 3, 4, 5, -1)),
    [](const auto& info) {
      const int level = std::get<1>(info.param);
      return std::string(std::get<0>(info.param).name) +
             (level < 0 ? std::string("_finest") : "_level_" + std::to_string(level));
    });

// ---------------------------------------------------------------------------------------
// Boxes stacked on the floor rest at every level: no cycle of the last 50 leaves a box
// moving, and none sinks into the one below.
// - Two boxes against a wall. A wall beside the upper box does not carry it; ranked as
//   carried like the lower box, it shared each step's stop with that box, which the floor
//   then stopped whole, and it kept a step of gravity (98 mm/s at h = 0.01 s) every cycle,
//   held up by the pushes alone, or sank into the lower box: so did most of the pile along
//   its walls.
// - Three boxes added to the scene from the top down, so that the contact order puts the
//   upper pairs first. Resolved in that order, the top box was stopped against the middle
//   one before the middle one was stopped against the bottom one, and kept its step of
//   gravity every cycle; the pairs are resolved from the supports up.

enum class StackArrangement { kTwoAgainstAWall, kThreeAddedTopFirst };

struct RestingStackCase {
  StackArrangement arrangement;
  StackMode mode;
  double stiffness;
  int level;
};

void PrintTo(const RestingStackCase& c, std::ostream* os) {
  *os << (c.arrangement == StackArrangement::kTwoAgainstAWall ? "two against a wall, "
                                                              : "three added top first, ")
      << c.mode.name << " stiffness " << c.stiffness << " level " << c.level;
}

/// A 0.8 m wide wall of two layers 2 cm apart standing on floorPoints(), its face the plane
/// x = `face_x_m`, 0.5 m high.
Points wallPoints(double face_x_m) {
  Points wall;
  for (int j = -20; j <= 20; ++j) {
    for (int k = 1; k <= 25; ++k) {
      for (int layer = 0; layer < 2; ++layer)
        wall.emplace_back(face_x_m - 0.02 * layer, 0.02 * j, 0.02 * k);
    }
  }
  return wall;
}

class RestingStackTest : public ::testing::TestWithParam<RestingStackCase> {};

TEST_P(RestingStackTest, RestsAndStaysApart) {
  const RestingStackCase& c = GetParam();
  auto scene = sceneOnFloor(c.level);
  constexpr double kWallFace = -0.1, kHalfSide = 0.06;
  const double gap = scene->config().contact_distance_m / 2;
  const bool against_wall = c.arrangement == StackArrangement::kTwoAgainstAWall;
  if (against_wall) {
    ObjectConfig wall;
    wall.name = "wall";
    wall.kind = ObjectKind::kStatic;
    scene->addObject(wall, wallPoints(kWallFace));
  }
  const int count = against_wall ? 2 : 3;
  // boxes[k] is the k-th from the floor, whichever order the scene has them in.
  std::vector<std::size_t> boxes(count);
  for (int n = 0; n < count; ++n) {
    const int k = against_wall ? n : count - 1 - n;
    ObjectConfig box;
    box.name = "box_" + std::to_string(k);
    box.shape.mode = c.mode.mode;
    box.shape.clusters = c.mode.clusters;
    box.shape.stiffness = c.stiffness;
    Points points = sampleBox(500, {kHalfSide, kHalfSide, kHalfSide}, 3 + k);
    for (auto& p : points) {
      if (against_wall) p.x() += kWallFace + gap + kHalfSide;
      p.z() += gap + kHalfSide + k * (2 * kHalfSide + gap);
    }
    boxes[k] = scene->addObject(box, points);
  }
  constexpr int kCycles = 300, kLateCycles = 50;
  double late_fastest = 0.0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    scene->cycle();
    ASSERT_TRUE(allFinite(*scene)) << "cycle " << cycle;
    if (cycle < kCycles - kLateCycles) continue;
    for (const std::size_t box : boxes) {
      late_fastest = std::max(late_fastest, scene->body(box).meanVelocity().norm());
    }
  }
  EXPECT_LT(late_fastest, 1e-3) << "m/s over the last " << kLateCycles << " cycles";
  for (int k = 1; k < count; ++k) {
    const Eigen::Vector3d lower = meanPosition(scene->body(boxes[k - 1]));
    const Eigen::Vector3d upper = meanPosition(scene->body(boxes[k]));
    EXPECT_GT(upper.z() - lower.z(), 2 * kHalfSide - scene->config().contact_distance_m)
        << "box " << k << " sank into the one below";
  }
  if (against_wall) {
    EXPECT_GT(meanPosition(scene->body(boxes[0])).x() - kHalfSide, kWallFace) << "into the wall";
  }
}

std::vector<RestingStackCase> restingStackCases() {
  std::vector<RestingStackCase> cases;
  for (const StackArrangement arrangement :
       {StackArrangement::kTwoAgainstAWall, StackArrangement::kThreeAddedTopFirst}) {
    for (const StackMode mode :
         {StackMode{"rigid", DeformationMode::kRigid, 1},
          StackMode{"linear", DeformationMode::kLinear, 1},
          StackMode{"quadratic_3_clusters", DeformationMode::kQuadratic, 3}}) {
      for (const double stiffness : {0.2, 1.0}) {
        for (const int level : {0, 1, 2, 3, 4, 5, -1})
          cases.push_back({arrangement, mode, stiffness, level});
      }
    }
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(ArrangementsModesStiffnessesAndLevels, RestingStackTest,
                         ::testing::ValuesIn(restingStackCases()), [](const auto& info) {
                           const RestingStackCase& c = info.param;
                           return std::string(c.arrangement == StackArrangement::kTwoAgainstAWall
                                                  ? "against_a_wall_"
                                                  : "added_top_first_") +
                                  c.mode.name + (c.stiffness < 1.0 ? "_soft" : "_stiff") +
                                  (c.level < 0 ? std::string("_finest")
                                               : "_level_" + std::to_string(c.level));
                         });

// ---------------------------------------------------------------------------------------
// Six soft ellipsoids (436 points each, stiffness 0.5, in the pile's modes) dropped on each
// other stay apart under the load of those above, at every level: no two points of two
// objects come closer than a quarter of the contact distance over cycles 200 to 400. Their
// clouds must not pass into each other: the nearest pair of two such clouds stays closer
// than the point spacing however deep they are, and a response that takes its depth from
// it lets a stack sink into itself.

class SoftStackTest : public ::testing::TestWithParam<int> {};

TEST_P(SoftStackTest, PointsOfTwoObjectsStayApart) {
  auto scene_on_floor = sceneOnFloor(GetParam());
  Scene& scene = *scene_on_floor;
  const SceneConfig& config = scene.config();
  constexpr int kObjects = 6;
  for (int k = 0; k < kObjects; ++k) {
    ObjectConfig soft;
    soft.name = "soft_" + std::to_string(k);
    soft.shape.mode = k % 2 ? DeformationMode::kQuadratic : DeformationMode::kLinear;
    soft.shape.stiffness = 0.5;
    soft.shape.beta = 0.6;
    soft.shape.damping = 0.1;
    soft.shape.mass_kg = 0.2;
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    Points points = sampleEllipsoid(436, {0.07, 0.06, 0.05}, 10 + k);
    for (auto& p : points) p = turn * p + Eigen::Vector3d(0.02 * (k % 2), 0.0, 0.08 + 0.13 * k);
    scene.addObject(soft, points);
  }
  if (GetParam() > scene.maxLevel())
    GTEST_SKIP() << "the scene has " << scene.maxLevel() << " levels";

  double closest = std::numeric_limits<double>::infinity();
  for (int cycle = 0; cycle < 400; ++cycle) {
    scene.cycle();
    ASSERT_TRUE(allFinite(scene)) << "cycle " << cycle;
    if (cycle < 200 || cycle % 20 != 0) continue;
    for (std::size_t a = 1; a < scene.objectCount(); ++a) {
      for (std::size_t b = a + 1; b < scene.objectCount(); ++b) {
        for (const auto& p : scene.body(a).positions()) {
          for (const auto& q : scene.body(b).positions()) {
            closest = std::min(closest, (p - q).norm());
          }
        }
      }
    }
  }
  EXPECT_GT(closest, config.contact_distance_m / 4) << "m between points of two objects";
}

INSTANTIATE_TEST_SUITE_P(Levels, SoftStackTest, ::testing::Values(0, 1, 2, 3, 4, 5, 6, -1),
                         [](const auto& info) {
                           return info.param < 0 ? std::string("finest")
                                                 : "level_" + std::to_string(info.param);
                         });

}  // namespace
}  // namespace test
}  // namespace deformable_collision
