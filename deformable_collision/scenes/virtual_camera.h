#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <vector>

namespace deformable_collision {

/// A pinhole depth camera such as a RealSense or a Kinect, as far as a point cloud shows it.
struct VirtualCameraConfig {
  int width_px = 320;
  int height_px = 240;
  double horizontal_fov_rad = 1.2;  ///< Square pixels: the vertical field follows the aspect.
  double min_range_m = 0.1;         ///< Depth (z) nearer than this returns nothing.
  double max_range_m = 3.0;         ///< Depth (z) farther than this returns nothing.
  double noise_m = 0.001;           ///< Sigma of the Gaussian depth noise along each ray.
  double dropout_ratio = 0.02;      ///< Share of hit pixels that return NaN all the same.
  std::uint64_t seed = 1;           ///< Noise and dropout: the same seed, the same clouds.
};

/// The optical frame of a camera at `eye` looking at `target`, its image's x axis level
/// (perpendicular to world z, which must not be the viewing direction).
Eigen::Isometry3d cameraLookingAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

/// Renders surface samples, each a small disk ("splat"), into an organized cloud with a
/// z-buffer, so that only the surfaces nearest the camera are seen. The camera frame is the
/// optical one: z forward, x right, y down. A frame is rendered in three calls:
///
///   camera.beginFrame(world_from_camera);
///   const int sponge = camera.addSurface(sponge_points, sponge_normals, spacing);
///   camera.addSurface(floor_points, {}, floor_spacing);
///   camera.finishFrame();
///
/// after which points(), labels() and visible(sponge) describe it. After the first frame of
/// a given size and set of surfaces, a frame allocates nothing.
class VirtualCamera {
 public:
  static constexpr int kNoSurface = -1;

  /// @throw std::invalid_argument if the size, field of view, ranges, noise or dropout are
  /// out of range.
  explicit VirtualCamera(const VirtualCameraConfig& config);

  const VirtualCameraConfig& config() const { return config_; }
  double focalLengthPx() const { return focal_px_; }

  /// Clears the image; the camera's optical frame is at `world_from_camera`.
  void beginFrame(const Eigen::Isometry3d& world_from_camera);

  /// Splats `points` (world frame) as disks of `splat_radius_m`: about their spacing or a
  /// little more, so that neighbouring disks close the holes between the samples. With
  /// `normals` (one per point, unit, world frame) each disk lies in its tangent plane and a
  /// slanted surface gets the depth of the plane at every pixel; without (empty), each disk
  /// faces the camera at its sample's depth. Returns the surface's label.
  int addSurface(const std::vector<Eigen::Vector3d>& points,
                 const std::vector<Eigen::Vector3d>& normals, double splat_radius_m);

  /// Adds noise and dropout and decides which samples are visible.
  void finishFrame();

  /// width * height points in the camera frame, row by row; NaN where nothing was hit within
  /// range, or dropped.
  const std::vector<Eigen::Vector3f>& points() const { return points_; }
  /// The surface each point of points() comes from; kNoSurface where it is NaN.
  const std::vector<int>& labels() const { return labels_; }
  /// Per sample of surface `label`, 1 if the sample is on the front surface the camera
  /// sees: inside the image and range, facing the camera (with normals), and no nearer
  /// surface covers its pixel by more than its disk and the pixel's depth span. Geometry
  /// only: dropout and noise do not change it.
  const std::vector<std::uint8_t>& visible(int label) const { return surfaces_[label].visible; }

 private:
  /// What a surface's samples left behind for the visibility test.
  struct SurfaceRecord {
    std::vector<int> center_pixel;  ///< The pixel under each sample's centre, or -1.
    std::vector<double> depth_m;    ///< Each sample's depth (camera z).
    /// How much nearer than a sample its pixel's depth may be with the sample still seen;
    /// negative for a disk facing away, never seen.
    std::vector<double> depth_tolerance_m;
    std::vector<std::uint8_t> visible;
  };

  void splat(const Eigen::Vector3d& center, const Eigen::Vector3d* normal, double radius_m,
             int label);
  void markVisible(SurfaceRecord& surface) const;
  double gaussian();

  VirtualCameraConfig config_;
  double focal_px_;
  double center_u_px_;
  double center_v_px_;
  Eigen::Isometry3d camera_from_world_ = Eigen::Isometry3d::Identity();
  std::vector<double> depth_m_;  ///< The z-buffer before noise; +inf where nothing is hit.
  std::vector<int> labels_;
  std::vector<Eigen::Vector3f> points_;
  std::vector<SurfaceRecord> surfaces_;
  std::size_t surface_count_ = 0;
  std::mt19937_64 engine_;
};

}  // namespace deformable_collision
