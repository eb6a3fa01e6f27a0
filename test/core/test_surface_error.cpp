// SurfaceError: the registration's estimate of its model's error, seen side and hidden side,
// against the zoo's ground truth; and how a contact's side is told.
#include "deformable_collision/core/registration/surface_error.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <tuple>

#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/registration_zoo.h"

namespace deformable_collision {
namespace {

TEST(SurfaceError, TellsTheSideByTheViewpoint) {
  SurfaceError error;
  error.seen_m = 0.001;
  error.hidden_m = 0.003;
  error.viewpoint_m = Eigen::Vector3d(0.0, 0.0, 1.0);
  const Eigen::Vector3d top(0.0, 0.0, 0.05), bottom(0.0, 0.0, -0.05);
  EXPECT_EQ(error.at(top, Eigen::Vector3d::UnitZ()), 0.001);
  EXPECT_EQ(error.at(bottom, -Eigen::Vector3d::UnitZ()), 0.003);
  EXPECT_EQ(error.at(top, Eigen::Vector3d::UnitX()), 0.003) << "edge-on is not seen";
  error.viewpoint_m.reset();
  EXPECT_EQ(error.at(top, Eigen::Vector3d::UnitZ()), 0.003) << "no side known: the larger";
  EXPECT_EQ(SurfaceError{}.at(top, Eigen::Vector3d::UnitZ()), 0.0) << "never registered";
}

using ZooCase = std::tuple<ZooShape, ZooDeformation>;

struct Registered {
  ZooErrors truth;
  SurfaceError estimate;
};

/// The zoo case deformed and rested, registered cloud by cloud; its last estimate and the
/// model's true errors then.
Registered registerZooCase(const ZooCase& c, bool with_viewpoint) {
  RegistrationZooConfig config;
  config.points = 4000;
  RegistrationZooCase zoo(std::get<0>(c), std::get<1>(c), config);
  ShapeMatchingConfig shape;
  shape.clusters = 6;
  ShapeMatchingBody body(zoo.restModel(), shape);
  CloudRegistration registration{RegistrationConfig{}};
  Registered r;
  for (int frame = 0; frame < zoo.frames(); ++frame) {
    zoo.render(frame);
    const RegistrationReport report = registration.registerCloud(
        body, zoo.cloud(),
        with_viewpoint ? std::optional<Eigen::Vector3d>(zoo.cameraPose().translation())
                       : std::nullopt);
    EXPECT_FALSE(report.held);
    r.estimate = report.surface_error;
  }
  r.truth = zoo.score(body.positions());
  return r;
}

// Bent and dented, every shape: the estimate is no smaller than the model's mean distance
// from the true surface on either side, and not far above it (within 5x: an estimate that
// says "anything" is no use to a grasp). The hidden side is never estimated better than the
// seen one. Squeezes are left out: a far side squeezed while the near side is not shows in
// no view, and the estimate misses it (docs/design.md).
class ZooEstimate : public ::testing::TestWithParam<ZooCase> {};

TEST_P(ZooEstimate, CoversTheSurfaceError) {
  const Registered r = registerZooCase(GetParam(), true);
  std::printf("[ MEASURED ] surface error seen %.2f (estimated %.2f), hidden %.2f (%.2f) mm\n",
              1e3 * r.truth.seen_off_surface_m, 1e3 * r.estimate.seen_m,
              1e3 * r.truth.hidden_off_surface_m, 1e3 * r.estimate.hidden_m);
  EXPECT_GE(r.estimate.seen_m, r.truth.seen_off_surface_m);
  EXPECT_GE(r.estimate.hidden_m, r.truth.hidden_off_surface_m);
  EXPECT_LE(r.estimate.seen_m, 5.0 * r.truth.seen_off_surface_m);
  EXPECT_LE(r.estimate.hidden_m, 5.0 * r.truth.hidden_off_surface_m);
  EXPECT_GT(r.estimate.hidden_m, r.estimate.seen_m);
  ASSERT_TRUE(r.estimate.viewpoint_m.has_value());
}

INSTANTIATE_TEST_SUITE_P(BentAndDented, ZooEstimate,
                         ::testing::Combine(::testing::ValuesIn(kZooShapes),
                                            ::testing::Values(ZooDeformation::kBend,
                                                              ZooDeformation::kDent)),
                         [](const auto& info) {
                           return std::string(zooShapeName(std::get<0>(info.param))) + "_" +
                                  zooDeformationName(std::get<1>(info.param));
                         });

// Without the camera's position no side is known: both estimates are the hidden side's
// form over the whole model.
TEST(ZooEstimateWithoutViewpoint, BothSidesTakeTheLarger) {
  const Registered r = registerZooCase({ZooShape::kBanana, ZooDeformation::kBend}, false);
  EXPECT_EQ(r.estimate.seen_m, r.estimate.hidden_m);
  EXPECT_GE(r.estimate.hidden_m, r.truth.hidden_off_surface_m);
  EXPECT_FALSE(r.estimate.viewpoint_m.has_value());
}

}  // namespace
}  // namespace deformable_collision
