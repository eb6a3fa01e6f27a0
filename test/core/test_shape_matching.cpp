// ShapeMatchingBody, the fit and the step: exact recovery, goals, conservation, release,
// the goal deviation bound, stability, and bad configurations.
#include "deformable_collision/core/shape_matching/shape_matching.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "deformable_collision/scenes/shapes.h"
#include "shape_matching_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

// ---------------------------------------------------------------------------------------
// Exact recovery: observed points that are a known transform of the rest shape are
// registered with goals equal to the observations (to 1e-9 of the object size) and, with
// one cluster, with the known matrices themselves (to 1e-9).

Eigen::Matrix3d shearStretch() {
  Eigen::Matrix3d m;
  m << 1.3, 0.2, -0.1, 0.05, 0.8, 0.3, 0.1, -0.2, 1.1;
  return m;
}

Eigen::Matrix<double, 3, 9> quadraticMap() {
  Eigen::Matrix<double, 3, 9> t = Eigen::Matrix<double, 3, 9>::Zero();
  t.leftCols<3>() = kRotation * shearStretch();
  t.col(3) << 0.0, 0.0, 0.8;   // bend: z += 0.8 x^2
  t.col(7) << 0.4, 0.0, 0.0;   // twist-like: x += 0.4 y z
  t.col(6) << 0.0, -0.3, 0.0;  // y -= 0.3 x y
  return t;
}

struct RecoveryCase {
  const char* name;
  DeformationMode mode;
  int clusters;
  Eigen::Matrix<double, 3, 9> transform;  // applied to features of (x - rest centroid)
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const RecoveryCase& c, std::ostream* os) { *os << c.name; }

class ExactRecoveryTest : public ::testing::TestWithParam<RecoveryCase> {};

TEST_P(ExactRecoveryTest, TrackedTransformIsRecovered) {
  const auto& c = GetParam();
  const Points rest = sampleBox(800, {0.5, 0.3, 0.2}, 11);
  ShapeMatchingBody body(rest, configFor(c.mode, c.clusters));
  const Eigen::Vector3d center = centroid(rest);
  const Eigen::Vector3d translation(0.7, -2.0, 3.5);
  const Points observed = mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return c.transform * quadraticFeatures(p - center) + translation;
  });
  EXPECT_EQ(body.track(observed), 0u);

  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    EXPECT_LT(body.deformation(k).goal_deviation_bound_m, 1e-9) << "cluster " << k;
  }
  if (c.clusters == 1) {
    const auto& deformation = body.deformation(0);
    EXPECT_TRUE(deformation.transform.isApprox(c.transform, 1e-9))
        << deformation.transform << "\nexpected\n"
        << c.transform;
  }
}

Eigen::Matrix<double, 3, 9> linearPart(const Eigen::Matrix3d& m) {
  Eigen::Matrix<double, 3, 9> t = Eigen::Matrix<double, 3, 9>::Zero();
  t.leftCols<3>() = m;
  return t;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ExactRecoveryTest,
    ::testing::Values(
        RecoveryCase{"rigid_one_cluster", DeformationMode::kRigid, 1, linearPart(kRotation)},
        RecoveryCase{"rigid_four_clusters", DeformationMode::kRigid, 4, linearPart(kRotation)},
        RecoveryCase{"linear_one_cluster", DeformationMode::kLinear, 1,
                     linearPart(kRotation* shearStretch())},
        RecoveryCase{"linear_four_clusters", DeformationMode::kLinear, 4,
                     linearPart(kRotation* shearStretch())},
        RecoveryCase{"quadratic_one_cluster", DeformationMode::kQuadratic, 1, quadraticMap()},
        RecoveryCase{"quadratic_four_clusters", DeformationMode::kQuadratic, 4, quadraticMap()},
        RecoveryCase{"quadratic_of_linear_map", DeformationMode::kQuadratic, 1,
                     linearPart(shearStretch())}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(GoalTransform, LinearGoalIsTheVolumePreservingFitWithFullStiffness) {
  ShapeMatchingConfig config = configFor(DeformationMode::kLinear, 1);
  config.stiffness = 1.0;
  config.beta = 1.0;
  config.damping = 0.0;
  const Points rest = sampleBox(500, {0.4, 0.3, 0.2}, 3);
  ShapeMatchingBody body(rest, config);
  const Eigen::Matrix3d deformation = shearStretch();
  const Eigen::Vector3d center = centroid(rest);
  body.setPositions(mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return deformation * (p - center) + center;
  }));
  body.step(0.01, Eigen::Vector3d::Zero());
  // With alpha = 1 and zero velocity every point lands on its goal in one step.
  const Eigen::Matrix3d expected = deformation / std::cbrt(deformation.determinant());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    EXPECT_LT((body.positions()[i] - (expected * (rest[i] - center) + center)).norm(), 1e-9);
  }
}

TEST(GoalTransform, RigidGoalIsTheRotation) {
  ShapeMatchingConfig config = configFor(DeformationMode::kRigid, 1);
  config.stiffness = 1.0;
  config.damping = 0.0;
  const Points rest = sampleBox(500, {0.4, 0.3, 0.2}, 4);
  ShapeMatchingBody body(rest, config);
  const Eigen::Vector3d center = centroid(rest);
  body.setPositions(mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return kRotation * shearStretch() * (p - center) + center;
  }));
  body.step(0.01, Eigen::Vector3d::Zero());
  const Eigen::Matrix3d rotation = body.deformation(0).rotation.toRotationMatrix();
  for (std::size_t i = 0; i < rest.size(); ++i) {
    EXPECT_LT((body.positions()[i] - (rotation * (rest[i] - center) + center)).norm(), 1e-9);
  }
}

// ---------------------------------------------------------------------------------------
// Conservation: without external forces the goal step (and the damping) changes neither
// linear nor angular momentum.

struct ConservationCase {
  const char* name;
  DeformationMode mode;
  int clusters;
  double damping;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const ConservationCase& c, std::ostream* os) { *os << c.name; }

class ConservationTest : public ::testing::TestWithParam<ConservationCase> {};

TEST_P(ConservationTest, MomentumIsConserved) {
  const auto& c = GetParam();
  ShapeMatchingConfig config = configFor(c.mode, c.clusters);
  config.damping = c.damping;
  config.stiffness = 0.7;
  const Points rest = sampleEllipsoid(600, {0.5, 0.3, 0.2}, 5);
  ShapeMatchingBody body(rest, config);
  std::mt19937_64 engine(9);
  std::normal_distribution<double> noise(0.0, 0.05);
  body.setPositions(mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return shearStretch() * p + Eigen::Vector3d(noise(engine), noise(engine), noise(engine));
  }));
  // Spin the object first so that the test also sees angular momentum.
  const auto momenta = [&]() {
    Eigen::Vector3d linear = Eigen::Vector3d::Zero();
    Eigen::Vector3d angular = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < body.pointCount(); ++i) {
      linear += body.pointMassKg() * body.velocities()[i];
      angular += body.pointMassKg() * body.positions()[i].cross(body.velocities()[i]);
    }
    return std::make_pair(linear, angular);
  };
  body.step(0.01, Eigen::Vector3d::Zero());
  const auto before = momenta();
  ASSERT_GT(before.second.norm() + before.first.norm(), 0.0);
  for (int s = 0; s < 20; ++s) body.step(0.01, Eigen::Vector3d::Zero());
  const auto after = momenta();
  const double scale = body.pointMassKg() * body.pointCount() * 1.0;
  EXPECT_LT((after.first - before.first).norm(), 1e-10 * scale);
  EXPECT_LT((after.second - before.second).norm(), 1e-10 * scale);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ConservationTest,
    ::testing::Values(ConservationCase{"rigid", DeformationMode::kRigid, 1, 0.0},
                      ConservationCase{"linear", DeformationMode::kLinear, 1, 0.0},
                      ConservationCase{"quadratic", DeformationMode::kQuadratic, 1, 0.0},
                      ConservationCase{"linear_clusters", DeformationMode::kLinear, 3, 0.0},
                      ConservationCase{"quadratic_clusters", DeformationMode::kQuadratic, 3, 0.0},
                      ConservationCase{"linear_damped", DeformationMode::kLinear, 1, 0.2},
                      ConservationCase{"quadratic_clusters_damped", DeformationMode::kQuadratic, 4,
                                       0.2}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Release, DeformedObjectReturnsToItsRestShape) {
  for (const auto mode : {DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    ShapeMatchingConfig config = configFor(mode, 3);
    config.stiffness = 0.5;
    config.damping = 0.1;
    const Points rest = sampleBox(1500, {0.5, 0.2, 0.1}, 6);
    ShapeMatchingBody body(rest, config);
    body.setPositions(mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
      return Eigen::Vector3d(1.3 * p.x(), 0.8 * p.y(), p.z() + 0.6 * p.x() * p.x());
    }));
    const double initial = shapeError(body);
    const Eigen::Vector3d start_center = centroid(body.positions());
    for (int s = 0; s < 600; ++s) body.step(0.01, Eigen::Vector3d::Zero());
    EXPECT_GT(initial, 0.02) << toString(mode);
    EXPECT_LT(shapeError(body), 1e-3 * initial) << toString(mode);
    EXPECT_LT((centroid(body.positions()) - start_center).norm(), 1e-9) << toString(mode);
  }
}

// ---------------------------------------------------------------------------------------
// Erratum 3: the per-cluster bound covers every point's distance to its goal, whatever
// the stiffness and in track mode with noise.

TEST(GoalDeviationBound, CoversEveryPointInSimulationAndTracking) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    for (const double stiffness : {0.0, 0.3, 1.0}) {
      ShapeMatchingConfig config = configFor(mode, 4);
      config.stiffness = stiffness;
      const Points rest = sampleEllipsoid(700, {0.5, 0.3, 0.3}, 8);
      ShapeMatchingBody body(rest, config);
      body.setPositions(mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
        return Eigen::Vector3d(p.x() + 0.5 * p.y() * p.y(), 1.5 * p.y(), 0.7 * p.z());
      }));
      for (int s = 0; s < 30; ++s) {
        body.step(0.02, Eigen::Vector3d(0.0, 0.0, -9.81));
        ASSERT_LE(worstBoundExcess(body), 1e-12) << toString(mode) << " alpha " << stiffness;
      }
      std::mt19937_64 engine(12);
      std::normal_distribution<double> noise(0.0, 0.01);
      Points observed = body.positions();
      for (auto& p : observed) p += Eigen::Vector3d(noise(engine), noise(engine), noise(engine));
      body.track(observed);
      EXPECT_LE(worstBoundExcess(body), 1e-12) << toString(mode) << " tracked";
    }
  }
}

TEST(GoalDeviationBound, ExcludesTheObjectsOwnMotion) {
  ShapeMatchingConfig config = configFor(DeformationMode::kRigid, 1);
  config.stiffness = 1.0;
  ShapeMatchingBody body(sampleBox(300, {0.1, 0.1, 0.1}, 2), config);
  for (int s = 0; s < 100; ++s) body.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
  // The box falls at about 10 m/s, i.e. 0.1 m per step, without deforming.
  EXPECT_LT(body.deformation(0).goal_deviation_bound_m, 1e-9);
}

// ---------------------------------------------------------------------------------------
// Stability matrix: every mode, stiffness 0 to 1, steps up to 0.1 s, degenerate and inverted
// clusters (docs/design.md, "Shape matching"). Every case runs 300 steps under gravity twice:
// with the default goals (volume-preserving, damping 0.1) and undamped with conservative
// goals (preserve_volume off, damping 0). Nothing may become NaN or Inf, and the energy
// stays bounded, measured against D, the largest distance of the start from the rigidly
// registered rest shape (the elastic displacement): the object stays within 3 (R0 + D) of
// its centre (R0 its rest radius) and no point moves faster than the free fall plus 10 D/dt.

struct StabilityCase {
  std::string name;
  DeformationMode mode;
  int clusters;
  double stiffness;
  double dt_s;
  Points rest;
  PointMap start;  // initial positions from rest positions
  bool damped_volume_goals;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const StabilityCase& c, std::ostream* os) { *os << c.name; }

double radiusAbout(const Points& points, const Eigen::Vector3d& center) {
  double r = 0.0;
  for (const auto& p : points) r = std::max(r, (p - center).norm());
  return r;
}

Points line(std::size_t n) {
  Points p;
  for (std::size_t i = 0; i < n; ++i) p.emplace_back(0.1 * i, 0.05 * i, -0.02 * i);
  return p;
}

Points plane(std::size_t n) {
  Points p = sampleBox(n, {0.3, 0.2, 0.0}, 21);
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 1, 0).normalized()).matrix();
  for (auto& x : p) x = tilt * x;
  return p;
}

Points scaled(const Points& points, double factor, const Eigen::Vector3d& offset) {
  return mapped(points,
                [&](const Eigen::Vector3d& p) -> Eigen::Vector3d { return factor * p + offset; });
}

const PointMap kSquash = [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
  return Eigen::Vector3d(1.3 * p.x(), 1.3 * p.y(), 0.5 * p.z());
};
const PointMap kIdentity = [](const Eigen::Vector3d& p) -> Eigen::Vector3d { return p; };

PointMap aroundCentroid(const Points& rest, const PointMap& f) {
  const Eigen::Vector3d c = centroid(rest);
  return [c, f](const Eigen::Vector3d& p) -> Eigen::Vector3d { return f(p - c) + c; };
}

std::vector<StabilityCase> stabilityCases() {
  const Points cube = sampleBox(300, {0.2, 0.2, 0.2}, 20);
  const Points far_cube = scaled(cube, 1.0, Eigen::Vector3d(1e5, -1e5, 1e5));
  const Points tiny_cube = scaled(cube, 5e-4, Eigen::Vector3d::Zero());
  const Points huge_cube = scaled(cube, 5e4, Eigen::Vector3d::Zero());
  const PointMap mirror = [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return Eigen::Vector3d(-p.x(), p.y(), p.z());
  };
  const PointMap point_inversion = [](const Eigen::Vector3d& p) -> Eigen::Vector3d { return -p; };
  const PointMap stretch = [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return Eigen::Vector3d(100 * p.x(), p.y(), p.z());
  };
  std::vector<StabilityCase> cases;
  for (const bool damped_volume_goals : {true, false}) {
    for (const auto mode :
         {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
      const std::string prefix =
          std::string(toString(mode)) + (damped_volume_goals ? "_default_" : "_undamped_");
      const auto add = [&](const std::string& name, int clusters, double stiffness, double dt,
                           const Points& rest, const PointMap& start) {
        cases.push_back(
            {prefix + name, mode, clusters, stiffness, dt, rest, start, damped_volume_goals});
      };
      add("stiffness_0", 2, 0.0, 0.01, cube, aroundCentroid(cube, kSquash));
      add("stiffness_0_5", 2, 0.5, 0.01, cube, aroundCentroid(cube, kSquash));
      add("stiffness_1", 2, 1.0, 0.01, cube, aroundCentroid(cube, kSquash));
      add("dt_0_1", 2, 1.0, 0.1, cube, aroundCentroid(cube, kSquash));
      add("one_point", 1, 1.0, 0.05, {Eigen::Vector3d(1, 2, 3)}, kIdentity);
      add("two_points", 1, 1.0, 0.05, {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, 0, 0)},
          [](const Eigen::Vector3d& p) -> Eigen::Vector3d { return 3.0 * p; });
      add("three_points", 1, 1.0, 0.05,
          {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0, 0.1, 0)},
          [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
            return Eigen::Vector3d(p.y(), p.x(), 0.05);
          });
      add("collinear", 2, 1.0, 0.05, line(40), [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
        return Eigen::Vector3d(p.x(), 2 * p.y(), p.x() * p.x());
      });
      add("coplanar", 2, 1.0, 0.05, plane(200), aroundCentroid(plane(200), kSquash));
      add("coincident", 2, 1.0, 0.05, Points(30, Eigen::Vector3d(0.5, 0.5, 0.5)),
          [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
            return p + Eigen::Vector3d(0, 0, 0.01);
          });
      add("inverted_mirror", 2, 1.0, 0.02, cube, aroundCentroid(cube, mirror));
      add("inverted_point", 1, 0.5, 0.02, cube, aroundCentroid(cube, point_inversion));
      add("far_from_origin_1e5m", 3, 1.0, 0.01, far_cube, aroundCentroid(far_cube, kSquash));
      add("tiny_1e_minus4m", 3, 1.0, 0.01, tiny_cube, aroundCentroid(tiny_cube, kSquash));
      add("huge_1e4m", 3, 1.0, 0.01, huge_cube, aroundCentroid(huge_cube, kSquash));
      add("stretch_x100", 3, 1.0, 0.01, cube, aroundCentroid(cube, stretch));
    }
  }
  return cases;
}

/// Largest distance of `start` from the rest shape registered onto it rigidly.
double elasticDisplacement(const Points& rest, const Points& start) {
  ShapeMatchingConfig rigid;
  rigid.mode = DeformationMode::kRigid;
  ShapeMatchingBody registration(rest, rigid);
  registration.track(start);
  return registration.deformation(0).goal_deviation_bound_m;
}

class StabilityTest : public ::testing::TestWithParam<StabilityCase> {};

TEST_P(StabilityTest, StaysFiniteAndBounded) {
  const auto& c = GetParam();
  ShapeMatchingConfig config = configFor(c.mode, c.clusters);
  config.stiffness = c.stiffness;
  config.beta = 0.7;
  if (!c.damped_volume_goals) {
    config.damping = 0.0;
    config.preserve_volume = false;
  }
  ShapeMatchingBody body(c.rest, config);
  const Points start = mapped(c.rest, c.start);
  body.setPositions(start);

  const Eigen::Vector3d gravity(0.0, 0.0, -9.81);
  const double displacement = elasticDisplacement(c.rest, start);
  const double rest_radius = radiusAbout(c.rest, centroid(c.rest));
  const int steps = 300;
  // Rounding of coordinates far from the origin is the only other source of spread.
  const double rounding = 1e-9 * (1.0 + centroid(c.rest).norm());
  const double radius_limit = 3.0 * (rest_radius + displacement) + rounding;
  const double speed_limit = gravity.norm() * steps * c.dt_s + 10.0 * displacement / c.dt_s;
  double largest_radius = 0.0;
  double largest_speed = 0.0;
  for (int s = 0; s < steps; ++s) {
    body.step(c.dt_s, gravity);
    for (std::size_t i = 0; i < body.pointCount(); ++i) {
      ASSERT_TRUE(body.positions()[i].allFinite()) << "step " << s << " point " << i;
      ASSERT_TRUE(body.velocities()[i].allFinite()) << "step " << s << " point " << i;
      largest_speed = std::max(largest_speed, body.velocities()[i].norm());
    }
    largest_radius =
        std::max(largest_radius, radiusAbout(body.positions(), centroid(body.positions())));
    for (std::size_t k = 0; k < body.clusterCount(); ++k) {
      ASSERT_TRUE(body.deformation(k).transform.allFinite()) << "step " << s;
      ASSERT_TRUE(std::isfinite(body.deformation(k).goal_deviation_bound_m)) << "step " << s;
    }
  }
  EXPECT_LE(largest_radius, radius_limit) << "D = " << displacement << ", R0 = " << rest_radius;
  EXPECT_LE(largest_speed, speed_limit * (1 + 1e-9) + 1e-12) << "D = " << displacement;
  EXPECT_LE(worstBoundExcess(body), rounding * (1.0 + rest_radius));
}

INSTANTIATE_TEST_SUITE_P(Matrix, StabilityTest, ::testing::ValuesIn(stabilityCases()),
                         [](const auto& info) { return info.param.name; });

// ---------------------------------------------------------------------------------------
// Bad configuration: an exception whose message names the bad value.

struct BadConfigCase {
  const char* name;
  std::function<void(ShapeMatchingConfig&, Points&)> spoil;
  const char* message_part;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const BadConfigCase& c, std::ostream* os) { *os << c.name; }

class BadConfigTest : public ::testing::TestWithParam<BadConfigCase> {};

TEST_P(BadConfigTest, ThrowsNamingTheValue) {
  const auto& c = GetParam();
  ShapeMatchingConfig config;
  Points points = sampleBox(20, {0.1, 0.1, 0.1}, 1);
  c.spoil(config, points);
  try {
    ShapeMatchingBody body(points, config);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(c.message_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadConfigTest,
    ::testing::Values(
        BadConfigCase{"negative_mass", [](auto& c, auto&) { c.mass_kg = -2.5; }, "mass_kg = -2.5"},
        BadConfigCase{"zero_mass", [](auto& c, auto&) { c.mass_kg = 0.0; }, "mass_kg = 0"},
        BadConfigCase{"nan_mass", [](auto& c, auto&) { c.mass_kg = std::nan(""); },
                      "mass_kg = nan"},
        BadConfigCase{"stiffness_above_one", [](auto& c, auto&) { c.stiffness = 1.5; },
                      "stiffness = 1.5"},
        BadConfigCase{"stiffness_negative", [](auto& c, auto&) { c.stiffness = -0.1; },
                      "stiffness = -0.1"},
        BadConfigCase{"beta_above_one", [](auto& c, auto&) { c.beta = 2.0; }, "beta = 2"},
        BadConfigCase{"damping_negative", [](auto& c, auto&) { c.damping = -1.0; }, "damping = -1"},
        BadConfigCase{"zero_clusters", [](auto& c, auto&) { c.clusters = 0; }, "clusters = 0"},
        BadConfigCase{"more_clusters_than_points", [](auto& c, auto&) { c.clusters = 21; },
                      "clusters = 21"},
        BadConfigCase{"negative_overlap", [](auto& c, auto&) { c.cluster_overlap_ratio = -0.2; },
                      "cluster_overlap_ratio = -0.2"},
        BadConfigCase{"mode_outside_the_enum",
                      [](auto& c, auto&) { c.mode = static_cast<DeformationMode>(7); }, "mode = 7"},
        BadConfigCase{"empty_point_set", [](auto&, auto& p) { p.clear(); }, "no points"},
        BadConfigCase{"non_finite_point",
                      [](auto&, auto& p) { p[7] = Eigen::Vector3d(0, std::nan(""), 0); },
                      "rest point 7"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Step, BadTimeStepThrowsAndLeavesTheStateAlone) {
  const Points rest = sampleBox(20, {0.1, 0.1, 0.1}, 1);
  ShapeMatchingBody body(rest, ShapeMatchingConfig{});
  for (const double dt : {0.0, -0.01, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(body.step(dt, Eigen::Vector3d::Zero()), std::invalid_argument) << dt;
  }
  EXPECT_THROW(body.step(0.01, Eigen::Vector3d(0, 0, std::nan(""))), std::invalid_argument);
  EXPECT_EQ(body.positions(), rest);
}

TEST(DeformationModeNames, RoundTrip) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    EXPECT_EQ(parseDeformationMode(toString(mode)), mode);
  }
  EXPECT_FALSE(parseDeformationMode("elastic").has_value());
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
