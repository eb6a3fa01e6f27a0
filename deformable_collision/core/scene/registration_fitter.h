#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/registration/near_points_filter.h"
#include "deformable_collision/core/scene/tracked_fitter.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {

/// Registers a tracked object's unordered clouds on another thread than its scene's
/// (Scene::registrationFitter): a copy of the object's body and a registration of its own,
/// whose fits Scene::observeRegistered takes over in O(clusters). Each cloud carries on
/// from the fitter's last fit, as the object's own registration would: the object then
/// reaches the state that Scene::registerCloud of the same clouds gives it, bit for bit, as
/// long as every cloud goes through the fitter and it is given the points near the object
/// that the scene's registration would leave out (setPointsNearObject).
class RegistrationFitter {
 public:
  /// The other objects' points near this one (Scene::pointsNearObject), swapped in:
  /// `points_m` gets the former ones. The next clouds' points closer than the scene's
  /// contact distance to one of them are not taken for the object's.
  void setPointsNearObject(std::vector<Eigen::Vector3d>& points_m);

  /// Registers the model to the cloud in `points_m` (see Scene::registerCloud). Unless the
  /// report says `held`, `points_m` then holds the registered points (the object's size)
  /// and `fit` the clusters' sums and fits, to hand to Scene::observeRegistered; held,
  /// both are unchanged. Once it has held clouds and fits of these sizes, nothing is
  /// allocated.
  RegistrationReport fit(std::vector<Eigen::Vector3d>& points_m,
                         const std::optional<Eigen::Vector3d>& viewpoint_m, TrackedFit& fit);

  /// From the next cloud on: `iterations` rounds on the cloud thinned to `max_cloud_points`.
  /// @throw std::invalid_argument unless both are >= 1; nothing changes then.
  void setWorkPerCloud(int iterations, std::size_t max_cloud_points) {
    registration_.setWorkPerCloud(iterations, max_cloud_points);
  }
  /// Cloud points this close to the points near the object are left out, from the next
  /// points near the object on (the scene's contact distance, Scene::setContactDistance).
  /// @throw std::invalid_argument unless finite and > 0.
  void setContactDistance(double contact_distance_m);

 private:
  friend class Scene;
  RegistrationFitter(const ShapeMatchingBody& body, std::uint64_t rest_shape,
                     const RegistrationConfig& config, double contact_distance_m);

  ShapeMatchingBody body_;
  std::uint64_t rest_shape_;
  CloudRegistration registration_;
  NearPointsFilter near_points_;
  double contact_distance_m_;
};

}  // namespace deformable_collision
