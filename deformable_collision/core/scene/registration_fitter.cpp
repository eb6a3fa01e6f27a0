#include "deformable_collision/core/scene/registration_fitter.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace deformable_collision {

RegistrationFitter::RegistrationFitter(const ShapeMatchingBody& body, std::uint64_t rest_shape,
                                       const RegistrationConfig& config, double contact_distance_m)
    : body_(body.trackingCopy()),
      rest_shape_(rest_shape),
      registration_(config),
      contact_distance_m_(contact_distance_m) {}

void RegistrationFitter::setPointsNearObject(std::vector<Eigen::Vector3d>& points_m) {
  near_points_.reset(points_m, contact_distance_m_);
}

RegistrationReport RegistrationFitter::fit(std::vector<Eigen::Vector3d>& points_m,
                                           const std::optional<Eigen::Vector3d>& viewpoint_m,
                                           TrackedFit& fit) {
  const RegistrationReport report =
      registration_.registerCloud(body_, points_m, viewpoint_m, &near_points_);
  if (report.held) return report;
  // The registration reads the body's fits, never its points: the body may give its points
  // away for the cloud's buffer, and its next track() fills them again.
  points_m.resize(body_.pointCount());
  body_.giveTrackedState(points_m, fit.state);
  fit.rest_shape = rest_shape_;
  return report;
}

void RegistrationFitter::setContactDistance(double contact_distance_m) {
  if (!(contact_distance_m > 0.0) || !std::isfinite(contact_distance_m)) {
    throw std::invalid_argument("contact_distance_m = " + std::to_string(contact_distance_m) +
                                " must be finite and > 0");
  }
  contact_distance_m_ = contact_distance_m;
}

}  // namespace deformable_collision
