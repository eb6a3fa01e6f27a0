#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "deformable_collision/scenes/deforming_sponge.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

DeformingSpongeConfig smallSponge() {
  DeformingSpongeConfig config;
  config.points = 4000;
  return config;
}

/// Signed distance to the rounded box of `config` at rest (0 on its surface).
double restSignedDistance(const DeformingSpongeConfig& config, const Eigen::Vector3d& p) {
  const Eigen::Vector3d inner =
      0.5 * config.size_m - Eigen::Vector3d::Constant(config.corner_radius_m);
  const Eigen::Vector3d q = p.cwiseAbs() - inner;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0) - config.corner_radius_m;
}

TEST(DeformingSponge, RestSamplesLieOnTheRoundedBoxSpreadByArea) {
  const DeformingSponge sponge(smallSponge());
  const auto& config = sponge.config();
  ASSERT_EQ(sponge.restPoints().size(), config.points);
  std::size_t on_top = 0;
  for (std::size_t i = 0; i < config.points; ++i) {
    const Eigen::Vector3d& p = sponge.restPoints()[i];
    EXPECT_NEAR(restSignedDistance(config, p), 0.0, 1e-12) << i;
    EXPECT_NEAR(sponge.restNormals()[i].norm(), 1.0, 1e-12) << i;
    // The normal points outwards: a step along it leaves the box.
    EXPECT_NEAR(restSignedDistance(config, p + 1e-4 * sponge.restNormals()[i]), 1e-4, 1e-9) << i;
    on_top += sponge.restNormals()[i].z() == 1.0;
  }
  const double r = config.corner_radius_m;
  const double top_area = (config.size_m.x() - 2 * r) * (config.size_m.y() - 2 * r);
  // The spacing is sqrt(area / points): a face gets its area over the spacing squared.
  const double expected_top = top_area / std::pow(sponge.sampleSpacing(), 2);
  EXPECT_NEAR(static_cast<double>(on_top), expected_top, 5.0 * std::sqrt(expected_top));
}

TEST(DeformingSponge, IsAtRestAtPhaseZeroAndOne) {
  const DeformingSponge sponge(smallSponge());
  Points positions;
  for (const double phase : {0.0, 1.0, 2.0}) {
    const SpongeDeformation deformation = sponge.deformationAt(phase);
    EXPECT_EQ(deformation.squeeze_ratio, 0.0);
    EXPECT_EQ(deformation.bend_rad, 0.0);
    EXPECT_EQ(deformation.twist_rad, 0.0);
    sponge.positions(deformation, positions);
    ASSERT_EQ(positions.size(), sponge.restPoints().size());
    for (std::size_t i = 0; i < positions.size(); ++i) {
      EXPECT_LT((positions[i] - sponge.restPoints()[i]).norm(), 1e-15) << i;
    }
  }
  const SpongeDeformation most = sponge.deformationAt(0.5);
  EXPECT_DOUBLE_EQ(most.squeeze_ratio, sponge.config().max_squeeze_ratio);
  EXPECT_DOUBLE_EQ(most.bend_rad, sponge.config().max_bend_rad);
  EXPECT_DOUBLE_EQ(most.twist_rad, sponge.config().max_twist_rad);
}

TEST(DeformingSponge, StaysFiniteAndSmoothOverTheCycle) {
  const DeformingSponge sponge(smallSponge());
  Points previous, positions, normals;
  sponge.positions(sponge.deformationAt(0.0), previous);
  for (int frame = 1; frame <= 100; ++frame) {
    const SpongeDeformation deformation = sponge.deformationAt(frame / 100.0);
    sponge.positions(deformation, positions);
    sponge.normals(deformation, normals);
    for (std::size_t i = 0; i < positions.size(); ++i) {
      ASSERT_TRUE(positions[i].allFinite()) << frame << ", " << i;
      ASSERT_NEAR(normals[i].norm(), 1.0, 1e-9) << frame << ", " << i;
      // A frame of 100 moves no point by more than a few millimetres.
      EXPECT_LT((positions[i] - previous[i]).norm(), 0.003) << frame << ", " << i;
    }
    previous = positions;
  }
}

/// One deformation at a time, and what it must do to the sponge.
struct ModeCase {
  const char* name;
  SpongeDeformation deformation;
};

class SpongeModes : public ::testing::TestWithParam<ModeCase> {};

TEST_P(SpongeModes, JawsTouchTheSidesWithoutPenetrating) {
  const DeformingSponge sponge(smallSponge());
  const SpongeDeformation& deformation = GetParam().deformation;
  Points positions;
  sponge.positions(deformation, positions);
  const Eigen::Vector3d half = sponge.jawHalfExtents();
  for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
    const Eigen::Isometry3d jaw = sponge.jawPose(side, deformation);
    const double outward = side == JawSide::kLeft ? -1.0 : 1.0;
    const double inner_face = outward * (jaw.translation().y() - outward * half.y());
    double widest = -1.0;
    for (const auto& p : positions) {
      const Eigen::Vector3d local = jaw.inverse() * p;
      if (std::abs(local.x()) > half.x() || std::abs(local.z()) > half.z()) continue;
      widest = std::max(widest, outward * p.y());
    }
    EXPECT_NEAR(widest, inner_face, 1e-12) << "jaw " << int(side);
  }
}

TEST_P(SpongeModes, EndsTurnByTheBendAngle) {
  // The flat end faces' normals: each turned down by half the bend.
  const DeformingSponge sponge(smallSponge());
  const SpongeDeformation& deformation = GetParam().deformation;
  Points normals;
  sponge.normals(deformation, normals);
  Eigen::Vector3d plus_end = Eigen::Vector3d::Zero(), minus_end = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < normals.size(); ++i) {
    if (sponge.restNormals()[i].x() == 1.0) plus_end += normals[i];
    if (sponge.restNormals()[i].x() == -1.0) minus_end += normals[i];
  }
  const double angle = std::acos(plus_end.normalized().dot(-minus_end.normalized()));
  EXPECT_NEAR(angle, std::abs(deformation.bend_rad), 1e-6);
  EXPECT_LE(plus_end.z(), 1e-9);
  EXPECT_LE(minus_end.z(), 1e-9);
}

TEST_P(SpongeModes, TopFaceTurnsByTheTwistBeyondTheJaws) {
  // The top face's normal turns about the length by the twist at its distance from the
  // jaws, measured in the plane across the (bent) length: sideways against the local up.
  const DeformingSponge sponge(smallSponge());
  const auto& config = sponge.config();
  const SpongeDeformation& deformation = GetParam().deformation;
  Points normals;
  sponge.normals(deformation, normals);
  const double held = 0.5 * config.jaw_length_m, free_length = 0.5 * config.size_m.x() - held;
  const double curvature = 0.5 * deformation.bend_rad / free_length;
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const Eigen::Vector3d& rest = sponge.restPoints()[i];
    if (sponge.restNormals()[i].z() != 1.0) continue;
    const double beyond = std::max(0.0, std::abs(rest.x()) - held);
    const double side = rest.x() < 0 ? -1.0 : 1.0;
    const double heading = -side * curvature * beyond;
    const Eigen::Vector3d up(-std::sin(heading), 0.0, std::cos(heading));
    const double twist = side * deformation.twist_rad * beyond / free_length;
    EXPECT_NEAR(std::atan2(-normals[i].y(), normals[i].dot(up)), twist, 1e-6) << i;
  }
}

INSTANTIATE_TEST_SUITE_P(
    OneAtATime, SpongeModes,
    ::testing::Values(ModeCase{"rest", {}}, ModeCase{"squeeze", {0.3, 0.0, 0.0}},
                      ModeCase{"bend", {0.0, 30.0 * M_PI / 180.0, 0.0}},
                      ModeCase{"twist", {0.0, 0.0, 10.0 * M_PI / 180.0}},
                      ModeCase{"all", {0.3, 30.0 * M_PI / 180.0, 10.0 * M_PI / 180.0}}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(DeformingSponge, SqueezeNarrowsTheHeldPartByTheRatio) {
  const DeformingSponge sponge(smallSponge());
  Points positions;
  sponge.positions({0.3, 0.0, 0.0}, positions);
  double widest = 0.0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (std::abs(sponge.restPoints()[i].x()) <= 0.5 * sponge.config().jaw_length_m) {
      widest = std::max(widest, std::abs(positions[i].y()));
    }
  }
  EXPECT_NEAR(2.0 * widest, 0.7 * sponge.config().size_m.y(), 1e-12);
}

TEST(DeformingSponge, RejectsImpossibleConfigurations) {
  std::vector<DeformingSpongeConfig> impossible(4);
  impossible[0].points = 10;
  impossible[1].corner_radius_m = 0.03;  // wider than half the height
  impossible[2].jaw_length_m = 0.2;      // longer than the sponge
  impossible[3].max_squeeze_ratio = 0.95;
  for (std::size_t i = 0; i < impossible.size(); ++i) {
    EXPECT_THROW(DeformingSponge{impossible[i]}, std::invalid_argument) << "case " << i;
  }
}

}  // namespace
}  // namespace deformable_collision
