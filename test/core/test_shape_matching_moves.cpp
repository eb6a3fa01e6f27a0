// ShapeMatchingBody moved by the response: displaced points, rigid moves and turns, the
// rigid motion and centre of mass they leave, and velocities set.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"
#include "shape_matching_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

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
    kink.push_back(
        {i, Eigen::Vector3d(0.0, 0.0, rest[i].x() > 0 ? delta : -delta), Eigen::Vector3d::Zero()});
  }
  body.displacePoints(kink);
  const auto& deformation = body.deformation(0);
  const Eigen::Vector3d outlier_goal =
      deformation.transform * quadraticFeatures(body.cluster(0).rest_offsets.back()) +
      deformation.translation;
  ASSERT_GT((outlier_goal - rest.back()).norm(), 3 * delta)
      << "the scene must make the refit reach";
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
      spin[i] =
          Eigen::Vector3d(0.5, -1.0, 2.0).cross(body.positions()[i]) + Eigen::Vector3d(0.3, 0, 0);
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
      EXPECT_LT((fresh.deformation(k).center_of_mass - body.deformation(k).center_of_mass).norm(),
                1e-12)
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
    for (const auto& p : body.positions())
      velocities.push_back(Eigen::Vector3d(0.5, -1.0, 2.0).cross(p));
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
  const Points rest =
      mapped(sampleEllipsoid(400, {0.3, 0.2, 0.1}, 61),
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
    ::testing::Values(CenterOfMassCase{"Rigid", DeformationMode::kRigid, Eigen::Vector3d::Zero()},
                      CenterOfMassCase{"Linear", DeformationMode::kLinear, Eigen::Vector3d::Zero()},
                      CenterOfMassCase{"Quadratic", DeformationMode::kQuadratic,
                                       Eigen::Vector3d::Zero()},
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
    angular += body.pointMassKg() *
               (body.positions()[i] - centroid(body.positions())).cross(body.velocities()[i]);
  }
  Eigen::Vector3d initial = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < rest.size(); ++i) {
    initial += body.pointMassKg() * (rest[i] - center).cross(velocities[i]);
  }
  EXPECT_LT((angular - initial).norm(), 1e-9 * initial.norm());
  EXPECT_LT(shapeError(body), 1e-3);
  EXPECT_THROW(body.setVelocities(Points(499, Eigen::Vector3d::Zero())), std::invalid_argument);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
