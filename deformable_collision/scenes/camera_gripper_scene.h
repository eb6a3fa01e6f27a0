#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "deformable_collision/scenes/deforming_sponge.h"
#include "deformable_collision/scenes/virtual_camera.h"

namespace deformable_collision {

/// The camera_gripper scene: a sponge held in the air by two gripper jaws above a floor,
/// squeezed, bent and twisted over and over (DeformingSponge), seen by a depth camera that
/// sweeps slowly to and fro along an arc above it. World frame: z up, floor at z = 0.
struct CameraGripperConfig {
  DeformingSpongeConfig sponge;
  VirtualCameraConfig camera;
  double cycle_s = 10.0;         ///< One squeeze-bend-release of the sponge.
  double sweep_period_s = 20.0;  ///< The camera's arc, there and back.
  double camera_distance_m = 0.3;
  double floor_spacing_m = 0.01;  ///< The floor's grid of points, 0.6 m square.
  double jaw_spacing_m = 0.004;   ///< The jaws' plates' grids of points.
  /// The crop of the camera's cloud reaches this far beyond everywhere the sponge goes: a
  /// user's box filter, tight enough to leave the floor out, so that only the jaws' parts
  /// inside it remain as outliers.
  double crop_margin_m = 0.005;
};

/// Everything of the scene at one time: the camera's cloud and the ground truth behind it.
/// render() allocates nothing after the first call.
class CameraGripperScene {
 public:
  /// @throw std::invalid_argument from the sponge's or the camera's configuration, or when a
  /// period or spacing is not positive.
  explicit CameraGripperScene(const CameraGripperConfig& config);

  const CameraGripperConfig& config() const { return config_; }
  const DeformingSponge& sponge() const { return sponge_; }
  /// Where the sponge's frame is in the world: held 0.12 m above the floor.
  const Eigen::Isometry3d& worldFromSponge() const { return world_from_sponge_; }
  /// The sponge's rest model in the world frame, in model order: the model file's points.
  std::vector<Eigen::Vector3d> restModel() const;
  /// The floor's points in the world frame.
  const std::vector<Eigen::Vector3d>& floorPoints() const { return floor_points_; }
  /// A jaw's points in the jaw's own frame (both jaws alike).
  const std::vector<Eigen::Vector3d>& jawPoints() const { return jaw_points_; }

  SpongeDeformation deformationAt(double time_s) const;
  /// The camera's optical frame in the world at `time_s` (z forward, x right, y down).
  Eigen::Isometry3d cameraPose(double time_s) const;
  Eigen::Isometry3d jawPose(JawSide side, double time_s) const;

  /// Renders the scene at `time_s`; the accessors below then describe it.
  void render(double time_s);
  /// The camera's organized cloud (width * height, row by row, camera frame), NaN outside
  /// the crop box, where nothing was hit and where the camera dropped the pixel.
  const std::vector<Eigen::Vector3f>& cloud() const { return cloud_; }
  /// The sponge's points in the world frame, in model order.
  const std::vector<Eigen::Vector3d>& groundTruth() const { return ground_truth_; }
  /// The deformed surface's outward unit normals at groundTruth(), in the world frame.
  const std::vector<Eigen::Vector3d>& groundTruthNormals() const { return normals_; }
  /// Per model point, 1 if the camera sees it (VirtualCamera::visible).
  const std::vector<std::uint8_t>& groundTruthVisible() const;
  /// Finite points of cloud() in all, and those not on the sponge (jaws, floor).
  std::size_t cloudPoints() const { return cloud_points_; }
  std::size_t outlierPoints() const { return outlier_points_; }

 private:
  void cropCloud(const Eigen::Isometry3d& world_from_camera);

  CameraGripperConfig config_;
  DeformingSponge sponge_;
  VirtualCamera camera_;
  Eigen::Isometry3d world_from_sponge_;
  Eigen::AlignedBox3d crop_box_;
  std::vector<Eigen::Vector3d> floor_points_, floor_normals_, jaw_points_;
  std::vector<Eigen::Vector3d> ground_truth_, normals_, jaw_world_[2];
  std::vector<Eigen::Vector3f> cloud_;
  int sponge_label_ = 0;
  std::size_t cloud_points_ = 0, outlier_points_ = 0;
};

}  // namespace deformable_collision
