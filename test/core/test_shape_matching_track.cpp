// ShapeMatchingBody tracking observed clouds: unobserved points, swapped clouds, copies,
// and recovery from absurd but finite input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <ostream>
#include <string>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"
#include "shape_matching_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

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
      {"move_rigidly",
       [](ShapeMatchingBody& b) {
         b.moveRigidly({0.01, 0, 0}, {0.5, 0, 0});
       }},
      {"turn",
       [](ShapeMatchingBody& b) {
         b.moveRigidly({0, 0, 0}, {0, 0, 0}, {0, 0, 2.0}, Eigen::Vector3d::Zero());
       }},
      {"displace_points",
       [](ShapeMatchingBody& b) {
         b.displacePoints({{3, {0.001, 0, 0}, {0.2, 0, 0}}});
       }},
      {"set_velocities",
       [](ShapeMatchingBody& b) {
         b.setVelocities(Points(b.positions().size(), {0, 0.3, 0}));
       }},
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
      const std::string when =
          std::string(holes ? "with holes" : "whole") + ", frame " + std::to_string(frame);
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
  ShapeMatchingBody other(sampleBox(60, {0.3, 0.3, 0.3}, 16),
                          configFor(DeformationMode::kLinear, 2));
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
    EXPECT_LE((a.center_of_mass - b.center_of_mass).norm(), tolerance_m)
        << when << ", cluster " << k;
    EXPECT_LE((a.translation - b.translation).norm(), tolerance_m) << when << ", cluster " << k;
    EXPECT_LE((a.transform - b.transform).norm() * size_m, tolerance_m)
        << when << ", cluster " << k;
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
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
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

}  // namespace
}  // namespace test
}  // namespace deformable_collision
