#include "deformable_collision/scenes/deforming_sponge.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace deformable_collision {
namespace {

/// Uniform in [0, 1) from the top 53 bits, identical on every standard library.
double unitInterval(std::mt19937_64& engine) {
  return static_cast<double>(engine() >> 11) * 0x1.0p-53;
}

double symmetricUnit(std::mt19937_64& engine) { return 2.0 * unitInterval(engine) - 1.0; }

/// Finite differences of this step resolve the deformation's Jacobian to about 1e-9.
constexpr double kJacobianStepM = 1e-6;

void requireConfig(const DeformingSpongeConfig& c) {
  const bool valid =
      (c.size_m.array() > 0.0).all() && c.corner_radius_m >= 0.0 &&
      2.0 * c.corner_radius_m < c.size_m.minCoeff() && c.points >= 100 && c.jaw_length_m > 0.0 &&
      c.jaw_length_m < c.size_m.x() && c.jaw_thickness_m > 0.0 && c.max_squeeze_ratio >= 0.0 &&
      c.max_squeeze_ratio < 0.9 && std::abs(c.max_bend_rad) < M_PI &&
      std::abs(c.max_twist_rad) < M_PI && c.bulge_ratio >= 0.0 && c.bulge_ratio <= 1.0;
  if (!valid) {
    throw std::invalid_argument(
        "DeformingSponge: need positive sizes, 0 <= corner_radius_m < half the smallest size, "
        "points >= 100 (got " +
        std::to_string(c.points) +
        "), 0 < jaw_length_m < length, "
        "jaw_thickness_m > 0, max_squeeze_ratio in [0, 0.9), |angles| < pi, bulge_ratio in [0, 1]");
  }
}

}  // namespace

DeformingSponge::DeformingSponge(const DeformingSpongeConfig& config) : config_(config) {
  requireConfig(config_);
  sampleSurface();
}

void DeformingSponge::sampleSurface() {
  // The rounded box is the inner box grown by the corner radius: flat faces, quarter
  // cylinders along the edges and sphere octants at the corners, each drawn by its area.
  const double r = config_.corner_radius_m;
  const Eigen::Vector3d inner = 0.5 * config_.size_m - Eigen::Vector3d::Constant(r);
  const Eigen::Vector3d face_area(4 * inner.y() * inner.z(), 4 * inner.x() * inner.z(),
                                  4 * inner.x() * inner.y());
  const Eigen::Vector3d edge_area = 4.0 * M_PI * r * inner;  // the four edges along each axis
  const double corner_area = 4.0 * M_PI * r * r;
  const double total_area = 2.0 * face_area.sum() + edge_area.sum() + corner_area;
  sample_spacing_m_ = std::sqrt(total_area / static_cast<double>(config_.points));

  std::mt19937_64 engine(config_.seed);
  rest_points_.resize(config_.points);
  rest_normals_.resize(config_.points);
  for (std::size_t i = 0; i < config_.points; ++i) {
    double pick = unitInterval(engine) * total_area;
    Eigen::Vector3d center(symmetricUnit(engine), symmetricUnit(engine), symmetricUnit(engine));
    center = center.cwiseProduct(inner);
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    int axis = 0;
    while (axis < 2 && pick >= 2.0 * face_area[axis]) pick -= 2.0 * face_area[axis++];
    if (pick < 2.0 * face_area[axis]) {
      const double side = pick < face_area[axis] ? -1.0 : 1.0;
      normal[axis] = side;
      center[axis] = side * inner[axis];
    } else {
      pick -= 2.0 * face_area[axis];
      axis = 0;
      while (axis < 2 && pick >= edge_area[axis]) pick -= edge_area[axis++];
      if (pick < edge_area[axis]) {
        // Around an edge along `axis`: a direction in the plane of the other two.
        const double angle = 2.0 * M_PI * unitInterval(engine);
        const int b = (axis + 1) % 3, c = (axis + 2) % 3;
        normal[b] = std::cos(angle);
        normal[c] = std::sin(angle);
        center[b] = std::copysign(inner[b], normal[b]);
        center[c] = std::copysign(inner[c], normal[c]);
      } else {
        const double z = symmetricUnit(engine), angle = 2.0 * M_PI * unitInterval(engine);
        const double planar = std::sqrt(1.0 - z * z);
        normal = Eigen::Vector3d(planar * std::cos(angle), planar * std::sin(angle), z);
        for (int k = 0; k < 3; ++k) center[k] = std::copysign(inner[k], normal[k]);
      }
    }
    rest_points_[i] = center + r * normal;
    rest_normals_[i] = normal;
  }
}

SpongeDeformation DeformingSponge::deformationAt(double phase) const {
  const double amount = 0.5 * (1.0 - std::cos(2.0 * M_PI * (phase - std::floor(phase))));
  return {config_.max_squeeze_ratio * amount, config_.max_bend_rad * amount,
          config_.max_twist_rad * amount};
}

Eigen::Vector3d DeformingSponge::deformed(const Eigen::Vector3d& rest,
                                          const SpongeDeformation& deformation) const {
  const double held_half_length = 0.5 * config_.jaw_length_m;
  const double free_length = 0.5 * config_.size_m.x() - held_half_length;
  const double side = rest.x() < 0.0 ? -1.0 : 1.0;
  const double beyond = std::max(0.0, std::abs(rest.x()) - held_half_length);

  // Squeezed fully between the jaws, fading over half the free length beyond them.
  const double fade = beyond / (0.5 * free_length);
  const double squeeze = deformation.squeeze_ratio * std::exp(-fade * fade);
  const double y = rest.y() * (1.0 - squeeze);
  const double z = rest.z() * (1.0 + config_.bulge_ratio * squeeze);
  if (beyond == 0.0) return Eigen::Vector3d(rest.x(), y, z);

  // Each free end is an arc turning by half the bend angle; the part between the jaws is
  // straight.
  const double curvature = 0.5 * deformation.bend_rad / free_length;
  const double turn = curvature * beyond;
  double along = beyond, drop = 0.5 * curvature * beyond * beyond;
  if (std::abs(turn) > 1e-9) {
    along = std::sin(turn) / curvature;
    drop = (1.0 - std::cos(turn)) / curvature;
  }
  const Eigen::Vector3d centerline(side * (held_half_length + along), 0.0, -drop);
  const double heading = -side * turn;
  const Eigen::Vector3d up(-std::sin(heading), 0.0, std::cos(heading));

  const double twist = side * deformation.twist_rad * beyond / free_length;
  const double c = std::cos(twist), s = std::sin(twist);
  return centerline + Eigen::Vector3d(0.0, c * y - s * z, 0.0) + (s * y + c * z) * up;
}

void DeformingSponge::positions(const SpongeDeformation& deformation,
                                std::vector<Eigen::Vector3d>& positions) const {
  positions.resize(rest_points_.size());
  for (std::size_t i = 0; i < rest_points_.size(); ++i) {
    positions[i] = deformed(rest_points_[i], deformation);
  }
}

void DeformingSponge::normals(const SpongeDeformation& deformation,
                              std::vector<Eigen::Vector3d>& normals) const {
  // A normal maps with the inverse transpose of the deformation's Jacobian.
  normals.resize(rest_points_.size());
  for (std::size_t i = 0; i < rest_points_.size(); ++i) {
    Eigen::Matrix3d jacobian;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d step = kJacobianStepM * Eigen::Vector3d::Unit(k);
      jacobian.col(k) = (deformed(rest_points_[i] + step, deformation) -
                         deformed(rest_points_[i] - step, deformation)) /
                        (2.0 * kJacobianStepM);
    }
    normals[i] = (jacobian.inverse().transpose() * rest_normals_[i]).normalized();
  }
}

Eigen::Isometry3d DeformingSponge::jawPose(JawSide side,
                                           const SpongeDeformation& deformation) const {
  const double sign = side == JawSide::kLeft ? -1.0 : 1.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation().y() = sign * (0.5 * config_.size_m.y() * (1.0 - deformation.squeeze_ratio) +
                                   0.5 * config_.jaw_thickness_m);
  return pose;
}

Eigen::Vector3d DeformingSponge::jawHalfExtents() const {
  const double bulged_height =
      config_.size_m.z() * (1.0 + config_.bulge_ratio * config_.max_squeeze_ratio);
  return Eigen::Vector3d(0.5 * config_.jaw_length_m, 0.5 * config_.jaw_thickness_m,
                         0.5 * bulged_height + 0.01);
}

std::vector<Eigen::Vector3d> DeformingSponge::jawSurfacePoints(double spacing_m) const {
  if (!(spacing_m > 0.0)) throw std::invalid_argument("jawSurfacePoints: spacing_m must be > 0");
  const Eigen::Vector3d half = jawHalfExtents();
  Eigen::Vector3i steps;
  for (int k = 0; k < 3; ++k)
    steps[k] = std::max(1, static_cast<int>(std::ceil(2 * half[k] / spacing_m)));
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i <= steps.x(); ++i) {
    for (int j = 0; j <= steps.y(); ++j) {
      for (int k = 0; k <= steps.z(); ++k) {
        const bool on_face =
            i == 0 || j == 0 || k == 0 || i == steps.x() || j == steps.y() || k == steps.z();
        if (!on_face) continue;
        const Eigen::Vector3d unit(double(i) / steps.x(), double(j) / steps.y(),
                                   double(k) / steps.z());
        points.push_back((2.0 * unit - Eigen::Vector3d::Ones()).cwiseProduct(half));
      }
    }
  }
  return points;
}

}  // namespace deformable_collision
