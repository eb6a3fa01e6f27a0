// ShapeMatchingBody at every vector width: the AVX2 and AVX-512 passes give the bits of the
// portable ones, and a move deferred to the next step gives the bits of one made at once.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <ostream>
#include <string>
#include <tuple>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"
#include "shape_matching_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

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
    ::testing::Combine(::testing::Values(VectorWidth::kPortable, VectorWidth::kAvx2,
                                         VectorWidth::kAvx512),
                       ::testing::Values(DeferredMoveCase{"rigid_damped",
                                                          DeformationMode::kRigid,
                                                          1,
                                                          0.2,
                                                          {0.02, -0.01, 0.03},
                                                          {0.1, 0.2, -0.3}},
                                         DeferredMoveCase{"linear_shared_undamped",
                                                          DeformationMode::kLinear,
                                                          4,
                                                          0.0,
                                                          {-1e-3, 2e-3, 5e-4},
                                                          {0.0, 0.0, -0.05}},
                                         DeferredMoveCase{"quadratic_shared_damped",
                                                          DeformationMode::kQuadratic,
                                                          3,
                                                          0.1,
                                                          {0.3, 0.0, -0.2},
                                                          {1.5, -2.0, 0.25}},
                                         DeferredMoveCase{"offset_only",
                                                          DeformationMode::kLinear,
                                                          2,
                                                          0.1,
                                                          {0.02, -0.01, 0.0},
                                                          {0.0, 0.0, 0.0}},
                                         DeferredMoveCase{"velocity_only",
                                                          DeformationMode::kQuadratic,
                                                          2,
                                                          0.0,
                                                          {0.0, 0.0, 0.0},
                                                          {0.1, 0.0, -0.3}})),
    [](const ::testing::TestParamInfo<WidthAndMove>& info) {
      const VectorWidth width = std::get<0>(info.param);
      return std::string(width == VectorWidth::kPortable ? "portable_"
                         : width == VectorWidth::kAvx2   ? "avx2_"
                                                         : "avx512_") +
             std::get<1>(info.param).name;
    });

}  // namespace
}  // namespace test
}  // namespace deformable_collision
