#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "deformable_collision/scenes/virtual_camera.h"
#include "deformable_collision/scenes/zoo_shapes.h"

namespace deformable_collision {

/// The kinds of deformation the zoo applies, each in closed form on the object's frame
/// (x its long axis, z up): across-squeeze with a bulge, a bend about y, a twist about x,
/// a local dent pressed into the top, and the first three together at half their amplitudes
/// while the object is carried and turned.
enum class ZooDeformation { kSqueeze, kBend, kTwist, kDent, kCombined };

inline constexpr std::array<ZooDeformation, 5> kZooDeformations = {
    ZooDeformation::kSqueeze, ZooDeformation::kBend, ZooDeformation::kTwist, ZooDeformation::kDent,
    ZooDeformation::kCombined};

const char* zooDeformationName(ZooDeformation deformation);

/// One zoo case's sizes, camera and motion. Units in the names.
struct RegistrationZooConfig {
  std::size_t points = 8000;               ///< Model samples of the shape.
  int motion_frames = 40;                  ///< From rest to the full deformation, eased in and out.
  int rest_frames = 10;                    ///< Then held still.
  double squeeze_ratio = 0.2;              ///< Width lost across y at the middle.
  double bend_rad = 30.0 * M_PI / 180.0;   ///< Angle between the ends' tangents.
  double twist_rad = 30.0 * M_PI / 180.0;  ///< Between the ends, about x.
  double dent_m = 0.012;                   ///< Depth of the dent at its centre.
  /// The combined case is also carried this far and turned this much about z: a grasped
  /// object moved by the robot while it deforms.
  Eigen::Vector3d carry_m{0.03, 0.02, 0.01};
  double carry_turn_rad = 15.0 * M_PI / 180.0;
  double outlier_ratio = 0.01;      ///< Hit pixels given a wrong depth (flying pixels).
  double camera_distance_m = 0.45;  ///< From the object's centre, above its -y side.
  VirtualCameraConfig camera{320, 240, 1.2, 0.1, 3.0, 0.001, 0.05, 1};
  std::uint64_t seed = 7;
};

/// Registration's error against the ground truth, per material point, on the side the
/// camera sees and on the hidden side: the mean distance, and its mean part along the true
/// surface normal (the rest is a slide along the surface).
struct ZooErrors {
  double seen_m = 0.0, hidden_m = 0.0;
  double seen_off_surface_m = 0.0, hidden_off_surface_m = 0.0;
};

/// One shape under one deformation, seen by one depth camera: the clouds a registration is
/// given and the ground truth it is scored against. The object's frame is the world's.
class RegistrationZooCase {
 public:
  /// @throw std::invalid_argument from the shape or the camera, or if the frames are fewer
  /// than 1 (motion) or 0 (rest).
  RegistrationZooCase(ZooShape shape, ZooDeformation deformation,
                      const RegistrationZooConfig& config);

  ZooShape shape() const { return shape_; }
  ZooDeformation deformation() const { return deformation_; }
  int frames() const { return config_.motion_frames + config_.rest_frames; }
  const std::vector<Eigen::Vector3d>& restModel() const { return surface_.points; }
  double sampleSpacing() const { return surface_.spacing_m; }
  const Eigen::Isometry3d& cameraPose() const { return world_from_camera_; }

  /// Deforms the object to frame `frame` (0 .. frames() - 1; the motion ends at
  /// motion_frames - 1) and renders the camera's cloud.
  void render(int frame);
  /// The camera's finite points in the world frame, with noise, dropout and outliers.
  const std::vector<Eigen::Vector3d>& cloud() const { return cloud_; }
  const std::vector<Eigen::Vector3d>& groundTruth() const { return truth_; }
  const std::vector<std::uint8_t>& groundTruthVisible() const;
  /// `positions` (model order) against this frame's ground truth.
  ZooErrors score(const std::vector<Eigen::Vector3d>& positions) const;

  /// Where rest point `p` is at `amplitude` (0 rest, 1 the full deformation).
  Eigen::Vector3d deformed(const Eigen::Vector3d& p, double amplitude) const;

 private:
  Eigen::Vector3d squeezed(const Eigen::Vector3d& p, double ratio) const;
  Eigen::Vector3d bent(const Eigen::Vector3d& p, double angle_rad) const;
  Eigen::Vector3d twisted(const Eigen::Vector3d& p, double angle_rad) const;
  Eigen::Vector3d dented(const Eigen::Vector3d& p, double depth_m) const;
  /// The deformed normal of rest point i, through the deformation's Jacobian.
  Eigen::Vector3d deformedNormal(std::size_t i, double amplitude) const;
  void addOutliers();

  ZooShape shape_;
  ZooDeformation deformation_;
  RegistrationZooConfig config_;
  ZooSurface surface_;
  Eigen::Vector3d half_extent_m_;  ///< Of the rest shape's box, about its mean.
  Eigen::Vector3d dent_centre_m_;
  VirtualCamera camera_;
  Eigen::Isometry3d world_from_camera_;
  int label_ = 0;
  std::mt19937_64 outliers_;
  std::vector<Eigen::Vector3d> truth_, normals_, cloud_;
};

}  // namespace deformable_collision
