#include "deformable_collision/ros/hierarchy_markers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using visualization_msgs::Marker;

TEST(DrawnRadius, NeverBelowTheRadiusAndAtMostOneStepAbove) {
  std::mt19937_64 engine(11);
  std::uniform_real_distribution<double> exponent(-5.0, 3.0);
  for (int i = 0; i < 100000; ++i) {
    const double radius = std::pow(10.0, exponent(engine));
    const double drawn = drawnRadius(radius, 10.0);
    ASSERT_GE(drawn, radius) << radius;
    ASSERT_LE(drawn, (radius * (1 + 1e-6) + 1e-6 + 1e-9) * std::exp2(1.0 / 8.0)) << radius;
  }
}

/// The gripper scene after its jaws have closed on the fruit: every kind of object, contacts.
std::unique_ptr<Scene> squeezedGripper() {
  auto scene = makeDemoScene(DemoScene::kGripper, 3000);
  for (int step = 0; step < 150; ++step) {
    driveDemoScene(DemoScene::kGripper, *scene, step * scene->config().dt_s);
    scene->cycle();
  }
  return scene;
}

struct DrawnSphere {
  Eigen::Vector3d center;
  double radius;
};

/// Spheres of each namespace, as a client decodes them: centre = point, radius = scale / 2.
std::map<std::string, std::vector<DrawnSphere>> decode(
    const visualization_msgs::MarkerArray& array) {
  std::map<std::string, std::vector<DrawnSphere>> spheres;
  for (const Marker& marker : array.markers) {
    if (marker.action != Marker::ADD) continue;
    EXPECT_EQ(marker.type, Marker::SPHERE_LIST);
    EXPECT_EQ(marker.points.size(), marker.colors.size());
    EXPECT_DOUBLE_EQ(marker.scale.x, marker.scale.y);
    for (const auto& p : marker.points) {
      spheres[marker.ns].push_back({Eigen::Vector3d(p.x, p.y, p.z), marker.scale.x / 2});
    }
  }
  return spheres;
}

class MarkerLevelTest : public ::testing::TestWithParam<int> {};

TEST_P(MarkerLevelTest, EveryPublishedPointLiesInADrawnSphereOfItsObject) {
  auto scene = squeezedGripper();
  const int level = std::min(GetParam(), scene->maxLevel());
  std::vector<SceneContact> contacts;
  scene->contactsAt(level, std::nullopt, std::nullopt, contacts);
  HierarchyMarkers builder;
  visualization_msgs::MarkerArray array;
  std_msgs::Header header;
  header.frame_id = "world";
  builder.build(*scene, level, contacts, false, header, array);
  ASSERT_FALSE(array.markers.empty());
  EXPECT_EQ(array.markers.front().action, Marker::DELETEALL);
  const auto spheres = decode(array);
  ASSERT_EQ(spheres.size(), scene->objectCount());
  for (std::size_t o = 0; o < scene->objectCount(); ++o) {
    const auto& drawn = spheres.at(scene->objectConfig(o).name);
    for (const Eigen::Vector3d& point : scene->body(o).positions()) {
      // As a subscriber of ~deformed sees it: float32.
      const Eigen::Vector3d published = point.cast<float>().cast<double>();
      bool inside = false;
      for (const DrawnSphere& s : drawn) {
        if ((published - s.center).norm() <= s.radius) {
          inside = true;
          break;
        }
      }
      ASSERT_TRUE(inside) << scene->objectConfig(o).name << " at level " << level;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Levels, MarkerLevelTest, ::testing::Values(0, 1, 3, 6, 100));

/// The spheres drawn in the contact colour, and all spheres drawn.
std::pair<std::size_t, std::size_t> highlighted(const visualization_msgs::MarkerArray& array) {
  std::size_t red = 0, all = 0;
  for (const Marker& marker : array.markers) {
    for (const auto& color : marker.colors) {
      red += color.r == 1.0f && color.g < 0.2f && color.a > 0.8f;
      ++all;
    }
  }
  return {red, all};
}

TEST(HierarchyMarkers, CollidingSpheresAreHighlightedAndCanBeDrawnAlone) {
  auto scene = squeezedGripper();
  const int level = 7;  // fine enough that some spheres are clear of every contact
  std::vector<SceneContact> contacts;
  scene->contactsAt(level, std::nullopt, std::nullopt, contacts);
  ASSERT_FALSE(contacts.empty());
  std::set<std::pair<std::string, std::uint32_t>> colliding;
  for (const auto& c : contacts) {
    colliding.emplace(scene->objectConfig(c.object_a).name, c.contact.node_a);
    colliding.emplace(scene->objectConfig(c.object_b).name, c.contact.node_b);
  }
  HierarchyMarkers builder;
  visualization_msgs::MarkerArray everything, only_colliding;
  builder.build(*scene, level, contacts, false, std_msgs::Header(), everything);
  builder.build(*scene, level, contacts, true, std_msgs::Header(), only_colliding);
  const auto [red_all, count_all] = highlighted(everything);
  const auto [red_only, count_only] = highlighted(only_colliding);
  EXPECT_EQ(red_all, colliding.size());
  EXPECT_GT(count_all, red_all);
  EXPECT_EQ(red_only, colliding.size());
  EXPECT_EQ(count_only, colliding.size());
}

// A static floor meets a small ball at its own leaves once the level reaches the ball's:
// the floor's spheres drawn at that level are highlighted over the leaves in contact.
TEST(HierarchyMarkers, ASphereOverAContactBelowTheLevelIsHighlighted) {
  SceneConfig config;
  config.contact_distance_m = 0.02;
  Scene scene(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  std::vector<Eigen::Vector3d> floor_points;
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) floor_points.emplace_back(0.02 * i, 0.02 * j, 0.0);
  }
  scene.addObject(floor, floor_points);
  ObjectConfig ball;
  ball.name = "ball";
  std::vector<Eigen::Vector3d> ball_points = sampleEllipsoid(300, {0.05, 0.05, 0.05}, 4);
  for (auto& p : ball_points) p.z() += 0.06;
  const std::size_t ball_index = scene.addObject(ball, ball_points);
  const int level = scene.tree(ball_index).maxLevel();
  ASSERT_LT(level, scene.maxLevel()) << "the floor must be the deeper tree";

  std::vector<SceneContact> contacts;
  scene.contactsAt(level, std::nullopt, std::nullopt, contacts);
  bool below_level = false;
  for (const auto& c : contacts) below_level |= c.contact.level > level;
  ASSERT_TRUE(below_level) << "no contact of the floor's leaves below the level";

  // The spheres drawn at the level with a contact node under them (leaf ranges nest).
  std::size_t expected = 0;
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    const SphereTree& tree = scene.tree(o);
    for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
      const SphereNode& drawn = tree.node(n);
      // The level's cut: where descents from the root end.
      if (!endsDescentToLevel(drawn, level) || drawn.level > level) continue;
      const bool over_contact = std::any_of(contacts.begin(), contacts.end(), [&](const auto& c) {
        if (c.object_a != o && c.object_b != o) return false;
        const SphereNode& touched =
            tree.node(c.object_a == o ? c.contact.node_a : c.contact.node_b);
        return touched.first_leaf >= drawn.first_leaf &&
               touched.first_leaf < drawn.first_leaf + drawn.leaf_count;
      });
      expected += over_contact;
    }
  }
  HierarchyMarkers builder;
  visualization_msgs::MarkerArray only_colliding;
  builder.build(scene, level, contacts, true, std_msgs::Header(), only_colliding);
  const auto [red, drawn] = highlighted(only_colliding);
  EXPECT_GT(expected, 0u);
  EXPECT_EQ(drawn, expected);
  EXPECT_EQ(red, expected);
}

}  // namespace
}  // namespace deformable_collision
