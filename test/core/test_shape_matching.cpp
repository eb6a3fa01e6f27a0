#include "deformable_collision/core/shape_matching.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <tuple>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;
using PointMap = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

Points mapped(const Points& points, const PointMap& map) {
  Points out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(map(p));
  return out;
}

Eigen::Vector3d centroid(const Points& points) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) sum += p;
  return sum / static_cast<double>(points.size());
}

double radiusAbout(const Points& points, const Eigen::Vector3d& center) {
  double r = 0.0;
  for (const auto& p : points) r = std::max(r, (p - center).norm());
  return r;
}

ShapeMatchingConfig configFor(DeformationMode mode, int clusters) {
  ShapeMatchingConfig c;
  c.mode = mode;
  c.clusters = clusters;
  return c;
}

/// Largest |g_i - x_i| minus the cluster's bound, over all clusters: <= 0 when sound.
double worstBoundExcess(const ShapeMatchingBody& body) {
  double worst = -1.0;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto& deformation = body.deformation(k);
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Vector3d goal =
          deformation.transform * quadraticFeatures(cluster.rest_offsets[j]) +
          deformation.translation;
      const double gap = (goal - body.positions()[cluster.points[j]]).norm();
      worst = std::max(worst, gap - deformation.goal_deviation_bound_m);
    }
  }
  return worst;
}

/// RMS distance of the points from their clusters' rigidly moved rest positions.
double shapeError(const ShapeMatchingBody& body) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto& deformation = body.deformation(k);
    const Eigen::Matrix3d r = deformation.rotation.toRotationMatrix();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      sum += (body.positions()[cluster.points[j]] -
              (r * cluster.rest_offsets[j] + deformation.center_of_mass))
                 .squaredNorm();
      ++count;
    }
  }
  return std::sqrt(sum / count);
}

// ---------------------------------------------------------------------------------------
// Exact recovery: observed points that are a known transform of the rest shape are
// registered with goals equal to the observations (to 1e-9 of the object size) and, with
// one cluster, with the known matrices themselves (to 1e-9).

const Eigen::Matrix3d kRotation =
    Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).matrix();

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
        << deformation.transform << "\nexpected\n" << c.transform;
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
                     linearPart(kRotation * shearStretch())},
        RecoveryCase{"linear_four_clusters", DeformationMode::kLinear, 4,
                     linearPart(kRotation * shearStretch())},
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
                      ConservationCase{"quadratic_clusters_damped", DeformationMode::kQuadratic,
                                       4, 0.2}),
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

struct WideVectorCase {
  const char* name;
  DeformationMode mode;
  int clusters;
  std::size_t points;  ///< Not a multiple of 8: the portable code finishes each cluster.
};

void PrintTo(const WideVectorCase& c, std::ostream* os) { *os << c.name; }

using WidthAndCase = std::tuple<VectorWidth, WideVectorCase>;

class WideVectorTest : public ::testing::TestWithParam<WidthAndCase> {};

void expectSameBits(const ShapeMatchingBody& wide, const ShapeMatchingBody& portable,
                    const std::string& when) {
  ASSERT_EQ(wide.positions(), portable.positions()) << when;
  ASSERT_EQ(wide.velocities(), portable.velocities()) << when;
  for (std::size_t k = 0; k < wide.clusterCount(); ++k) {
    EXPECT_EQ(wide.deformation(k).transform, portable.deformation(k).transform) << when;
    EXPECT_EQ(wide.deformation(k).translation, portable.deformation(k).translation) << when;
    EXPECT_EQ(wide.deformation(k).goal_deviation_bound_m,
              portable.deformation(k).goal_deviation_bound_m)
        << when << ", cluster " << k;
  }
}

// The vector passes of each width (moves, sums, goals of shared points, fit residuals) give
// the same bits as the portable ones, through simulation, tracking with unobserved points,
// and responses.
TEST_P(WideVectorTest, GiveTheSameBitsAsThePortableCode) {
  const auto& [width, c] = GetParam();
  if (widestVectors() < width) GTEST_SKIP() << "this CPU has not these vectors";
  ShapeMatchingConfig config = configFor(c.mode, c.clusters);
  config.stiffness = 0.7;
  const Points rest = sampleEllipsoid(c.points, {0.3, 0.2, 0.15}, 21);
  ShapeMatchingBody wide(rest, config, width);
  ShapeMatchingBody portable(rest, config, VectorWidth::kPortable);
  ASSERT_EQ(wide.vectorWidth(), width);
  ASSERT_EQ(portable.vectorWidth(), VectorWidth::kPortable);
  const Points bent = mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return kRotation * Eigen::Vector3d(p.x() + 2.0 * p.y() * p.y(), 1.3 * p.y(), 0.8 * p.z());
  });
  wide.setPositions(bent);
  portable.setPositions(bent);
  // A spin, so that the damping's rigid velocity depends on every moment of the sums.
  const Points spinning = mapped(bent, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return Eigen::Vector3d(0.3, -2.0, 1.1).cross(p);
  });
  wide.setVelocities(spinning);
  portable.setVelocities(spinning);
  expectSameBits(wide, portable, "placed");
  ASSERT_GT(wide.deformation(0).goal_deviation_bound_m, 0.0) << "a residual to compare";
  for (int s = 0; s < 20; ++s) {
    wide.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
    portable.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
    expectSameBits(wide, portable, "step " + std::to_string(s));
  }
  std::vector<PointDisplacement> kicks;
  for (std::uint32_t i = 0; i < rest.size(); i += 5) {
    kicks.push_back({i, Eigen::Vector3d(0.0, 0.0, 1e-3), Eigen::Vector3d(0.0, 0.1, 0.0)});
  }
  wide.displacePoints(kicks);
  portable.displacePoints(kicks);
  wide.step(0.01, Eigen::Vector3d::Zero());
  portable.step(0.01, Eigen::Vector3d::Zero());
  expectSameBits(wide, portable, "after a response");
  Points observed = bent;
  for (std::size_t i = 0; i < observed.size(); i += 9) {
    observed[i].y() = std::numeric_limits<double>::quiet_NaN();
  }
  wide.track(observed);
  portable.track(observed);
  expectSameBits(wide, portable, "tracked");
}

INSTANTIATE_TEST_SUITE_P(
    Modes, WideVectorTest,
    ::testing::Combine(
        ::testing::Values(VectorWidth::kAvx2, VectorWidth::kAvx512),
        ::testing::Values(
            WideVectorCase{"rigid_one_cluster", DeformationMode::kRigid, 1, 203},
            WideVectorCase{"linear_shared_seams", DeformationMode::kLinear, 4, 701},
            WideVectorCase{"quadratic_shared_seams", DeformationMode::kQuadratic, 3, 517},
            WideVectorCase{"fewer_points_than_a_vector", DeformationMode::kQuadratic, 2, 13})),
    [](const ::testing::TestParamInfo<WidthAndCase>& info) {
      return std::string(std::get<0>(info.param) == VectorWidth::kAvx2 ? "avx2_" : "avx512_") +
             std::get<1>(info.param).name;
    });

// A move deferred to the next step gives the bits of the same move made at once, at every
// vector width (the AVX-512 step makes it before its pass), damped or not, with shared
// points, for each part of the move left out; reading the points before the step makes it
// there and then.

struct DeferredMoveCase {
  const char* name;
  DeformationMode mode;
  int clusters;
  double damping;
  Eigen::Vector3d offset;
  Eigen::Vector3d change;
};

void PrintTo(const DeferredMoveCase& c, std::ostream* os) { *os << c.name; }

using WidthAndMove = std::tuple<VectorWidth, DeferredMoveCase>;

class DeferredMoveTest : public ::testing::TestWithParam<WidthAndMove> {};

TEST_P(DeferredMoveTest, GivesTheBitsOfTheMoveMadeAtOnce) {
  const auto& [width, c] = GetParam();
  if (widestVectors() < width) GTEST_SKIP() << "this CPU has not these vectors";
  ShapeMatchingConfig config = configFor(c.mode, c.clusters);
  config.stiffness = 0.6;
  config.damping = c.damping;
  const Points rest = sampleEllipsoid(517, {0.3, 0.2, 0.15}, 31);
  ShapeMatchingBody at_once(rest, config, width);
  const Points spinning = mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return Eigen::Vector3d(0.3, -2.0, 1.1).cross(p);
  });
  at_once.setVelocities(spinning);
  for (int s = 0; s < 3; ++s) at_once.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
  ShapeMatchingBody deferred = at_once;
  ShapeMatchingBody read_early = at_once;

  at_once.moveRigidly(c.offset, c.change);
  deferred.deferRigidMove(c.offset, c.change);
  read_early.deferRigidMove(c.offset, c.change);
  const Eigen::Vector3d mean = deferred.meanPosition();
  Eigen::Vector3d expected_mean = Eigen::Vector3d::Zero();
  for (const auto& p : at_once.positions()) expected_mean += p;
  expected_mean /= static_cast<double>(rest.size());
  EXPECT_EQ(mean, expected_mean);
  expectSameBits(read_early, at_once, "read before the step");
  for (int s = 0; s < 3; ++s) {
    at_once.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
    deferred.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
    read_early.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
    expectSameBits(deferred, at_once, "step " + std::to_string(s));
    expectSameBits(read_early, at_once, "read early, step " + std::to_string(s));
    // Two deferred moves without a step between them are made in turn.
    at_once.moveRigidly(c.offset, c.change);
    at_once.moveRigidly(-c.offset, c.change);
    deferred.deferRigidMove(c.offset, c.change);
    deferred.deferRigidMove(-c.offset, c.change);
    read_early.moveRigidly(c.offset, c.change);
    read_early.deferRigidMove(-c.offset, c.change);
  }
  EXPECT_THROW(deferred.deferRigidMove(Eigen::Vector3d(std::nan(""), 0, 0), c.change),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(
    WidthsAndMoves, DeferredMoveTest,
    ::testing::Combine(
        ::testing::Values(VectorWidth::kPortable, VectorWidth::kAvx2, VectorWidth::kAvx512),
        ::testing::Values(
            DeferredMoveCase{"rigid_damped", DeformationMode::kRigid, 1, 0.2, {0.02, -0.01, 0.03},
                             {0.1, 0.2, -0.3}},
            DeferredMoveCase{"linear_shared_undamped", DeformationMode::kLinear, 4, 0.0,
                             {-1e-3, 2e-3, 5e-4}, {0.0, 0.0, -0.05}},
            DeferredMoveCase{"quadratic_shared_damped", DeformationMode::kQuadratic, 3, 0.1,
                             {0.3, 0.0, -0.2}, {1.5, -2.0, 0.25}},
            DeferredMoveCase{"offset_only", DeformationMode::kLinear, 2, 0.1, {0.02, -0.01, 0.0},
                             {0.0, 0.0, 0.0}},
            DeferredMoveCase{"velocity_only", DeformationMode::kQuadratic, 2, 0.0,
                             {0.0, 0.0, 0.0}, {0.1, 0.0, -0.3}})),
    [](const ::testing::TestParamInfo<WidthAndMove>& info) {
      const VectorWidth width = std::get<0>(info.param);
      return std::string(width == VectorWidth::kPortable ? "portable_"
                         : width == VectorWidth::kAvx2   ? "avx2_"
                                                         : "avx512_") +
             std::get<1>(info.param).name;
    });

// ---------------------------------------------------------------------------------------
// Collision responses move points; the fit follows and the bound stays sound.

TEST(DisplacePoints, BoundStaysSoundAndMomentumFollowsTheKicks) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    ShapeMatchingBody body(sampleEllipsoid(800, {0.4, 0.3, 0.2}, 40), configFor(mode, 3));
    std::mt19937_64 engine(41);
    std::normal_distribution<double> push(0.0, 0.01);
    std::uniform_int_distribution<std::uint32_t> pick(0, 799);
    const double dt = 0.01;
    for (int round = 0; round < 20; ++round) {
      body.step(dt, Eigen::Vector3d(0, 0, -9.81));
      std::vector<PointDisplacement> kicks;
      Eigen::Vector3d expected_momentum = Eigen::Vector3d::Zero();
      for (const auto& v : body.velocities()) expected_momentum += body.pointMassKg() * v;
      for (int i = 0; i < 50; ++i) {
        const Eigen::Vector3d shift(push(engine), push(engine), push(engine));
        kicks.push_back({pick(engine), shift, shift / dt});
        expected_momentum += body.pointMassKg() * kicks.back().velocity_change_mps;
      }
      body.displacePoints(kicks);
      ASSERT_LE(worstBoundExcess(body), 1e-12) << toString(mode) << " round " << round;
      Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
      for (const auto& v : body.velocities()) momentum += body.pointMassKg() * v;
      EXPECT_LT((momentum - expected_momentum).norm(), 1e-9) << toString(mode);
    }
    for (int s = 0; s < 100; ++s) body.step(dt, Eigen::Vector3d::Zero());
    for (const auto& x : body.positions()) ASSERT_TRUE(x.allFinite());
  }
}

TEST(DisplacePoints, RefitThatMovesUndisplacedPointsIsBounded) {
  // A least-squares refit can move an undisplaced, high-leverage point farther than any
  // displacement: 400 points in a small ball kinked by +-delta, and one point far out on
  // the kink's axis, which the refitted shear carries about 8 delta.
  Points rest = sampleEllipsoid(400, {0.05, 0.05, 0.05}, 42);
  rest.emplace_back(0.45, 0.0, 0.0);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kLinear, 1));
  const double delta = 1e-3;
  std::vector<PointDisplacement> kink;
  for (std::uint32_t i = 0; i < 400; ++i) {
    kink.push_back({i, Eigen::Vector3d(0.0, 0.0, rest[i].x() > 0 ? delta : -delta),
                    Eigen::Vector3d::Zero()});
  }
  body.displacePoints(kink);
  const auto& deformation = body.deformation(0);
  const Eigen::Vector3d outlier_goal =
      deformation.transform * quadraticFeatures(body.cluster(0).rest_offsets.back()) +
      deformation.translation;
  ASSERT_GT((outlier_goal - rest.back()).norm(), 3 * delta) << "the scene must make the refit reach";
  EXPECT_LE(worstBoundExcess(body), 1e-12);
}

TEST(DisplacePoints, IncrementalSumsMatchTheSumsOfTheMovedPoints) {
  // The sums that displacePoints updates per point feed the fit (offsets and features) and
  // the damping (momentum, spin, second moment). A copy that sums its points afresh must
  // fit the same transforms and take the same next step.
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    ShapeMatchingConfig config = configFor(mode, 3);
    config.damping = 0.2;
    ShapeMatchingBody body(sampleEllipsoid(600, {0.4, 0.3, 0.2}, 43), config);
    std::vector<Eigen::Vector3d> spin(body.pointCount());
    for (std::size_t i = 0; i < spin.size(); ++i) {
      spin[i] = Eigen::Vector3d(0.5, -1.0, 2.0).cross(body.positions()[i]) + Eigen::Vector3d(0.3, 0, 0);
    }
    body.setVelocities(spin);
    for (int s = 0; s < 5; ++s) body.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    std::mt19937_64 engine(44);
    std::normal_distribution<double> push(0.0, 0.01);
    std::uniform_int_distribution<std::uint32_t> pick(0, 599);
    // Runs of points with one displacement, as a dented node's points come, and single ones.
    std::vector<PointDisplacement> kicks;
    for (int run = 0; run < 40; ++run) {
      const Eigen::Vector3d shift(push(engine), push(engine), push(engine));
      for (int i = 0; i < 1 + run % 7; ++i) {
        kicks.push_back({pick(engine), shift,
                         Eigen::Vector3d(push(engine), push(engine), push(engine)) / 0.01});
      }
    }
    body.displacePoints(kicks);

    ShapeMatchingBody fresh = body;
    fresh.setPositions(body.positions());
    fresh.setVelocities(body.velocities());
    for (std::size_t k = 0; k < body.clusterCount(); ++k) {
      EXPECT_LT((fresh.deformation(k).center_of_mass - body.deformation(k).center_of_mass).norm(), 1e-12)
          << toString(mode) << " cluster " << k;
      EXPECT_LT((fresh.deformation(k).transform - body.deformation(k).transform).norm(), 1e-9)
          << toString(mode) << " cluster " << k;
    }
    body.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    fresh.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    double worst = 0.0;
    for (std::size_t i = 0; i < body.pointCount(); ++i) {
      worst = std::max(worst, (body.positions()[i] - fresh.positions()[i]).norm());
    }
    EXPECT_LT(worst, 1e-10) << toString(mode);
  }
}

TEST(DisplacePoints, BadInputThrowsAndLeavesTheStateAlone) {
  ShapeMatchingBody body(sampleBox(30, {0.1, 0.1, 0.1}, 2), ShapeMatchingConfig{});
  const Points before = body.positions();
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  EXPECT_THROW(body.displacePoints({{3, Eigen::Vector3d(0.1, 0, 0), zero}, {30, zero, zero}}),
               std::invalid_argument);
  EXPECT_THROW(body.displacePoints({{3, Eigen::Vector3d(std::nan(""), 0, 0), zero}}),
               std::invalid_argument);
  EXPECT_THROW(body.displacePoints({{3, zero, Eigen::Vector3d(0, std::nan(""), 0)}}),
               std::invalid_argument);
  EXPECT_EQ(body.positions(), before);
}

TEST(DisplacePoints, PointListedTwiceMovesByTheSumAndTheBoundFollows) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    SCOPED_TRACE(toString(mode));
    ShapeMatchingBody listed(sampleEllipsoid(600, {0.4, 0.3, 0.2}, 45), configFor(mode, 2));
    for (int s = 0; s < 3; ++s) listed.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    ShapeMatchingBody merged = listed;
    const Cluster& first = listed.cluster(0);
    ASSERT_LT(first.exclusive_count, first.points.size()) << "a point both clusters hold";
    const std::uint32_t shared = first.points[first.exclusive_count];
    const Eigen::Vector3d dx1(0.0, 0.0, 0.01), dx2(0.003, 0.0, 0.01), dx3(0.0, -0.002, 0.0);
    const Eigen::Vector3d dv1(0.0, 0.0, 1.0), dv2(0.5, 0.0, 0.0), dv3(0.0, 0.2, 0.0);
    listed.displacePoints({{shared, dx1, dv1}, {7, dx3, dv3}, {shared, dx2, dv2}});
    merged.displacePoints({{shared, dx1 + dx2, dv1 + dv2}, {7, dx3, dv3}});
    EXPECT_LE(worstBoundExcess(listed), 1e-12);
    EXPECT_TRUE(listed.positions() == merged.positions());
    EXPECT_TRUE(listed.velocities() == merged.velocities());
    for (std::size_t k = 0; k < listed.clusterCount(); ++k) {
      const ClusterDeformation& once = merged.deformation(k);
      EXPECT_EQ(listed.deformation(k).transform, once.transform) << "cluster " << k;
      EXPECT_EQ(listed.deformation(k).translation, once.translation) << "cluster " << k;
      EXPECT_EQ(listed.deformation(k).goal_deviation_bound_m, once.goal_deviation_bound_m)
          << "cluster " << k;
    }
  }
}

// A body straddling x = 2^16 m: a change of 0.4 or 0.6 ulp there rounds one way for the
// points below and another for those above, so the points drift from the fit by rounding
// alone. 1e-10 m leaves room for the rounding of the test's own goals at 2^16 m.
constexpr double kUlpAt65536 = 1.0 / (1ULL << 36);

ShapeMatchingBody bodyAcross65536(DeformationMode mode) {
  const Points rest = sampleEllipsoid(300, {0.4, 0.25, 0.15}, 17);
  ShapeMatchingBody body(rest, configFor(mode, 2));
  body.setPositions(mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return p + Eigen::Vector3d(65536.0, 0, 0);
  }));
  return body;
}

TEST(DisplacePoints, BoundCoversTheRoundingOfManyCallsFarFromTheOrigin) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    SCOPED_TRACE(toString(mode));
    ShapeMatchingBody body = bodyAcross65536(mode);
    std::vector<PointDisplacement> nudges;
    for (std::uint32_t i = 0; i < body.pointCount(); ++i) {
      nudges.push_back({i, Eigen::Vector3d(0.4 * kUlpAt65536, 0, 0), Eigen::Vector3d::Zero()});
    }
    for (int call = 0; call < 3000; ++call) body.displacePoints(nudges);
    EXPECT_LE(worstBoundExcess(body), 1e-10);
  }
}

TEST(MoveRigidly, BoundCoversTheRoundingOfManyMovesFarFromTheOrigin) {
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    SCOPED_TRACE(toString(mode));
    ShapeMatchingBody body = bodyAcross65536(mode);
    for (int move = 0; move < 3000; ++move) {
      body.moveRigidly(Eigen::Vector3d(0.6 * kUlpAt65536, 0, 0), Eigen::Vector3d::Zero());
    }
    EXPECT_LE(worstBoundExcess(body), 1e-10);
    // Sound, and still at the scale of the rounding: micrometres after 3000 moves.
    for (std::size_t k = 0; k < body.clusterCount(); ++k) {
      EXPECT_LT(body.deformation(k).goal_deviation_bound_m, 1e-5) << "cluster " << k;
    }
  }
}

TEST(MoveRigidly, EveryPointTakesTheSameOffsetAndVelocityChange) {
  // Without a turn the points are moved as a flat array of coordinates, two points at a
  // time: every count, odd ones with a last point alone too, must move each point exactly
  // as adding the offset to it would, and a zero offset or change must leave the points.
  struct MoveCase {
    const char* name;
    std::size_t points;
    Eigen::Vector3d offset;
    Eigen::Vector3d change;
  };
  const std::vector<MoveCase> cases = {
      {"one_point", 1, {0.02, -0.01, 0.03}, {0.1, 0.2, -0.3}},
      {"two_points", 2, {0.02, -0.01, 0.03}, {0.1, 0.2, -0.3}},
      {"five_points", 5, {-1e-3, 2e-3, 7e-4}, {0.0, 0.0, -0.05}},
      {"odd_hundreds", 601, {0.3, 0.0, -0.2}, {1.5, -2.0, 0.25}},
      {"far_from_the_origin", 64, {1e5, -1e5, 3e4}, {0.1, 0.2, -0.3}},
      {"no_offset", 9, {0.0, 0.0, 0.0}, {0.1, 0.2, -0.3}},
      {"no_velocity_change", 9, {0.02, -0.01, 0.03}, {0.0, 0.0, 0.0}},
  };
  for (const MoveCase& c : cases) {
    SCOPED_TRACE(c.name);
    ShapeMatchingBody body(sampleBox(c.points, {0.3, 0.2, 0.1}, 11),
                           configFor(DeformationMode::kLinear, 1));
    Points velocities;
    for (const auto& p : body.positions()) velocities.push_back(Eigen::Vector3d(0.5, -1.0, 2.0).cross(p));
    body.setVelocities(velocities);
    const Points positions = body.positions();
    body.moveRigidly(c.offset, c.change);
    ASSERT_EQ(body.pointCount(), c.points);
    for (std::size_t i = 0; i < c.points; ++i) {
      for (int r = 0; r < 3; ++r) {
        EXPECT_EQ(body.positions()[i][r], positions[i][r] + c.offset[r]) << "point " << i;
        EXPECT_EQ(body.velocities()[i][r], velocities[i][r] + c.change[r]) << "point " << i;
      }
    }
  }
}

TEST(MoveRigidly, TurnMovesThePointsVelocitiesAndTheSumsFollow) {
  // The sums that moveRigidly updates without visiting the points feed the damping and
  // rigidMotion: a copy that sums its points afresh must report the same motion and take
  // the same next step.
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    SCOPED_TRACE(toString(mode));
    ShapeMatchingConfig config = configFor(mode, 3);
    config.damping = 0.2;
    ShapeMatchingBody body(sampleEllipsoid(600, {0.4, 0.3, 0.2}, 47), config);
    Points velocities;
    for (const auto& p : body.positions()) {
      velocities.push_back(Eigen::Vector3d(0.5, -1.0, 2.0).cross(p));
    }
    body.setVelocities(velocities);
    for (int s = 0; s < 5; ++s) body.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    const Points before = body.velocities();
    const Eigen::Vector3d offset(0.02, -0.01, 0.03);
    const Eigen::Vector3d change(0.1, 0.2, -0.3);
    const Eigen::Vector3d turn(-0.7, 0.4, 1.5);
    const Eigen::Vector3d center =
        centroid(body.positions()) + offset + Eigen::Vector3d(0.05, 0.0, 0.0);
    body.moveRigidly(offset, change, turn, center);
    double worst_velocity = 0.0;
    for (std::size_t i = 0; i < body.pointCount(); ++i) {
      const Eigen::Vector3d expected =
          before[i] + change + turn.cross(body.positions()[i] - center);
      worst_velocity = std::max(worst_velocity, (body.velocities()[i] - expected).norm());
    }
    EXPECT_LT(worst_velocity, 1e-12);

    ShapeMatchingBody fresh = body;
    fresh.setPositions(body.positions());
    fresh.setVelocities(body.velocities());
    const RigidMotion moved = body.rigidMotion();
    const RigidMotion summed = fresh.rigidMotion();
    EXPECT_LT((moved.center - summed.center).norm(), 1e-12);
    EXPECT_LT((moved.velocity - summed.velocity).norm(), 1e-12);
    EXPECT_LT((moved.spin - summed.spin).norm(), 1e-10);
    EXPECT_LT((moved.inertia - summed.inertia).norm(), 1e-12);
    body.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    fresh.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    double worst = 0.0;
    for (std::size_t i = 0; i < body.pointCount(); ++i) {
      worst = std::max(worst, (body.positions()[i] - fresh.positions()[i]).norm());
    }
    EXPECT_LT(worst, 1e-10);
  }
}

TEST(RigidMotion, IsTheMotionOfTheWholeObject) {
  const Points rest = sampleBox(500, {0.3, 0.2, 0.1}, 5);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kQuadratic, 3));
  const Eigen::Vector3d center = centroid(rest);
  const Eigen::Vector3d spin(0.3, -0.2, 1.0);
  const Eigen::Vector3d velocity(1.0, 0.0, -2.0);
  Points velocities;
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  for (const auto& p : rest) {
    velocities.push_back(velocity + spin.cross(p - center));
    const Eigen::Vector3d arm = p - center;
    inertia += body.pointMassKg() *
               (arm.squaredNorm() * Eigen::Matrix3d::Identity() - arm * arm.transpose());
  }
  body.setVelocities(velocities);
  const RigidMotion motion = body.rigidMotion();
  EXPECT_LT((motion.center - center).norm(), 1e-12);
  EXPECT_LT((motion.velocity - velocity).norm(), 1e-12);
  EXPECT_LT((motion.spin - spin).norm(), 1e-10);
  EXPECT_LT((motion.inertia - inertia).norm(), 1e-12 * inertia.norm());
}

struct CenterOfMassCase {
  std::string name;
  DeformationMode mode;
  Eigen::Vector3d origin;
};

class CenterOfMassTest : public ::testing::TestWithParam<CenterOfMassCase> {};

// The scene sees a new contact's side from the centre of mass, taken from the clusters'
// centres: it must follow every way the points move, to rounding.
TEST_P(CenterOfMassTest, IsTheMeanOfThePointsAfterEveryKindOfMove) {
  const CenterOfMassCase& c = GetParam();
  ShapeMatchingConfig config = configFor(c.mode, 4);
  config.damping = 0.1;
  const Points rest = mapped(sampleEllipsoid(400, {0.3, 0.2, 0.1}, 61),
                             [&](const Eigen::Vector3d& p) -> Eigen::Vector3d { return c.origin + p; });
  ShapeMatchingBody body(rest, config);
  const double tolerance = 1e-12 * (1.0 + c.origin.norm());
  const auto expectMean = [&](const std::string& after) {
    EXPECT_LT((body.centerOfMass() - body.meanPosition()).norm(), tolerance)
        << c.name << ", after " << after;
  };
  expectMean("construction");
  body.setVelocities(mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return Eigen::Vector3d(0.4, -1.0, 2.0).cross(p - c.origin) + Eigen::Vector3d(0.5, 0.0, 0.1);
  }));
  for (int s = 0; s < 5; ++s) body.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
  expectMean("steps");
  body.moveRigidly({0.01, -0.02, 0.005}, {0.1, 0.0, 0.0}, {0.0, 1.0, 0.5}, body.centerOfMass());
  expectMean("a turn");
  body.deferRigidMove({-0.003, 0.004, 0.02}, {0.0, 0.2, 0.0});
  expectMean("a deferred move");
  std::vector<PointDisplacement> dents;
  for (std::uint32_t i = 0; i < 400; i += 7) {
    dents.push_back({i, Eigen::Vector3d(0.0, 0.0, 0.002 * (i % 5)), Eigen::Vector3d::Zero()});
  }
  body.displacePoints(dents);
  expectMean("dents");
  body.step(0.01, Eigen::Vector3d(0.0, 0.0, -9.81));
  expectMean("a step after dents");
  body.track(mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    const Eigen::Vector3d arm = p - c.origin;
    return c.origin + Eigen::Vector3d(1.1 * arm.x(), arm.y(), 0.9 * arm.z() + 0.05);
  }));
  expectMean("a tracked cloud");
  body.setPositions(rest);
  expectMean("placed at rest");
}

INSTANTIATE_TEST_SUITE_P(
    ModesNearAndFarFromTheOrigin, CenterOfMassTest,
    ::testing::Values(
        CenterOfMassCase{"Rigid", DeformationMode::kRigid, Eigen::Vector3d::Zero()},
        CenterOfMassCase{"Linear", DeformationMode::kLinear, Eigen::Vector3d::Zero()},
        CenterOfMassCase{"Quadratic", DeformationMode::kQuadratic, Eigen::Vector3d::Zero()},
        CenterOfMassCase{"QuadraticFarOut", DeformationMode::kQuadratic,
                         Eigen::Vector3d(1e5, -2e4, 3e3)}),
    [](const auto& info) { return info.param.name; });

TEST(SetVelocities, SpinIsKeptByTheDampingAndMomentumConserved) {
  ShapeMatchingConfig config = configFor(DeformationMode::kLinear, 2);
  config.damping = 0.5;
  const Points rest = sampleBox(500, {0.3, 0.2, 0.1}, 3);
  ShapeMatchingBody body(rest, config);
  const Eigen::Vector3d spin(0.0, 0.0, 2.0);
  const Eigen::Vector3d center = centroid(rest);
  Points velocities;
  for (const auto& p : rest) velocities.push_back(spin.cross(p - center));
  body.setVelocities(velocities);
  for (int s = 0; s < 50; ++s) body.step(0.01, Eigen::Vector3d::Zero());
  // A rigid spin is no deformation: heavy damping must leave it (and its energy) alone.
  Eigen::Vector3d angular = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < body.pointCount(); ++i) {
    angular += body.pointMassKg() * (body.positions()[i] - centroid(body.positions()))
                                        .cross(body.velocities()[i]);
  }
  Eigen::Vector3d initial = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < rest.size(); ++i) {
    initial += body.pointMassKg() * (rest[i] - center).cross(velocities[i]);
  }
  EXPECT_LT((angular - initial).norm(), 1e-9 * initial.norm());
  EXPECT_LT(shapeError(body), 1e-3);
  EXPECT_THROW(body.setVelocities(Points(499, Eigen::Vector3d::Zero())), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Tracking with unobserved points.

TEST(Track, UnobservedPointsFollowTheFit) {
  const Points rest = sampleBox(400, {0.3, 0.3, 0.3}, 13);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kLinear, 2));
  Points observed = mapped(rest, [](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return kRotation * p + Eigen::Vector3d(1, 2, 3);
  });
  const Points truth = observed;
  for (std::size_t i = 0; i < observed.size(); i += 7) {
    observed[i].x() = std::numeric_limits<double>::quiet_NaN();
  }
  EXPECT_EQ(body.track(observed), (observed.size() + 6) / 7);
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_LT((body.positions()[i] - truth[i]).norm(), 1e-9) << "point " << i;
  }
}

struct MotionCase {
  const char* name;
  std::function<void(ShapeMatchingBody&)> move;
};

TEST(Track, StopsThePointsWhateverMovedThemSinceTheLastRegistration) {
  const MotionCase cases[] = {
      {"step", [](ShapeMatchingBody& b) { b.step(0.01, Eigen::Vector3d(0, 0, -9.81)); }},
      {"move_rigidly", [](ShapeMatchingBody& b) { b.moveRigidly({0.01, 0, 0}, {0.5, 0, 0}); }},
      {"turn",
       [](ShapeMatchingBody& b) {
         b.moveRigidly({0, 0, 0}, {0, 0, 0}, {0, 0, 2.0}, Eigen::Vector3d::Zero());
       }},
      {"displace_points",
       [](ShapeMatchingBody& b) { b.displacePoints({{3, {0.001, 0, 0}, {0.2, 0, 0}}}); }},
      {"set_velocities",
       [](ShapeMatchingBody& b) { b.setVelocities(Points(b.positions().size(), {0, 0.3, 0})); }},
  };
  const Points rest = sampleBox(120, {0.3, 0.2, 0.1}, 21);
  for (const MotionCase& c : cases) {
    ShapeMatchingBody body(rest, configFor(DeformationMode::kQuadratic, 2));
    body.track(rest);
    c.move(body);
    const bool moving = std::any_of(body.velocities().begin(), body.velocities().end(),
                                    [](const Eigen::Vector3d& v) { return !v.isZero(0.0); });
    ASSERT_TRUE(moving) << c.name << " moved no point: the case tests nothing";
    body.track(body.positions());
    for (std::size_t i = 0; i < body.velocities().size(); ++i) {
      ASSERT_TRUE(body.velocities()[i].isZero(0.0)) << c.name << ", point " << i;
    }
    EXPECT_TRUE(body.meanVelocity().isZero(0.0)) << c.name;
  }
}

TEST(Track, SwappingInACloudGivesTheSameBitsAsCopyingIt) {
  const Points rest = sampleBox(300, {0.3, 0.2, 0.1}, 22);
  for (const bool holes : {false, true}) {
    ShapeMatchingBody copied(rest, configFor(DeformationMode::kQuadratic, 3));
    ShapeMatchingBody swapped(rest, configFor(DeformationMode::kQuadratic, 3));
    for (int frame = 1; frame <= 3; ++frame) {
      Points cloud = mapped(rest, [frame](const Eigen::Vector3d& p) -> Eigen::Vector3d {
        return kRotation * p + Eigen::Vector3d(0.01 * frame, 0, 0.02 * p.x() * p.x());
      });
      if (holes) cloud[5 * frame].setConstant(std::numeric_limits<double>::quiet_NaN());
      const Points sent = cloud;
      const Points previous = swapped.positions();
      const std::size_t unobserved = copied.track(sent);
      ASSERT_EQ(swapped.trackSwapping(cloud), unobserved);
      const std::string when = std::string(holes ? "with holes" : "whole") + ", frame " +
                               std::to_string(frame);
      ASSERT_EQ(swapped.positions(), copied.positions()) << when;
      for (std::size_t k = 0; k < copied.clusterCount(); ++k) {
        ASSERT_EQ(swapped.deformation(k).transform, copied.deformation(k).transform) << when;
        ASSERT_EQ(swapped.deformation(k).goal_deviation_bound_m,
                  copied.deformation(k).goal_deviation_bound_m)
            << when;
      }
      // A cloud with holes is copied and left as sent; a whole one gets the old positions.
      if (!holes) {
        ASSERT_EQ(cloud, previous) << when;
        continue;
      }
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        ASSERT_TRUE(cloud[i] == sent[i] || (cloud[i].hasNaN() && sent[i].hasNaN()))
            << when << ", point " << i;
      }
    }
  }
  ShapeMatchingBody body(rest, configFor(DeformationMode::kLinear, 1));
  Points short_cloud(rest.size() - 1, Eigen::Vector3d::Zero());
  EXPECT_THROW(body.trackSwapping(short_cloud), std::invalid_argument);
  EXPECT_EQ(short_cloud.size(), rest.size() - 1);
  EXPECT_EQ(body.positions(), rest);
}

TEST(Track, WrongSizeThrowsAndLeavesTheStateAlone) {
  const Points rest = sampleBox(50, {0.3, 0.3, 0.3}, 14);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kLinear, 1));
  EXPECT_THROW(body.track(Points(49, Eigen::Vector3d::Zero())), std::invalid_argument);
  EXPECT_EQ(body.positions(), rest);
}

// A TrackedFitter is a copy of its object's body: the copy holds the body's state, not a
// second rest shape.
TEST(Track, ACopySharesTheRestShapeAndTracksOnItsOwn) {
  const Points rest = sampleBox(80, {0.3, 0.3, 0.3}, 17);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kQuadratic, 3));
  ShapeMatchingBody copy = body;
  EXPECT_EQ(copy.restPositions().data(), body.restPositions().data());
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    EXPECT_EQ(copy.cluster(k).points.data(), body.cluster(k).points.data());
    EXPECT_EQ(copy.cluster(k).rest_offsets.data(), body.cluster(k).rest_offsets.data());
  }
  EXPECT_NE(copy.positions().data(), body.positions().data());
  Points moved = rest;
  for (auto& p : moved) p.x() += 0.2;
  copy.track(moved);
  EXPECT_EQ(body.positions(), rest);
  EXPECT_EQ(copy.positions(), moved);
  EXPECT_EQ(copy.restPositions(), rest);
}

TEST(Track, ATrackedStateOfAnotherSizeThrowsAndLeavesBothAlone) {
  const Points rest = sampleBox(50, {0.3, 0.3, 0.3}, 15);
  ShapeMatchingBody body(rest, configFor(DeformationMode::kLinear, 2));
  ShapeMatchingBody other(sampleBox(60, {0.3, 0.3, 0.3}, 16), configFor(DeformationMode::kLinear, 2));
  Points positions = other.positions();
  TrackedState state;
  state.deformations = {other.deformation(0), other.deformation(1)};
  state.sums.resize(2);
  EXPECT_THROW(body.takeTrackedState(positions, state), std::invalid_argument);
  positions.resize(rest.size());
  state.deformations.pop_back();
  EXPECT_THROW(body.takeTrackedState(positions, state), std::invalid_argument);
  EXPECT_EQ(body.positions(), rest);
  EXPECT_EQ(positions.size(), rest.size());
  EXPECT_EQ(state.deformations.size(), 1u);
}

// ---------------------------------------------------------------------------------------
// Recovery from absurd but finite input: a cloud with 1% of its points at 1e100 or 1e200 m,
// a step at 1e30 or 1e200 m/s. The next valid input must give the state a fresh body given
// the same input has, to rounding (1e-12 m on a 1 m body), and the same trajectory after it:
// nothing of the absurd state carries.

struct AbsurdInputCase {
  std::string name;
  DeformationMode mode;
  int clusters;
  double magnitude;  ///< Of the absurd coordinates (m) or velocities (m/s).
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const AbsurdInputCase& c, std::ostream* os) { *os << c.name; }

std::vector<AbsurdInputCase> absurdInputCases(const std::vector<double>& magnitudes) {
  std::vector<AbsurdInputCase> cases;
  for (const auto mode :
       {DeformationMode::kRigid, DeformationMode::kLinear, DeformationMode::kQuadratic}) {
    for (const int clusters : {1, 4}) {
      for (const double magnitude : magnitudes) {
        const std::string exponent = std::to_string(static_cast<int>(std::log10(magnitude)));
        cases.push_back({std::string(toString(mode)) + "_" + std::to_string(clusters) +
                             "_clusters_1e" + exponent,
                         mode, clusters, magnitude});
      }
    }
  }
  return cases;
}

/// Every point, velocity and per-cluster output of `body` equals that of `fresh` within
/// `tolerance_m` (lengths; the transforms, which are dimensionless, within tolerance_m / size).
void expectSameState(const ShapeMatchingBody& body, const ShapeMatchingBody& fresh,
                     double tolerance_m, double size_m, const std::string& when) {
  for (std::size_t i = 0; i < body.pointCount(); ++i) {
    ASSERT_LE((body.positions()[i] - fresh.positions()[i]).norm(), tolerance_m)
        << when << ": point " << i << " at " << body.positions()[i].transpose() << ", fresh at "
        << fresh.positions()[i].transpose();
    ASSERT_LE((body.velocities()[i] - fresh.velocities()[i]).norm(), tolerance_m)
        << when << ": velocity of point " << i;
  }
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const ClusterDeformation& a = body.deformation(k);
    const ClusterDeformation& b = fresh.deformation(k);
    EXPECT_LE((a.center_of_mass - b.center_of_mass).norm(), tolerance_m) << when << ", cluster " << k;
    EXPECT_LE((a.translation - b.translation).norm(), tolerance_m) << when << ", cluster " << k;
    EXPECT_LE((a.transform - b.transform).norm() * size_m, tolerance_m) << when << ", cluster " << k;
    EXPECT_LE((a.rotation.toRotationMatrix() - b.rotation.toRotationMatrix()).norm() * size_m,
              tolerance_m)
        << when << ", cluster " << k;
    EXPECT_LE(std::abs(a.goal_deviation_bound_m - b.goal_deviation_bound_m), tolerance_m)
        << when << ", cluster " << k << ": residual " << a.goal_deviation_bound_m << ", fresh "
        << b.goal_deviation_bound_m;
  }
}

/// The rest shape seen turned, bent a little and moved, as a tracked object is.
Points observedPose(const Points& rest, double shift_m) {
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  return mapped(rest, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return turn * Eigen::Vector3d(p.x(), p.y() + 0.2 * p.x() * p.x(), p.z()) +
           Eigen::Vector3d(1.5 + shift_m, -0.4, 0.8);
  });
}

/// `points` with 1% of them (every 100th from 3, which every 7th meets at 203) moved to
/// +-`magnitude` along one axis.
Points withPointsFarOut(Points points, double magnitude) {
  for (std::size_t i = 3; i < points.size(); i += 100) {
    points[i][i % 3] = (i % 2 == 0 ? 1.0 : -1.0) * magnitude;
  }
  return points;
}

class AbsurdInputTest : public ::testing::TestWithParam<AbsurdInputCase> {
 protected:
  static constexpr double kSizeM = 0.5;  ///< Largest half extent of the rest box.
  /// To rounding: a damaged cluster starts afresh from a fresh body's state, but a cluster
  /// the absurd input left intact carries on about its own centre of mass, which a compiler
  /// may round differently in the last bits (clang does here, GCC does not).
  static constexpr double kToleranceM = 1e-12;
  const Points rest_ = sampleBox(600, {kSizeM, 0.3, 0.2}, 23);
  ShapeMatchingBody body_{rest_, configFor(GetParam().mode, GetParam().clusters)};
  ShapeMatchingBody fresh_{rest_, configFor(GetParam().mode, GetParam().clusters)};
};

TEST_P(AbsurdInputTest, TheGoodCloudAfterOneWithPointsFarOutGivesAFreshBodysState) {
  body_.track(withPointsFarOut(observedPose(rest_, 0.0), GetParam().magnitude));
  for (int cloud = 0; cloud < 8; ++cloud) {
    const Points good = observedPose(rest_, 0.01 * cloud);
    body_.track(good);
    fresh_.track(good);
    expectSameState(body_, fresh_, kToleranceM, kSizeM, "good cloud " + std::to_string(cloud));
  }
  for (int s = 0; s < 50; ++s) {
    body_.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    fresh_.step(0.01, Eigen::Vector3d(0, 0, -9.81));
  }
  expectSameState(body_, fresh_, kToleranceM, kSizeM, "50 steps later");
}

// Registered on its observed points alone, with the points far out in the last cloud now
// unobserved among others.
TEST_P(AbsurdInputTest, AGoodCloudWithHolesAfterOneWithPointsFarOutGivesAFreshBodysState) {
  body_.track(withPointsFarOut(observedPose(rest_, 0.0), GetParam().magnitude));
  Points holed = observedPose(rest_, 0.02);
  for (std::size_t i = 0; i < holed.size(); i += 7) {
    holed[i].setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  EXPECT_EQ(body_.track(holed), fresh_.track(holed));
  expectSameState(body_, fresh_, kToleranceM, kSizeM, "cloud with holes");
}

TEST_P(AbsurdInputTest, PlacedAndStoppedAfterAStepAtAbsurdSpeedItMovesAsAFreshBody) {
  Points velocities(rest_.size());
  for (std::size_t i = 0; i < velocities.size(); ++i) {
    velocities[i] = GetParam().magnitude * Eigen::Vector3d(1.0, (i % 5) * 0.3, -0.7);
  }
  body_.setVelocities(velocities);
  body_.step(0.01, Eigen::Vector3d(0, 0, -9.81));
  const Points clean = observedPose(rest_, 0.0);
  const Points still(rest_.size(), Eigen::Vector3d::Zero());
  for (ShapeMatchingBody* b : {&body_, &fresh_}) {
    b->setPositions(clean);
    b->setVelocities(still);
  }
  expectSameState(body_, fresh_, kToleranceM, kSizeM, "placed and stopped");
  for (int s = 0; s < 50; ++s) {
    body_.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    fresh_.step(0.01, Eigen::Vector3d(0, 0, -9.81));
  }
  expectSameState(body_, fresh_, kToleranceM, kSizeM, "50 steps later");
}

INSTANTIATE_TEST_SUITE_P(Matrix, AbsurdInputTest,
                         ::testing::ValuesIn(absurdInputCases({1e30, 1e100, 1e200})),
                         [](const auto& info) { return info.param.name; });

// A cluster with no observed point keeps its last transform; one made not finite by steps
// at 1e307 m/s (the goals' pull overflows) gives way to a fresh body's, and its points go
// where a fresh body's would.
TEST(AbsurdInput, AClusterUnobservedAfterStepsToOverflowTakesAFreshBodysPlace) {
  const Points rest = sampleBox(600, {0.5, 0.3, 0.2}, 23);
  for (const AbsurdInputCase& c : absurdInputCases({1e307})) {
    ShapeMatchingBody body(rest, configFor(c.mode, c.clusters));
    ShapeMatchingBody fresh(rest, configFor(c.mode, c.clusters));
    body.setVelocities(Points(rest.size(), 1e307 * Eigen::Vector3d(0.6, -0.8, 0.1)));
    for (int s = 0; s < 3; ++s) body.step(0.01, Eigen::Vector3d(0, 0, -9.81));
    ASSERT_FALSE(body.deformation(0).transform.allFinite() &&
                 body.deformation(0).translation.allFinite())
        << c.name;
    Points blind = observedPose(rest, 0.0);
    for (const std::uint32_t i : body.cluster(0).points) {
      blind[i].setConstant(std::numeric_limits<double>::quiet_NaN());
    }
    EXPECT_EQ(body.track(blind), fresh.track(blind)) << c.name;
    expectSameState(body, fresh, 1e-12, 0.5, c.name + ", cluster 0 unobserved");
  }
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
  return mapped(points, [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return factor * p + offset;
  });
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
        cases.push_back({prefix + name, mode, clusters, stiffness, dt, rest, start,
                         damped_volume_goals});
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
    largest_radius = std::max(largest_radius, radiusAbout(body.positions(), centroid(body.positions())));
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
        BadConfigCase{"nan_mass", [](auto& c, auto&) { c.mass_kg = std::nan(""); }, "mass_kg = nan"},
        BadConfigCase{"stiffness_above_one", [](auto& c, auto&) { c.stiffness = 1.5; }, "stiffness = 1.5"},
        BadConfigCase{"stiffness_negative", [](auto& c, auto&) { c.stiffness = -0.1; }, "stiffness = -0.1"},
        BadConfigCase{"beta_above_one", [](auto& c, auto&) { c.beta = 2.0; }, "beta = 2"},
        BadConfigCase{"damping_negative", [](auto& c, auto&) { c.damping = -1.0; }, "damping = -1"},
        BadConfigCase{"zero_clusters", [](auto& c, auto&) { c.clusters = 0; }, "clusters = 0"},
        BadConfigCase{"more_clusters_than_points", [](auto& c, auto&) { c.clusters = 21; }, "clusters = 21"},
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
}  // namespace deformable_collision
