#include "deformable_collision/core/hierarchy/node_slabs.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// A grid of `layers` layers of points 2 cm apart across a square of `half_m`, turned by
/// `pose`: a floor, a wall, a tilted ramp.
Points grid(double half_m, int layers, const Eigen::Isometry3d& pose) {
  Points points;
  const int steps = static_cast<int>(std::lround(2.0 * half_m / 0.02));
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      for (int k = 0; k < layers; ++k) {
        points.push_back(pose * Eigen::Vector3d(-half_m + 0.02 * i, -half_m + 0.02 * j, -0.02 * k));
      }
    }
  }
  return points;
}

Eigen::Isometry3d turned(double angle_rad, const Eigen::Vector3d& axis, const Eigen::Vector3d& at) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(at);
  pose.rotate(Eigen::AngleAxisd(angle_rad, axis.normalized()));
  return pose;
}

struct ShapeCase {
  std::string name;
  Points points;
  double scale_m;  ///< The shape's size: the spheres tried are of this order.
};

std::vector<ShapeCase> shapeCases() {
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  Points coincident(40, Eigen::Vector3d(0.3, -0.2, 0.1));
  Points collinear;
  for (int i = 0; i < 60; ++i) collinear.emplace_back(0.01 * i, 0.02 * i, -0.005 * i);
  Points far = sampleEllipsoid(500, {0.2, 0.1, 0.1}, 7);
  for (auto& p : far) p += Eigen::Vector3d(1e5, -1e5, 1e5);
  Points tiny = sampleBox(300, {1e-4, 2e-4, 1e-5}, 3);
  return {
      {"floor_two_layers", grid(0.3, 2, identity), 0.3},
      {"floor_one_layer", grid(0.3, 1, identity), 0.3},
      {"tilted_ramp", grid(0.2, 2, turned(0.4, {1, 1, 0}, {0.5, 0.1, -0.2})), 0.2},
      {"wall", grid(0.2, 3, turned(M_PI / 2, {0, 1, 0}, {-0.5, 0, 0.2})), 0.2},
      {"ellipsoid", sampleEllipsoid(800, {0.3, 0.2, 0.1}, 5), 0.3},
      {"coincident", coincident, 0.1},
      {"collinear", collinear, 0.5},
      {"far_from_origin", far, 0.2},
      {"tiny", tiny, 1e-4},
  };
}

/// The property the query relies on: a slab never calls a node apart from a sphere that
/// comes within the distance of one of its points. Spheres are tried all around each node,
/// most just beyond or within reach of its points, where rounding matters. Returns how many
/// trials the slabs called apart.
std::size_t checkNeverWronglyApart(const SphereTree& tree, const Points& positions,
                                   NodeSlabs& slabs, double scale_m) {
  EXPECT_EQ(slabs.size(), tree.nodeCount());
  std::mt19937_64 engine(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::size_t apart = 0;
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& node = tree.node(n);
    for (int trial = 0; trial < 40; ++trial) {
      const Eigen::Vector3d anchor =
          positions[tree.pointIndices()[node.first_point + trial % node.point_count]];
      const Sphere sphere{
          anchor + scale_m * Eigen::Vector3d(unit(engine), unit(engine), unit(engine)),
          0.2 * scale_m * (1.0 + unit(engine))};
      const double distance = 0.05 * scale_m * (1.0 + unit(engine));
      double nearest = std::numeric_limits<double>::infinity();
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        const Eigen::Vector3d& point = positions[tree.pointIndices()[s]];
        nearest = std::min(nearest, (point - sphere.center).norm() - sphere.radius);
      }
      if (slabs.apart(n, sphere, distance)) {
        ++apart;
        EXPECT_GE(nearest, distance) << "node " << n << ", trial " << trial;
        if (nearest < distance) return apart;
      }
      // A sphere on one of the node's points is never apart from it.
      EXPECT_FALSE(slabs.apart(n, Sphere{anchor, 0.0}, 0.0)) << "node " << n;
    }
  }
  return apart;
}

TEST(NodeSlabs, NeverCallAPairApartThatComesWithinReach) {
  for (const ShapeCase& shape : shapeCases()) {
    SCOPED_TRACE(shape.name);
    const ShapeMatchingBody body(shape.points, ShapeMatchingConfig{});
    const SphereTree tree(body, SphereTreeConfig{2, 8});
    NodeSlabs slabs;
    slabs.compute(tree, body.positions());
    const std::size_t apart = checkNeverWronglyApart(tree, body.positions(), slabs, shape.scale_m);
    // The trials are not all within reach: the slabs rule some out (the test has teeth).
    if (shape.name != "coincident") {
      EXPECT_GT(apart, 0u);
    }
  }
}

// A static object's slabs are measured when first asked for, in whatever order the queries
// ask: the same slabs as measured all at once.
TEST(NodeSlabs, MeasuredOnDemandAsMeasuredAtOnce) {
  for (const ShapeCase& shape : shapeCases()) {
    SCOPED_TRACE(shape.name);
    const ShapeMatchingBody body(shape.points, ShapeMatchingConfig{});
    const SphereTree tree(body, SphereTreeConfig{2, 8});
    NodeSlabs at_once;
    at_once.compute(tree, body.positions());
    NodeSlabs on_demand;
    on_demand.measureOnDemand(tree, body.positions());
    std::mt19937_64 engine(5);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (std::uint32_t n = static_cast<std::uint32_t>(tree.nodeCount()); n-- > 0;) {
      const Eigen::Vector3d& anchor =
          body.positions()[tree.pointIndices()[tree.node(n).first_point]];
      for (int trial = 0; trial < 8; ++trial) {
        const Eigen::Vector3d offset(unit(engine), unit(engine), unit(engine));
        const Sphere sphere{anchor + shape.scale_m * offset, 0.1 * shape.scale_m};
        const double distance_m = 0.05 * shape.scale_m * (trial % 3);
        ASSERT_EQ(on_demand.apart(n, sphere, distance_m), at_once.apart(n, sphere, distance_m))
            << "node " << n;
      }
    }
    NodeSlabs checked;
    checked.measureOnDemand(tree, body.positions());
    checkNeverWronglyApart(tree, body.positions(), checked, shape.scale_m);
  }
}

// A kinematic object's slabs follow its pose without visiting its points, and still hold
// them under a matrix that is not quite a rotation.
TEST(NodeSlabs, FollowAPoseWithoutVisitingThePoints) {
  Eigen::Isometry3d sheared = turned(0.7, {0.2, 1, -0.4}, {0.3, -0.1, 0.2});
  sheared.linear() *=
      (Eigen::Matrix3d() << 1.02, 0.03, 0.0, 0.0, 0.98, 0.01, 0.02, 0.0, 1.0).finished();
  const struct {
    const char* name;
    Eigen::Isometry3d pose;
  } poses[] = {
      {"identity", Eigen::Isometry3d::Identity()},
      {"turned", turned(2.1, {1, -2, 0.5}, {0.4, 0.2, -0.3})},
      {"far_from_origin", turned(-0.9, {0, 0, 1}, {1e5, 2e4, -1e5})},
      {"sheared", sheared},
  };
  for (const ShapeCase& shape : shapeCases()) {
    const ShapeMatchingBody body(shape.points, ShapeMatchingConfig{});
    const SphereTree tree(body, SphereTreeConfig{2, 8});
    NodeSlabs rest;
    rest.compute(tree, body.restPositions());
    for (const auto& [name, pose] : poses) {
      SCOPED_TRACE(shape.name + ", " + name);
      Points posed = body.restPositions();
      for (auto& p : posed) p = pose * p;
      NodeSlabs slabs;
      slabs.pose(rest, pose);
      const std::size_t apart = checkNeverWronglyApart(tree, posed, slabs, shape.scale_m);
      // A shear widens each slab by its turn's error times the points' norm: 1e5 m from the
      // origin, wider than anything the trials place around a node.
      const bool widened_away = std::string(name) == "sheared" && shape.name == "far_from_origin";
      if (shape.name != "coincident" && !widened_away) {
        EXPECT_GT(apart, 0u);
      }
    }
  }
}

// What the slabs are for: over a floor, a small sphere a few centimetres above it is apart
// from the floor's root, whose sphere reaches far above the floor.
TEST(NodeSlabs, RuleOutWhatIsAboveAFloorThatItsSpheresReach) {
  const ShapeMatchingBody floor(grid(0.5, 2, Eigen::Isometry3d::Identity()), ShapeMatchingConfig{});
  SphereTree tree(floor, SphereTreeConfig{2, 8});
  NodeSlabs slabs;
  slabs.compute(tree, floor.positions());
  const Sphere above{Eigen::Vector3d(0.1, -0.1, 0.05), 0.02};
  ASSERT_GT(tree.sphere(0).radius, 0.5);
  EXPECT_TRUE(slabs.apart(0, above, 0.02));
  EXPECT_FALSE(slabs.apart(0, above, 0.04));  // 3 cm above the top layer, 2 cm sphere
  const Sphere below{Eigen::Vector3d(0.0, 0.0, -0.08), 0.02};
  EXPECT_TRUE(slabs.apart(0, below, 0.02));
}

TEST(NodeSlabs, RefuseATreeOverOtherPoints) {
  const ShapeMatchingBody body(sampleEllipsoid(100, {0.1, 0.1, 0.1}, 1), ShapeMatchingConfig{});
  const SphereTree tree(body, SphereTreeConfig{2, 8});
  NodeSlabs slabs;
  const Points fewer(body.positions().begin(), body.positions().begin() + 50);
  EXPECT_THROW(slabs.compute(tree, fewer), std::invalid_argument);
  EXPECT_TRUE(slabs.empty());
}

}  // namespace
}  // namespace deformable_collision
