#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "deformable_collision/scenes/shapes.h"
#include "deformable_collision/scenes/virtual_camera.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// Samples on the six faces of an axis-aligned box, `spacing` apart, with outward normals.
struct BoxSurface {
  Points points, normals;
  std::vector<int> face_axis;  ///< Per sample: +-(axis + 1) of its face's normal.
};

BoxSurface boxSurface(const Eigen::Vector3d& low, const Eigen::Vector3d& high, double spacing) {
  BoxSurface box;
  for (int axis = 0; axis < 3; ++axis) {
    const int b = (axis + 1) % 3, c = (axis + 2) % 3;
    const int nb = static_cast<int>(std::ceil((high[b] - low[b]) / spacing));
    const int nc = static_cast<int>(std::ceil((high[c] - low[c]) / spacing));
    for (const double side : {-1.0, 1.0}) {
      for (int i = 0; i <= nb; ++i) {
        for (int j = 0; j <= nc; ++j) {
          Eigen::Vector3d p;
          p[axis] = side < 0 ? low[axis] : high[axis];
          p[b] = low[b] + (high[b] - low[b]) * i / nb;
          p[c] = low[c] + (high[c] - low[c]) * j / nc;
          box.points.push_back(p);
          box.normals.push_back(side * Eigen::Vector3d::Unit(axis));
          box.face_axis.push_back(static_cast<int>(side) * (axis + 1));
        }
      }
    }
  }
  return box;
}

struct FrontFaceCase {
  double noise_m;
  double dropout_ratio;
};

class CameraFrontFace : public ::testing::TestWithParam<FrontFaceCase> {};

TEST_P(CameraFrontFace, SeesOnlyTheFrontFaceAtItsDepth) {
  VirtualCameraConfig config;
  config.noise_m = GetParam().noise_m;
  config.dropout_ratio = GetParam().dropout_ratio;
  VirtualCamera camera(config);
  // A box 0.4 m wide whose front face is 0.5 m ahead, filling the middle of the image.
  const double front_m = 0.5, half_m = 0.2, spacing_m = 0.004;
  const BoxSurface box =
      boxSurface({-half_m, -half_m, front_m}, {half_m, half_m, front_m + 0.2}, spacing_m);
  camera.beginFrame(Eigen::Isometry3d::Identity());
  const int label = camera.addSurface(box.points, box.normals, 1.5 * spacing_m);
  camera.finishFrame();

  const auto& points = camera.points();
  ASSERT_EQ(points.size(), std::size_t(config.width_px * config.height_px));
  const double depth_tolerance_m = 6.0 * config.noise_m + 1e-6;
  std::size_t inside = 0, holes = 0;
  for (int v = 0; v < config.height_px; ++v) {
    for (int u = 0; u < config.width_px; ++u) {
      const std::size_t pixel = static_cast<std::size_t>(v * config.width_px + u);
      const Eigen::Vector3f& p = points[pixel];
      // Where the pixel's ray meets the front face's plane.
      const Eigen::Vector2d on_plane =
          front_m / camera.focalLengthPx() *
          Eigen::Vector2d(u - 0.5 * config.width_px + 0.5, v - 0.5 * config.height_px + 0.5);
      const bool well_inside = on_plane.cwiseAbs().maxCoeff() < half_m - 2 * spacing_m;
      if (!p.allFinite()) {
        EXPECT_EQ(camera.labels()[pixel], VirtualCamera::kNoSurface);
        if (well_inside) ++holes;
        continue;
      }
      EXPECT_EQ(camera.labels()[pixel], label);
      EXPECT_NEAR(p.z(), front_m, depth_tolerance_m) << "pixel " << u << ", " << v;
      EXPECT_LE(p.head<2>().cwiseAbs().maxCoeff(), half_m + 2 * spacing_m) << u << ", " << v;
      inside += well_inside;
    }
  }
  const double expected_holes = config.dropout_ratio * (inside + holes);
  EXPECT_NEAR(static_cast<double>(holes), expected_holes, 5.0 * std::sqrt(expected_holes) + 0.5);
  EXPECT_GT(inside + holes, 10000u);

  for (std::size_t i = 0; i < box.points.size(); ++i) {
    if (box.face_axis[i] == -3) {
      EXPECT_TRUE(camera.visible(label)[i]) << "front sample " << i;
    } else if (box.face_axis[i] == 3) {
      EXPECT_FALSE(camera.visible(label)[i]) << "back sample " << i;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(NoiseAndDropout, CameraFrontFace,
                         ::testing::Values(FrontFaceCase{0.0, 0.0}, FrontFaceCase{0.001, 0.02},
                                           FrontFaceCase{0.002, 0.1}));

struct SphereCase {
  const char* name;
  Eigen::Vector3d eye;
};

class CameraSphere : public ::testing::TestWithParam<SphereCase> {};

TEST_P(CameraSphere, SeesAboutTheNearHalf) {
  // From a distance D a sphere of radius R shows a cap of (1 - R / D) / 2 of its surface.
  const double radius_m = 0.1;
  const Eigen::Vector3d center(0.3, -0.2, 0.5);
  const Points directions = sampleEllipsoid(20000, Eigen::Vector3d::Ones(), 3);
  Points points, normals;
  for (const auto& d : directions) {
    if (d.norm() < 0.1) continue;
    normals.push_back(d.normalized());
    points.push_back(center + radius_m * normals.back());
  }
  const double spacing_m = std::sqrt(4 * M_PI * radius_m * radius_m / points.size());
  const Eigen::Vector3d eye = center + GetParam().eye;
  VirtualCamera camera(VirtualCameraConfig{});
  camera.beginFrame(cameraLookingAt(eye, center));
  const int label = camera.addSurface(points, normals, 2.0 * spacing_m);
  camera.finishFrame();

  std::size_t seen = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double facing = normals[i].dot((eye - points[i]).normalized());
    if (facing > 0.2) {
      EXPECT_TRUE(camera.visible(label)[i]) << i << " faces the camera";
    } else if (facing < -0.05) {
      EXPECT_FALSE(camera.visible(label)[i]) << i << " faces away";
    }
    seen += camera.visible(label)[i];
  }
  const double expected = 0.5 * (1.0 - radius_m / GetParam().eye.norm());
  EXPECT_NEAR(static_cast<double>(seen) / points.size(), expected, 0.03);
}

INSTANTIATE_TEST_SUITE_P(Poses, CameraSphere,
                         ::testing::Values(SphereCase{"ahead", {0.0, -0.5, 0.0}},
                                           SphereCase{"above", {0.2, 0.3, 0.6}},
                                           SphereCase{"far", {-1.5, 0.5, 0.4}}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(VirtualCamera, LabelsTellTheSurfacesApartAndTheNearerWins) {
  VirtualCameraConfig config;
  config.noise_m = 0.0;
  config.dropout_ratio = 0.0;
  VirtualCamera camera(config);
  const BoxSurface wall = boxSurface({-2, -2, 1.0}, {2, 2, 1.1}, 0.01);
  const BoxSurface box = boxSurface({-0.1, -0.1, 0.5}, {0.1, 0.1, 0.6}, 0.004);
  camera.beginFrame(Eigen::Isometry3d::Identity());
  const int wall_label = camera.addSurface(wall.points, wall.normals, 0.015);
  const int box_label = camera.addSurface(box.points, box.normals, 0.006);
  camera.finishFrame();
  std::size_t on_box = 0, on_wall = 0;
  for (std::size_t pixel = 0; pixel < camera.points().size(); ++pixel) {
    const Eigen::Vector3f& p = camera.points()[pixel];
    ASSERT_TRUE(p.allFinite()) << "the wall fills the image: pixel " << pixel;
    if (camera.labels()[pixel] == box_label) {
      EXPECT_NEAR(p.z(), 0.5, 1e-6);
      ++on_box;
    } else {
      EXPECT_EQ(camera.labels()[pixel], wall_label);
      EXPECT_NEAR(p.z(), 1.0, 1e-6);
      ++on_wall;
    }
  }
  EXPECT_GT(on_box, 1000u);
  EXPECT_GT(on_wall, 10000u);
}

TEST(VirtualCamera, NothingOutsideTheRangeAndTheSameSeedGivesTheSameCloud) {
  VirtualCameraConfig config;
  config.max_range_m = 0.8;
  const BoxSurface far_box = boxSurface({-0.2, -0.2, 0.9}, {0.2, 0.2, 1.0}, 0.01);
  const BoxSurface near_box = boxSurface({-0.2, -0.2, 0.5}, {0.2, 0.2, 0.6}, 0.004);
  VirtualCamera first(config), second(config);
  for (VirtualCamera* camera : {&first, &second}) {
    camera->beginFrame(Eigen::Isometry3d::Identity());
    camera->addSurface(far_box.points, far_box.normals, 0.015);
    camera->finishFrame();
    for (const auto& p : camera->points()) EXPECT_FALSE(p.allFinite());
    camera->beginFrame(Eigen::Isometry3d::Identity());
    camera->addSurface(near_box.points, near_box.normals, 0.006);
    camera->finishFrame();
  }
  for (std::size_t pixel = 0; pixel < first.points().size(); ++pixel) {
    const Eigen::Vector3f a = first.points()[pixel], b = second.points()[pixel];
    EXPECT_TRUE(a.allFinite() ? a == b : !b.allFinite()) << pixel;
  }
}

TEST(VirtualCamera, RejectsImpossibleConfigurations) {
  const auto with = [](auto change) {
    VirtualCameraConfig config;
    change(config);
    return config;
  };
  EXPECT_THROW(VirtualCamera(with([](auto& c) { c.width_px = 0; })), std::invalid_argument);
  EXPECT_THROW(VirtualCamera(with([](auto& c) { c.horizontal_fov_rad = 3.5; })),
               std::invalid_argument);
  EXPECT_THROW(VirtualCamera(with([](auto& c) { c.max_range_m = c.min_range_m; })),
               std::invalid_argument);
  EXPECT_THROW(VirtualCamera(with([](auto& c) { c.noise_m = -0.001; })), std::invalid_argument);
  EXPECT_THROW(VirtualCamera(with([](auto& c) { c.dropout_ratio = 1.5; })), std::invalid_argument);
  VirtualCamera camera(VirtualCameraConfig{});
  camera.beginFrame(Eigen::Isometry3d::Identity());
  EXPECT_THROW(camera.addSurface({Eigen::Vector3d::UnitZ()}, {}, 0.0), std::invalid_argument);
  EXPECT_THROW(camera.addSurface({Eigen::Vector3d::UnitZ()},
                                 {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()}, 0.01),
               std::invalid_argument);
}

}  // namespace
}  // namespace deformable_collision
