#include "deformable_collision/scenes/camera_gripper_scene.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace deformable_collision {
namespace {

constexpr double kSpongeHeightM = 0.12;
constexpr double kFloorHalfSizeM = 0.3;
/// The camera looks down at the sponge from this elevation, from the -y side, swinging
/// this far to either side.
constexpr double kCameraElevationRad = 70.0 * M_PI / 180.0;
constexpr double kCameraSwingRad = 45.0 * M_PI / 180.0;
/// Disk radii over sample spacing: random samples need a little more than a grid.
constexpr double kRandomSplatRatio = 1.5;
constexpr double kGridSplatRatio = 0.75;

void requirePositive(double value, const char* name) {
  if (!(value > 0.0)) {
    throw std::invalid_argument(std::string("CameraGripperScene: ") + name + " must be > 0");
  }
}

std::vector<Eigen::Vector3d> floorGrid(double spacing_m) {
  std::vector<Eigen::Vector3d> points;
  const int steps = static_cast<int>(std::ceil(2 * kFloorHalfSizeM / spacing_m));
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      points.emplace_back(-kFloorHalfSizeM + 2 * kFloorHalfSizeM * i / steps,
                          -kFloorHalfSizeM + 2 * kFloorHalfSizeM * j / steps, 0.0);
    }
  }
  return points;
}

}  // namespace

CameraGripperScene::CameraGripperScene(const CameraGripperConfig& config)
    : config_(config),
      sponge_(config.sponge),
      camera_(config.camera),
      world_from_sponge_(Eigen::Translation3d(0.0, 0.0, kSpongeHeightM)) {
  requirePositive(config.cycle_s, "cycle_s");
  requirePositive(config.sweep_period_s, "sweep_period_s");
  requirePositive(config.camera_distance_m, "camera_distance_m");
  requirePositive(config.floor_spacing_m, "floor_spacing_m");
  requirePositive(config.jaw_spacing_m, "jaw_spacing_m");
  if (!(config.crop_margin_m >= 0.0)) {
    throw std::invalid_argument("CameraGripperScene: crop_margin_m must be >= 0");
  }
  floor_points_ = floorGrid(config.floor_spacing_m);
  floor_normals_.assign(floor_points_.size(), Eigen::Vector3d::UnitZ());
  jaw_points_ = sponge_.jawSurfacePoints(config.jaw_spacing_m);
  // The deformation grows from phase 0 to 0.5 and shrinks back the same way.
  for (int step = 0; step <= 10; ++step) {
    sponge_.positions(sponge_.deformationAt(0.05 * step), ground_truth_);
    for (const auto& p : ground_truth_) crop_box_.extend(world_from_sponge_ * p);
  }
  crop_box_.min().array() -= config.crop_margin_m;
  crop_box_.max().array() += config.crop_margin_m;
}

std::vector<Eigen::Vector3d> CameraGripperScene::restModel() const {
  std::vector<Eigen::Vector3d> points = sponge_.restPoints();
  for (auto& p : points) p = world_from_sponge_ * p;
  return points;
}

SpongeDeformation CameraGripperScene::deformationAt(double time_s) const {
  return sponge_.deformationAt(time_s / config_.cycle_s);
}

Eigen::Isometry3d CameraGripperScene::cameraPose(double time_s) const {
  const double azimuth =
      -0.5 * M_PI + kCameraSwingRad * std::sin(2.0 * M_PI * time_s / config_.sweep_period_s);
  const Eigen::Vector3d target = world_from_sponge_.translation();
  const Eigen::Vector3d direction(std::cos(kCameraElevationRad) * std::cos(azimuth),
                                  std::cos(kCameraElevationRad) * std::sin(azimuth),
                                  std::sin(kCameraElevationRad));
  return cameraLookingAt(target + config_.camera_distance_m * direction, target);
}

Eigen::Isometry3d CameraGripperScene::jawPose(JawSide side, double time_s) const {
  return world_from_sponge_ * sponge_.jawPose(side, deformationAt(time_s));
}

void CameraGripperScene::render(double time_s) {
  const SpongeDeformation deformation = deformationAt(time_s);
  sponge_.positions(deformation, ground_truth_);
  sponge_.normals(deformation, normals_);
  for (std::size_t i = 0; i < ground_truth_.size(); ++i) {
    ground_truth_[i] = world_from_sponge_ * ground_truth_[i];
    normals_[i] = world_from_sponge_.linear() * normals_[i];
  }
  const Eigen::Isometry3d world_from_camera = cameraPose(time_s);
  camera_.beginFrame(world_from_camera);
  sponge_label_ =
      camera_.addSurface(ground_truth_, normals_, kRandomSplatRatio * sponge_.sampleSpacing());
  camera_.addSurface(floor_points_, floor_normals_, kGridSplatRatio * config_.floor_spacing_m);
  for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
    // The plates' faces meet at their edges, so their disks face the camera.
    std::vector<Eigen::Vector3d>& jaw = jaw_world_[side == JawSide::kLeft ? 0 : 1];
    const Eigen::Isometry3d pose = jawPose(side, time_s);
    jaw.resize(jaw_points_.size());
    for (std::size_t i = 0; i < jaw.size(); ++i) jaw[i] = pose * jaw_points_[i];
    camera_.addSurface(jaw, {}, kGridSplatRatio * config_.jaw_spacing_m);
  }
  camera_.finishFrame();
  cropCloud(world_from_camera);
}

void CameraGripperScene::cropCloud(const Eigen::Isometry3d& world_from_camera) {
  const auto& points = camera_.points();
  cloud_.resize(points.size());
  cloud_points_ = outlier_points_ = 0;
  for (std::size_t pixel = 0; pixel < points.size(); ++pixel) {
    cloud_[pixel] = points[pixel];
    if (!points[pixel].allFinite()) continue;
    if (!crop_box_.contains(world_from_camera * points[pixel].cast<double>())) {
      cloud_[pixel].setConstant(std::numeric_limits<float>::quiet_NaN());
      continue;
    }
    ++cloud_points_;
    outlier_points_ += camera_.labels()[pixel] != sponge_label_;
  }
}

const std::vector<std::uint8_t>& CameraGripperScene::groundTruthVisible() const {
  return camera_.visible(sponge_label_);
}

}  // namespace deformable_collision
