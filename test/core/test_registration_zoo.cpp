#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <tuple>

#include "deformable_collision/core/common/nearest_point_index.h"
#include "deformable_collision/scenes/registration_zoo.h"

namespace deformable_collision {
namespace {

RegistrationZooConfig smallZoo() {
  RegistrationZooConfig config;
  config.points = 3000;
  config.motion_frames = 4;
  config.rest_frames = 1;
  config.camera.width_px = 160;
  config.camera.height_px = 120;
  return config;
}

using ZooCaseParam = std::tuple<ZooShape, ZooDeformation>;

class ZooCases : public ::testing::TestWithParam<ZooCaseParam> {};

TEST_P(ZooCases, RestAtTheStartDeformedAtTheEnd) {
  const auto [shape, deformation] = GetParam();
  const RegistrationZooConfig config = smallZoo();
  RegistrationZooCase zoo(shape, deformation, config);
  double largest_m = 0.0;
  for (const auto& p : zoo.restModel()) {
    EXPECT_EQ(zoo.deformed(p, 0.0), p);
    largest_m = std::max(largest_m, (zoo.deformed(p, 1.0) - p).norm());
  }
  // Every deformation moves some point by more than the camera's noise and a sample
  // spacing, none by more than the object is long.
  EXPECT_GT(largest_m, 0.003);
  EXPECT_LT(largest_m, 0.1);
  zoo.render(zoo.frames() - 1);
  for (std::size_t i = 0; i < zoo.restModel().size(); ++i) {
    EXPECT_EQ(zoo.groundTruth()[i], zoo.deformed(zoo.restModel()[i], 1.0));
  }
}

TEST_P(ZooCases, TheCloudShowsOneSideOfTheTruth) {
  const auto [shape, deformation] = GetParam();
  RegistrationZooCase zoo(shape, deformation, smallZoo());
  zoo.render(2);
  std::size_t seen = 0;
  for (const auto v : zoo.groundTruthVisible()) seen += v;
  const double seen_share = static_cast<double>(seen) / zoo.restModel().size();
  EXPECT_GT(seen_share, 0.2);
  EXPECT_LT(seen_share, 0.7);
  ASSERT_GT(zoo.cloud().size(), 300u);
  // Apart from the outliers, every cloud point is on the seen surface, within the noise.
  NearestPointIndex truth;
  truth.build(zoo.groundTruth());
  std::size_t near = 0;
  for (const auto& p : zoo.cloud()) {
    NearestPointIndex::Nearest nearest;
    truth.nearest(p, nearest);
    near += nearest.squared_distance_m2 < std::pow(zoo.sampleSpacing() + 0.004, 2);
  }
  EXPECT_GT(near, 0.97 * zoo.cloud().size());
  // The same errors for the truth itself: none.
  const ZooErrors errors = zoo.score(zoo.groundTruth());
  EXPECT_EQ(errors.seen_m, 0.0);
  EXPECT_EQ(errors.hidden_m, 0.0);
}

INSTANTIATE_TEST_SUITE_P(All, ZooCases,
                         ::testing::Combine(::testing::ValuesIn(kZooShapes),
                                            ::testing::ValuesIn(kZooDeformations)),
                         [](const auto& info) {
                           return std::string(zooShapeName(std::get<0>(info.param))) + "_" +
                                  zooDeformationName(std::get<1>(info.param));
                         });

TEST(RegistrationZooCase, RefusesNoMotion) {
  RegistrationZooConfig config = smallZoo();
  config.motion_frames = 0;
  EXPECT_THROW(RegistrationZooCase(ZooShape::kFruit, ZooDeformation::kBend, config),
               std::invalid_argument);
}

}  // namespace
}  // namespace deformable_collision
