// What making an object builds, bit for bit as before its construction was made O(n log n):
// each case's trees (nodes, point order, buckets) and fixed planes (normals and surface extents,
// measured per node on demand in any order; the response's internal unit, so its header from
// detail/) against digests of what the quadratic-time construction (a sort per tree level,
// each fixed plane's columns read from the whole object) built.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/response/detail/fixed_planes.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/byte_digest.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Digest = ByteDigest;

void addTree(const SphereTree& tree, Digest& digest) {
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    digest.add(node.rest_center);
    for (const double v : {node.rest_radius_m, node.quadratic_extent_m2, node.mixed_extent_m2}) {
      digest.add(v);
    }
    for (const std::uint32_t v : {node.first_child, node.child_count, node.first_point,
                                  node.point_count, node.first_leaf, node.leaf_count}) {
      digest.add(v);
    }
    digest.add(node.cluster);
    digest.add(node.level);
  }
  for (const std::uint32_t index : tree.pointIndices()) digest.add(index);
  for (const std::uint32_t bucket : tree.buckets()) digest.add(bucket);
}

/// Every node's plane, asked for in node order. The planes are measured on the first ask: a
/// second set asked for leaves first, as contacts ask, must give the same bits.
void addPlanes(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m,
               Digest& digest) {
  detail::FixedPlanes planes(body, tree, gap_m);
  detail::FixedPlanes asked_backwards(body, tree, gap_m);
  const auto count = static_cast<std::uint32_t>(tree.nodeCount());
  for (std::uint32_t n = count; n-- > 0;) asked_backwards.plane(n);
  for (std::uint32_t n = 0; n < count; ++n) {
    const detail::FixedPlanes::Plane& plane = planes.plane(n);
    const detail::FixedPlanes::Plane& backwards = asked_backwards.plane(n);
    ASSERT_EQ(plane.normal, backwards.normal) << "node " << n;
    ASSERT_EQ(plane.extent_along, backwards.extent_along) << "node " << n;
    ASSERT_EQ(plane.extent_against, backwards.extent_against) << "node " << n;
    digest.add(plane.normal);
    digest.add(plane.extent_along);
    digest.add(plane.extent_against);
  }
}

struct Digests {
  std::uint64_t trees = 0;
  std::uint64_t planes = 0;
};

Digests ofScene(DemoScene which) {
  const auto scene = makeDemoScene(which);
  Digest trees, planes;
  for (std::size_t i = 0; i < scene->objectCount(); ++i) {
    addTree(scene->tree(i), trees);
    addPlanes(scene->body(i), scene->tree(i), scene->config().contact_distance_m, planes);
  }
  return {trees.value(), planes.value()};
}

Digests ofShape(const std::vector<Eigen::Vector3d>& points, int clusters,
                const SphereTreeConfig& tree_config, double gap_m) {
  ShapeMatchingConfig shape;
  shape.clusters = clusters;
  const ShapeMatchingBody body(points, shape);
  const SphereTree tree(body, tree_config);
  Digest trees, planes;
  addTree(tree, trees);
  addPlanes(body, tree, gap_m, planes);
  return {trees.value(), planes.value()};
}

/// `points` turned about a slanted axis and carried `offset_m` away: planes whose normals
/// are no axis, coordinates whose rounding is far coarser than near the origin.
std::vector<Eigen::Vector3d> moved(std::vector<Eigen::Vector3d> points, double angle_rad,
                                   const Eigen::Vector3d& offset_m) {
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(angle_rad, Eigen::Vector3d(1.0, 2.0, 0.5).normalized()).toRotationMatrix();
  for (auto& p : points) p = turn * p + offset_m;
  return points;
}

SphereTreeConfig wideTree() {
  SphereTreeConfig config;
  config.branching = 3;
  config.leaf_size = 4;
  return config;
}

struct Case {
  const char* name;
  std::function<Digests()> make;
  Digests expected;
};

const std::vector<Case>& cases() {
  static const std::vector<Case> all = {
      {"two_objects",
       [] { return ofScene(DemoScene::kTwoObjects); },
       {0x32ecc62ea4afbf9dull, 0x45ef34c9b334d737ull}},
      {"pile",
       [] { return ofScene(DemoScene::kPile); },
       {0x30450cfd3334915bull, 0xf390ed8becdb83e5ull}},
      {"three_objects",
       [] { return ofScene(DemoScene::kThreeObjects); },
       {0xebdae7d32900e2e1ull, 0xb0c0bc7ac595a09aull}},
      {"gripper",
       [] { return ofScene(DemoScene::kGripper); },
       {0xeb9ba2ee427b7589ull, 0x10eae26bcaf24ad4ull}},
      {"thin_floor",
       [] { return ofShape(gridLayers(61, 2, 0.02), 1, {}, 0.02); },
       {0xaad90451769c5e59ull, 0xc439b5ee8d9ac5a9ull}},
      {"thick_floor",
       [] { return ofShape(gridLayers(41, 8, 0.01), 1, {}, 0.01); },
       {0x5427e998d0f32052ull, 0x0b8863bf36c5a1beull}},
      {"thick_floor_clusters",
       [] { return ofShape(gridLayers(31, 6, 0.01), 4, {}, 0.01); },
       {0xca200f1923c45e18ull, 0x730871b33b39b715ull}},
      {"thick_floor_wide_tree",
       [] { return ofShape(gridLayers(31, 6, 0.01), 1, wideTree(), 0.01); },
       {0x0f47165cf8db5c06ull, 0x005aad86fbab2503ull}},
      {"random_box",
       [] {
         return ofShape(sampleBox(8000, {0.2, 0.2, 0.04}, 7), 1, {}, 0.01);
       },
       {0x68df41f1cf3c55e2ull, 0x1b80cda60ef77b65ull}},
      {"tilted_thick_floor",
       [] {
         return ofShape(moved(gridLayers(31, 6, 0.01), 0.7, {0.3, -0.2, 0.1}), 1, {}, 0.01);
       },
       {0x4d574a9ab27e3863ull, 0xc86b017478583c78ull}},
      {"far_thick_floor",
       [] {
         return ofShape(moved(gridLayers(31, 6, 0.01), 0.3, {1e5, -3e4, 2e3}), 1, {}, 0.01);
       },
       {0xc02957c691e92515ull, 0x233b0782f787a59bull}},
      {"scanned_surface",
       [] {
         return ofShape(sampleNoisySurface(8000, {0.3, 0.2, 0.1}, 0.001, 11), 1, {}, 0.01);
       },
       {0x6186343e8db0c853ull, 0x284288e1fe078295ull}},
  };
  return all;
}

class ObjectBuildEquivalence : public ::testing::TestWithParam<std::size_t> {};

TEST_P(ObjectBuildEquivalence, TreesAndPlanesAsBefore) {
  const Case& c = cases()[GetParam()];
  const Digests got = c.make();
  EXPECT_EQ(got.trees, c.expected.trees) << c.name << ": trees 0x" << std::hex << got.trees;
  EXPECT_EQ(got.planes, c.expected.planes) << c.name << ": planes 0x" << std::hex << got.planes;
}

INSTANTIATE_TEST_SUITE_P(Cases, ObjectBuildEquivalence, ::testing::Range<std::size_t>(0, 12),
                         [](const ::testing::TestParamInfo<std::size_t>& info) {
                           return std::string(cases()[info.param].name);
                         });

}  // namespace
}  // namespace deformable_collision
