#include "deformable_collision/scenes/virtual_camera.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace deformable_collision {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
/// A disk seen more edge-on than this (cosine between its normal and the ray) is drawn
/// facing the camera: its plane would put depths far from the sample.
constexpr double kGrazingCosine = 0.1;

/// Uniform in [0, 1) from the top 53 bits, identical on every standard library.
double unitInterval(std::mt19937_64& engine) {
  return static_cast<double>(engine() >> 11) * 0x1.0p-53;
}

/// The focal length in pixels of a checked configuration.
double validatedFocalLengthPx(const VirtualCameraConfig& c) {
  const bool valid = c.width_px > 0 && c.height_px > 0 && c.width_px <= 8192 &&
                     c.height_px <= 8192 && c.horizontal_fov_rad > 0.0 &&
                     c.horizontal_fov_rad < 3.0 && c.min_range_m > 0.0 &&
                     c.max_range_m > c.min_range_m && c.noise_m >= 0.0 && c.noise_m < 1.0 &&
                     c.dropout_ratio >= 0.0 && c.dropout_ratio <= 1.0;
  if (!valid) {
    throw std::invalid_argument(
        "VirtualCamera: need 0 < width_px, height_px <= 8192, horizontal_fov_rad in (0, 3), "
        "0 < min_range_m < max_range_m, noise_m in [0, 1) and dropout_ratio in [0, 1]; got " +
        std::to_string(c.width_px) + " x " + std::to_string(c.height_px) + ", fov " +
        std::to_string(c.horizontal_fov_rad) + ", range " + std::to_string(c.min_range_m) + " .. " +
        std::to_string(c.max_range_m) + ", noise " + std::to_string(c.noise_m) + ", dropout " +
        std::to_string(c.dropout_ratio));
  }
  return 0.5 * c.width_px / std::tan(0.5 * c.horizontal_fov_rad);
}

}  // namespace

Eigen::Isometry3d cameraLookingAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d forward = (target - eye).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = right;
  pose.linear().col(1) = forward.cross(right);
  pose.linear().col(2) = forward;
  pose.translation() = eye;
  return pose;
}

VirtualCamera::VirtualCamera(const VirtualCameraConfig& config)
    : config_(config),
      focal_px_(validatedFocalLengthPx(config)),
      center_u_px_(0.5 * config.width_px - 0.5),
      center_v_px_(0.5 * config.height_px - 0.5),
      engine_(config.seed) {
  const std::size_t pixels = static_cast<std::size_t>(config.width_px) * config.height_px;
  depth_m_.assign(pixels, kInfinity);
  labels_.assign(pixels, kNoSurface);
  points_.assign(pixels, Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
}

void VirtualCamera::beginFrame(const Eigen::Isometry3d& world_from_camera) {
  camera_from_world_ = world_from_camera.inverse();
  std::fill(depth_m_.begin(), depth_m_.end(), kInfinity);
  std::fill(labels_.begin(), labels_.end(), kNoSurface);
  surface_count_ = 0;
}

int VirtualCamera::addSurface(const std::vector<Eigen::Vector3d>& points,
                              const std::vector<Eigen::Vector3d>& normals, double splat_radius_m) {
  if (!normals.empty() && normals.size() != points.size()) {
    throw std::invalid_argument("VirtualCamera::addSurface: " + std::to_string(normals.size()) +
                                " normals for " + std::to_string(points.size()) + " points");
  }
  if (!(splat_radius_m > 0.0)) {
    throw std::invalid_argument("VirtualCamera::addSurface: splat_radius_m must be > 0");
  }
  if (surface_count_ == surfaces_.size()) surfaces_.emplace_back();
  const int label = static_cast<int>(surface_count_++);
  SurfaceRecord& surface = surfaces_[label];
  surface.center_pixel.resize(points.size());
  surface.depth_m.resize(points.size());
  surface.depth_tolerance_m.resize(points.size());
  surface.visible.resize(points.size());
  const Eigen::Matrix3d rotation = camera_from_world_.linear();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d center = camera_from_world_ * points[i];
    surface.depth_m[i] = center.z();
    surface.center_pixel[i] = -1;
    if (!(center.z() >= config_.min_range_m && center.z() <= config_.max_range_m)) continue;
    const long u = std::lround(focal_px_ * center.x() / center.z() + center_u_px_);
    const long v = std::lround(focal_px_ * center.y() / center.z() + center_v_px_);
    if (u >= 0 && v >= 0 && u < config_.width_px && v < config_.height_px) {
      surface.center_pixel[i] = static_cast<int>(v * config_.width_px + u);
    }
    // Neighbours cover a sample's pixel too, at depths that differ by about the disk and,
    // on a slanted surface, by the slope across a disk and the pixel's footprint.
    const double footprint_m = center.z() / focal_px_;
    if (normals.empty()) {
      surface.depth_tolerance_m[i] = splat_radius_m + footprint_m;
      splat(center, nullptr, splat_radius_m, label);
      continue;
    }
    // The back of a closed surface is hidden by its front; its disks, drawn, would stick
    // out in front of the edges where the two meet.
    const Eigen::Vector3d normal = rotation * normals[i];
    const double facing = -normal.dot(center.normalized());
    if (facing <= 0.0) {
      surface.depth_tolerance_m[i] = -1.0;
      continue;
    }
    const double slope =
        std::sqrt(1.0 - std::min(1.0, facing * facing)) / std::max(facing, kGrazingCosine);
    surface.depth_tolerance_m[i] =
        splat_radius_m + slope * (splat_radius_m + M_SQRT1_2 * footprint_m);
    splat(center, &normal, splat_radius_m, label);
  }
  return label;
}

void VirtualCamera::splat(const Eigen::Vector3d& center, const Eigen::Vector3d* normal,
                          double radius_m, int label) {
  const double u = focal_px_ * center.x() / center.z() + center_u_px_;
  const double v = focal_px_ * center.y() / center.z() + center_v_px_;
  const double radius_px = focal_px_ * radius_m / center.z();
  const long center_u = std::lround(u), center_v = std::lround(v);
  // The pixel under the centre always, so that a sample far away still shows.
  const long u_begin = std::max(0L, std::min(center_u, std::lround(std::ceil(u - radius_px))));
  const long u_end =
      std::min(config_.width_px - 1L, std::max(center_u, std::lround(std::floor(u + radius_px))));
  const long v_begin = std::max(0L, std::min(center_v, std::lround(std::ceil(v - radius_px))));
  const long v_end =
      std::min(config_.height_px - 1L, std::max(center_v, std::lround(std::floor(v + radius_px))));
  for (long pv = v_begin; pv <= v_end; ++pv) {
    for (long pu = u_begin; pu <= u_end; ++pu) {
      const bool under_center = pu == center_u && pv == center_v;
      if (!under_center && (pu - u) * (pu - u) + (pv - v) * (pv - v) > radius_px * radius_px) {
        continue;
      }
      double depth = center.z();
      if (normal) {
        const Eigen::Vector3d ray((pu - center_u_px_) / focal_px_, (pv - center_v_px_) / focal_px_,
                                  1.0);
        const double facing = normal->dot(ray);
        if (std::abs(facing) > kGrazingCosine * ray.norm()) {
          // Where the pixel's ray meets the disk's plane; outside the disk, not this splat's.
          depth = normal->dot(center) / facing;
          if ((depth * ray - center).squaredNorm() > radius_m * radius_m && !under_center) continue;
        }
      }
      const std::size_t pixel = static_cast<std::size_t>(pv * config_.width_px + pu);
      if (depth >= config_.min_range_m && depth <= config_.max_range_m && depth < depth_m_[pixel]) {
        depth_m_[pixel] = depth;
        labels_[pixel] = label;
      }
    }
  }
}

void VirtualCamera::finishFrame() {
  for (std::size_t k = 0; k < surface_count_; ++k) markVisible(surfaces_[k]);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t pixel = 0; pixel < depth_m_.size(); ++pixel) {
    if (depth_m_[pixel] == kInfinity) {
      points_[pixel].setConstant(nan);
      continue;
    }
    if (config_.dropout_ratio > 0.0 && unitInterval(engine_) < config_.dropout_ratio) {
      points_[pixel].setConstant(nan);
      labels_[pixel] = kNoSurface;
      continue;
    }
    const long u = static_cast<long>(pixel % config_.width_px);
    const long v = static_cast<long>(pixel / config_.width_px);
    const Eigen::Vector3d point =
        depth_m_[pixel] *
        Eigen::Vector3d((u - center_u_px_) / focal_px_, (v - center_v_px_) / focal_px_, 1.0);
    const double along_ray_m = config_.noise_m > 0.0 ? config_.noise_m * gaussian() : 0.0;
    points_[pixel] = (point * (1.0 + along_ray_m / point.norm())).cast<float>();
  }
}

void VirtualCamera::markVisible(SurfaceRecord& surface) const {
  for (std::size_t i = 0; i < surface.visible.size(); ++i) {
    const int pixel = surface.center_pixel[i];
    surface.visible[i] = pixel >= 0 && surface.depth_tolerance_m[i] >= 0.0 &&
                         depth_m_[pixel] >= surface.depth_m[i] - surface.depth_tolerance_m[i];
  }
}

double VirtualCamera::gaussian() {
  // Box-Muller on the library-independent uniforms: the same noise on every platform.
  const double radius = std::sqrt(-2.0 * std::log(1.0 - unitInterval(engine_)));
  return radius * std::cos(2.0 * M_PI * unitInterval(engine_));
}

}  // namespace deformable_collision
