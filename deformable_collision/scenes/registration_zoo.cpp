#include "deformable_collision/scenes/registration_zoo.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace deformable_collision {
namespace {

/// Disk radii over sample spacing: random samples need a little more than a grid.
constexpr double kSplatRatio = 1.5;
/// The camera looks at the object from above its -y side, a little to its +x end.
const Eigen::Vector3d kCameraDirection = Eigen::Vector3d(0.25, -0.8, 0.55).normalized();
/// An outlier's depth is the true one times a factor this far from 1: a flying pixel.
constexpr double kOutlierDepthSpread = 0.15;

double unit(std::mt19937_64& engine) { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }

/// 0 to 1 over the motion, eased at both ends; 1 after it.
double amplitudeAt(int frame, int motion_frames) {
  const double t = std::min(1.0, (frame + 1.0) / motion_frames);
  return t * t * (3.0 - 2.0 * t);
}

}  // namespace

const char* zooDeformationName(ZooDeformation deformation) {
  switch (deformation) {
    case ZooDeformation::kSqueeze:
      return "squeeze";
    case ZooDeformation::kBend:
      return "bend";
    case ZooDeformation::kTwist:
      return "twist";
    case ZooDeformation::kDent:
      return "dent";
    case ZooDeformation::kCombined:
      return "combined";
  }
  return "?";
}

RegistrationZooCase::RegistrationZooCase(ZooShape shape, ZooDeformation deformation,
                                         const RegistrationZooConfig& config)
    : shape_(shape),
      deformation_(deformation),
      config_(config),
      surface_(zooShapeSurface(shape, config.points, config.seed)),
      camera_(config.camera),
      world_from_camera_(
          cameraLookingAt(config.camera_distance_m * kCameraDirection, Eigen::Vector3d::Zero())),
      outliers_(config.seed + 1) {
  if (config.motion_frames < 1 || config.rest_frames < 0) {
    throw std::invalid_argument(
        "RegistrationZooCase: motion_frames must be >= 1, rest_frames >= 0");
  }
  half_extent_m_.setZero();
  for (const auto& p : surface_.points) half_extent_m_ = half_extent_m_.cwiseMax(p.cwiseAbs());
  // The dent is pressed into the top, a little off the middle along x.
  const double x = 0.3 * half_extent_m_.x();
  double top = -std::numeric_limits<double>::infinity();
  for (const auto& p : surface_.points) {
    if (std::abs(p.x() - x) < 0.1 * half_extent_m_.x() &&
        std::abs(p.y()) < 0.5 * half_extent_m_.y())
      top = std::max(top, p.z());
  }
  dent_centre_m_ = Eigen::Vector3d(x, 0.0, std::isfinite(top) ? top : half_extent_m_.z());
}

Eigen::Vector3d RegistrationZooCase::squeezed(const Eigen::Vector3d& p, double ratio) const {
  const double across = std::exp(-std::pow(p.x() / (0.6 * half_extent_m_.x()), 2));
  return {p.x(), p.y() * (1.0 - ratio * across), p.z() * (1.0 + 0.5 * ratio * across)};
}

Eigen::Vector3d RegistrationZooCase::bent(const Eigen::Vector3d& p, double angle_rad) const {
  // The long axis bent into an arc that turns by angle_rad from end to end, ends down.
  const double curvature = angle_rad / (2.0 * half_extent_m_.x());
  if (std::abs(curvature) < 1e-12) return p;
  const double radius = 1.0 / curvature;
  const double phi = curvature * p.x();
  return {(radius + p.z()) * std::sin(phi), p.y(), (radius + p.z()) * std::cos(phi) - radius};
}

Eigen::Vector3d RegistrationZooCase::twisted(const Eigen::Vector3d& p, double angle_rad) const {
  const double angle = 0.5 * angle_rad * p.x() / half_extent_m_.x();
  const double c = std::cos(angle), s = std::sin(angle);
  return {p.x(), c * p.y() - s * p.z(), s * p.y() + c * p.z()};
}

Eigen::Vector3d RegistrationZooCase::dented(const Eigen::Vector3d& p, double depth_m) const {
  const double sigma = std::max(0.02, 0.2 * half_extent_m_.x());
  const double weight = std::exp(-(p - dent_centre_m_).squaredNorm() / (2.0 * sigma * sigma));
  return p - depth_m * weight * Eigen::Vector3d::UnitZ();
}

Eigen::Vector3d RegistrationZooCase::deformed(const Eigen::Vector3d& p, double amplitude) const {
  const RegistrationZooConfig& c = config_;
  switch (deformation_) {
    case ZooDeformation::kSqueeze:
      return squeezed(p, amplitude * c.squeeze_ratio);
    case ZooDeformation::kBend:
      return bent(p, amplitude * c.bend_rad);
    case ZooDeformation::kTwist:
      return twisted(p, amplitude * c.twist_rad);
    case ZooDeformation::kDent:
      return dented(p, amplitude * c.dent_m);
    case ZooDeformation::kCombined: {
      const Eigen::Vector3d shaped = bent(
          twisted(squeezed(p, 0.5 * amplitude * c.squeeze_ratio), 0.5 * amplitude * c.twist_rad),
          0.5 * amplitude * c.bend_rad);
      return Eigen::AngleAxisd(amplitude * c.carry_turn_rad, Eigen::Vector3d::UnitZ()) * shaped +
             amplitude * c.carry_m;
    }
  }
  return p;
}

Eigen::Vector3d RegistrationZooCase::deformedNormal(std::size_t i, double amplitude) const {
  constexpr double kStepM = 1e-6;
  const Eigen::Vector3d& p = surface_.points[i];
  Eigen::Matrix3d jacobian;
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d step = kStepM * Eigen::Vector3d::Unit(axis);
    jacobian.col(axis) =
        (deformed(p + step, amplitude) - deformed(p - step, amplitude)) / (2 * kStepM);
  }
  return (jacobian.inverse().transpose() * surface_.normals[i]).normalized();
}

void RegistrationZooCase::render(int frame) {
  const double amplitude = amplitudeAt(frame, config_.motion_frames);
  const std::size_t n = surface_.points.size();
  truth_.resize(n);
  normals_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    truth_[i] = deformed(surface_.points[i], amplitude);
    normals_[i] = deformedNormal(i, amplitude);
  }
  camera_.beginFrame(world_from_camera_);
  label_ = camera_.addSurface(truth_, normals_, kSplatRatio * surface_.spacing_m);
  camera_.finishFrame();
  addOutliers();
}

void RegistrationZooCase::addOutliers() {
  cloud_.clear();
  for (const Eigen::Vector3f& p : camera_.points()) {
    if (!p.allFinite()) continue;
    double scale = 1.0;
    if (unit(outliers_) < config_.outlier_ratio) {
      scale += kOutlierDepthSpread * (2.0 * unit(outliers_) - 1.0);
    }
    cloud_.push_back(world_from_camera_ * (scale * p.cast<double>()));
  }
}

const std::vector<std::uint8_t>& RegistrationZooCase::groundTruthVisible() const {
  return camera_.visible(label_);
}

ZooErrors RegistrationZooCase::score(const std::vector<Eigen::Vector3d>& positions) const {
  ZooErrors e;
  std::size_t seen = 0, hidden = 0;
  const auto& visible = groundTruthVisible();
  for (std::size_t i = 0; i < truth_.size(); ++i) {
    const Eigen::Vector3d error = positions[i] - truth_[i];
    const double off = std::abs(error.dot(normals_[i]));
    if (visible[i]) {
      e.seen_m += error.norm(), e.seen_off_surface_m += off, ++seen;
    } else {
      e.hidden_m += error.norm(), e.hidden_off_surface_m += off, ++hidden;
    }
  }
  const double seen_count = std::max<std::size_t>(seen, 1);
  const double hidden_count = std::max<std::size_t>(hidden, 1);
  e.seen_m /= seen_count, e.seen_off_surface_m /= seen_count;
  e.hidden_m /= hidden_count, e.hidden_off_surface_m /= hidden_count;
  return e;
}

}  // namespace deformable_collision
