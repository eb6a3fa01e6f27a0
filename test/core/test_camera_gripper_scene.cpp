#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "deformable_collision/scenes/camera_gripper_scene.h"

namespace deformable_collision {
namespace {

CameraGripperConfig smallScene() {
  CameraGripperConfig config;
  config.sponge.points = 4000;
  return config;
}

TEST(CameraGripperScene, GroundTruthStartsAsTheRestModel) {
  CameraGripperScene scene(smallScene());
  scene.render(0.0);
  const auto rest = scene.restModel();
  ASSERT_EQ(scene.groundTruth().size(), rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    EXPECT_LT((scene.groundTruth()[i] - rest[i]).norm(), 1e-15) << i;
  }
}

class CameraGripperTimes : public ::testing::TestWithParam<double> {};

TEST_P(CameraGripperTimes, TheCloudIsTheSpongeSeenWithAFewOutliers) {
  CameraGripperScene scene(smallScene());
  const double time_s = GetParam();
  scene.render(time_s);
  const auto& camera = scene.config().camera;
  ASSERT_EQ(scene.cloud().size(), std::size_t(camera.width_px * camera.height_px));
  const Eigen::Isometry3d world_from_camera = scene.cameraPose(time_s);
  std::size_t finite = 0, near_sponge = 0;
  for (const auto& p : scene.cloud()) {
    if (!p.allFinite()) continue;
    ++finite;
    const Eigen::Vector3d world = world_from_camera * p.cast<double>();
    double nearest = std::numeric_limits<double>::infinity();
    for (const auto& q : scene.groundTruth()) nearest = std::min(nearest, (world - q).norm());
    // Noise of 1 mm (up to 5 sigma) plus about the samples' spacing.
    near_sponge += nearest < 0.005 + 2 * scene.sponge().sampleSpacing();
  }
  EXPECT_EQ(finite, scene.cloudPoints());
  EXPECT_GT(finite, 1000u);
  const double outlier_ratio = double(scene.outlierPoints()) / finite;
  // The jaws' faces that the crop keeps: 3 % open, 11 % closed on the squeezed sponge.
  EXPECT_GT(outlier_ratio, 0.01);
  EXPECT_LT(outlier_ratio, 0.15);
  // Some jaw points touch the sponge and count as near it too.
  EXPECT_GT(double(near_sponge) / finite, 1.0 - outlier_ratio - 0.01);
  std::size_t visible = 0;
  for (const auto v : scene.groundTruthVisible()) visible += v;
  const double visible_ratio = double(visible) / scene.groundTruth().size();
  EXPECT_GT(visible_ratio, 0.2);
  EXPECT_LT(visible_ratio, 0.6);
}

INSTANTIATE_TEST_SUITE_P(OverTheCycle, CameraGripperTimes, ::testing::Values(0.0, 2.5, 5.0, 7.5));

TEST(CameraGripperScene, TheCameraSweepsAndTheJawsClose) {
  const CameraGripperScene scene(smallScene());
  const double sweep = scene.config().sweep_period_s, cycle = scene.config().cycle_s;
  // A quarter of the sweep turns the camera by its swing of 45 degrees about the vertical.
  const auto heading = [&](double time_s) {
    const Eigen::Vector3d forward = scene.cameraPose(time_s).linear().col(2);
    return std::atan2(forward.y(), forward.x());
  };
  EXPECT_NEAR(heading(0.25 * sweep) - heading(0.0), M_PI / 4, 1e-9);
  const double open_gap = scene.jawPose(JawSide::kRight, 0.0).translation().y() -
                          scene.jawPose(JawSide::kLeft, 0.0).translation().y();
  const double closed_gap = scene.jawPose(JawSide::kRight, 0.5 * cycle).translation().y() -
                            scene.jawPose(JawSide::kLeft, 0.5 * cycle).translation().y();
  const auto& sponge = scene.config().sponge;
  EXPECT_NEAR(open_gap - closed_gap, sponge.max_squeeze_ratio * sponge.size_m.y(), 1e-12);
}

}  // namespace
}  // namespace deformable_collision
