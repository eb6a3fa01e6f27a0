// SphereContact::error_bound_m against brute force on the points of each contact's two
// nodes, at every level of several scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

Points shifted(Points points, const Eigen::Vector3d& offset) {
  for (auto& p : points) p += offset;
  return points;
}

/// A lumpy ball, about as irregular as a scanned animal: points of an ellipsoid pushed out
/// or in by a few random bumps.
Points blob(std::size_t count, double radius_m, std::uint64_t seed) {
  Points points = sampleEllipsoid(count, {radius_m, 0.8 * radius_m, 0.7 * radius_m}, seed);
  std::mt19937_64 engine(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<Eigen::Vector3d> bumps(5);
  for (auto& bump : bumps)
    bump = Eigen::Vector3d(normal(engine), normal(engine), normal(engine)).normalized();
  for (auto& p : points) {
    const Eigen::Vector3d direction =
        p.norm() > 0.0 ? Eigen::Vector3d(p.normalized()) : Eigen::Vector3d::UnitX();
    double scale = 1.0;
    for (const auto& bump : bumps) scale += 0.3 * std::exp(-4.0 * (direction - bump).squaredNorm());
    p *= scale;
  }
  return points;
}

/// One object of a test scene: how its rest points are sampled, where, and how it moves.
struct ObjectSpec {
  enum class Shape { kEllipsoid, kBox, kBlob };
  const char* name;
  ObjectKind kind;
  DeformationMode mode;
  int clusters;
  Shape shape;
  std::size_t points;
  Eigen::Vector3d extents_m;  ///< Radii or half extents; a blob's first radius.
  std::uint64_t seed;
  Eigen::Vector3d offset_m;
};

Points restPoints(const ObjectSpec& spec) {
  switch (spec.shape) {
    case ObjectSpec::Shape::kEllipsoid:
      return shifted(sampleEllipsoid(spec.points, spec.extents_m, spec.seed), spec.offset_m);
    case ObjectSpec::Shape::kBox:
      return shifted(sampleBox(spec.points, spec.extents_m, spec.seed), spec.offset_m);
    case ObjectSpec::Shape::kBlob:
      break;
  }
  return shifted(blob(spec.points, spec.extents_m.x(), spec.seed), spec.offset_m);
}

/// A scene of soft objects with a contact distance of 2 cm, run for `cycles` cycles.
std::unique_ptr<Scene> sceneOf(const std::vector<ObjectSpec>& objects, bool gravity, int cycles) {
  SceneConfig config;
  config.contact_distance_m = 0.02;
  if (!gravity) config.gravity_mps2.setZero();
  auto scene = std::make_unique<Scene>(config);
  for (const ObjectSpec& spec : objects) {
    ObjectConfig object;
    object.name = spec.name;
    object.kind = spec.kind;
    object.shape.mode = spec.mode;
    object.shape.clusters = spec.clusters;
    object.shape.stiffness = 0.4;
    scene->addObject(object, restPoints(spec));
  }
  for (int cycle = 0; cycle < cycles; ++cycle) scene->cycle();
  return scene;
}

using Shape = ObjectSpec::Shape;
constexpr ObjectKind kDynamic = ObjectKind::kDynamic;
constexpr ObjectKind kStatic = ObjectKind::kStatic;
constexpr DeformationMode kRigid = DeformationMode::kRigid;
constexpr DeformationMode kLinear = DeformationMode::kLinear;
constexpr DeformationMode kQuadratic = DeformationMode::kQuadratic;

// clang-format off
/// A static plate 2 cm thick, its top at z = 1 cm.
const ObjectSpec kPlate{
    "plate", kStatic, kRigid, 1, Shape::kBox, 1200, {0.3, 0.3, 0.01}, 21, {0, 0, 0}};
/// Two balls of points overlapping by a fifth of their radius.
const std::vector<ObjectSpec> kTwoBalls{
    {"a", kDynamic, kLinear, 1, Shape::kEllipsoid, 500, {0.1, 0.1, 0.1}, 11, {0, 0, 0}},
    {"b", kDynamic, kLinear, 2, Shape::kEllipsoid, 400, {0.1, 0.1, 0.1}, 12, {0.18, 0.02, 0}}};
/// A box resting on the plate, 5 mm above it.
const std::vector<ObjectSpec> kBoxOnPlate{
    kPlate,
    {"box", kDynamic, kLinear, 2, Shape::kBox, 500, {0.1, 0.08, 0.06}, 22, {0.05, 0, 0.075}}};
/// Two lumpy blobs, quadratic and in several clusters, pushed into each other.
const std::vector<ObjectSpec> kBlobs{
    {"a", kDynamic, kQuadratic, 3, Shape::kBlob, 600, {0.1, 0, 0}, 31, {0, 0, 0}},
    {"b", kDynamic, kQuadratic, 2, Shape::kBlob, 500, {0.09, 0, 0}, 32, {0.17, 0.03, -0.02}}};
/// Blobs to drop onto the plate and each other.
const std::vector<ObjectSpec> kBlobsAbovePlate{
    kPlate,
    {"a", kDynamic, kQuadratic, 3, Shape::kBlob, 600, {0.1, 0, 0}, 42, {0, 0, 0.12}},
    {"b", kDynamic, kLinear, 2, Shape::kBlob, 500, {0.09, 0, 0}, 43, {0.05, 0.02, 0.33}}};
// clang-format on

struct BoundCase {
  const char* name;
  std::function<std::unique_ptr<Scene>()> make;
};

const BoundCase kCases[] = {
    {"two_balls", [] { return sceneOf(kTwoBalls, false, 0); }},
    {"box_on_plate", [] { return sceneOf(kBoxOnPlate, true, 0); }},
    {"blobs", [] { return sceneOf(kBlobs, false, 0); }},
    // Deformed by shape matching and the response, so that spheres carry each cluster's
    // goal deviation.
    {"blobs_settling_on_plate", [] { return sceneOf(kBlobsAbovePlate, true, 40); }},
    // The soft ball and bar of S3 on their floor.
    {"three_objects_after_cycles",
     [] {
       auto scene = makeDemoScene(DemoScene::kThreeObjects, 9000);
       for (int cycle = 0; cycle < 60; ++cycle) scene->cycle();
       return scene;
     }},
};

/// What brute force finds on the points of a contact's two nodes: their least distance,
/// and the midpoints of the pairs at it.
struct ClosestPairs {
  double distance_m = std::numeric_limits<double>::infinity();
  Points midpoints;
};

Points nodePoints(const Scene& scene, std::size_t object, std::uint32_t node) {
  const SphereTree& tree = scene.tree(object);
  const SphereNode& n = tree.node(node);
  Points points;
  for (std::uint32_t s = n.first_point; s < n.first_point + n.point_count; ++s) {
    points.push_back(scene.body(object).positions()[tree.pointIndices()[s]]);
  }
  return points;
}

/// Pairs within `tie_m` of the least distance count as closest: the query sums the
/// squares in another order than Eigen's norm.
ClosestPairs closestPairs(const Points& a, const Points& b, double tie_m) {
  ClosestPairs closest;
  for (const auto& x : a) {
    for (const auto& y : b) closest.distance_m = std::min(closest.distance_m, (x - y).norm());
  }
  for (const auto& x : a) {
    for (const auto& y : b) {
      if ((x - y).norm() <= closest.distance_m + tie_m) closest.midpoints.push_back(0.5 * (x + y));
    }
  }
  return closest;
}

class ContactErrorBound : public ::testing::TestWithParam<BoundCase> {};

// At every level, each contact's position and depth lie within its error bound of the
// truth of its nodes' points (docs/design.md, "Error bound of a contact"); the bound
// shrinks towards the leaves, stays within a few radii, and is 0 at the leaves, where
// position and depth are a closest pair's.
TEST_P(ContactErrorBound, HoldsAgainstTheNodesPointsAtEveryLevel) {
  auto scene = GetParam().make();
  const double contact_distance = scene->config().contact_distance_m;
  constexpr double kRounding = 1e-12;
  // The mean bound of the node contacts of each level that has some, from level 0 on.
  std::vector<double> mean_bound_of_level;
  std::vector<SceneContact> contacts;
  for (int level = 0; level <= scene->maxLevel(); ++level) {
    scene->contactsAt(level, std::nullopt, std::nullopt, contacts);
    ASSERT_FALSE(contacts.empty()) << "level " << level << ": the scene must touch";
    double bound_sum = 0.0;
    std::size_t node_contacts = 0;
    for (const SceneContact& found : contacts) {
      const SphereContact& c = found.contact;
      const ClosestPairs truth =
          closestPairs(nodePoints(*scene, found.object_a, c.node_a),
                       nodePoints(*scene, found.object_b, c.node_b), kRounding);
      const double true_depth = contact_distance - truth.distance_m;
      ASSERT_TRUE(std::isfinite(c.error_bound_m));
      ASSERT_GE(c.error_bound_m, 0.0);
      if (c.point_a != SphereContact::kNoPoint) {
        // A leaf pair: exact, the position being the midpoint of one of the closest pairs.
        EXPECT_EQ(c.error_bound_m, 0.0) << "level " << level;
        EXPECT_NEAR(c.depth_m, true_depth, kRounding) << "level " << level;
        double nearest_midpoint = std::numeric_limits<double>::infinity();
        for (const auto& m : truth.midpoints) {
          nearest_midpoint = std::min(nearest_midpoint, (c.position - m).norm());
        }
        EXPECT_LE(nearest_midpoint, kRounding) << "level " << level;
        continue;
      }
      EXPECT_LE(std::abs(c.depth_m - true_depth), c.error_bound_m)
          << "level " << level << ", nodes " << c.node_a << ", " << c.node_b;
      for (const auto& m : truth.midpoints) {
        EXPECT_LE((c.position - m).norm(), c.error_bound_m)
            << "level " << level << ", nodes " << c.node_a << ", " << c.node_b;
      }
      // Not vacuous: a few radii of the two spheres at most (and the bound's rounding margin).
      const double radius_a = scene->currentSphere(found.object_a, c.node_a).radius;
      const double radius_b = scene->currentSphere(found.object_b, c.node_b).radius;
      EXPECT_LE(c.error_bound_m,
                (1.0 + kRounding) * std::max(2.0 * (radius_a + radius_b), contact_distance) +
                    kRounding * 10.0)
          << "level " << level;
      bound_sum += c.error_bound_m;
      ++node_contacts;
    }
    if (level == scene->maxLevel()) {
      EXPECT_EQ(node_contacts, 0u) << "the finest level tests points only";
    } else if (node_contacts > 0) {
      mean_bound_of_level.push_back(bound_sum / node_contacts);
    }
  }
  // Level 0 is one pair of roots per object pair; from level 1 on, finer levels bound
  // tighter: the deepest level above the leaves, at least twice as tight as level 1.
  ASSERT_GE(mean_bound_of_level.size(), 3u);
  EXPECT_GT(mean_bound_of_level.back(), 0.0);
  EXPECT_LT(mean_bound_of_level.back(), 0.5 * mean_bound_of_level[1]);
}

INSTANTIATE_TEST_SUITE_P(Scenes, ContactErrorBound, ::testing::ValuesIn(kCases),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace deformable_collision
