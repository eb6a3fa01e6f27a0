// A tracked object's model fitted to a depth camera's cloud, here or on another thread
// (RegistrationFitter), without the cloud's points of the scene's other objects.
#include <stdexcept>

#include "deformable_collision/core/scene/detail/scene_object.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace {

/// @throw std::invalid_argument naming `object` unless it is tracked.
void requireRegistrable(const detail::SceneObject& object) {
  if (object.config.kind != ObjectKind::kTracked) {
    throw std::invalid_argument("object '" + object.config.name + "' is " +
                                toString(object.config.kind) +
                                ", only tracked objects are registered to clouds");
  }
}

}  // namespace

RegistrationReport Scene::registerCloud(std::size_t object,
                                        const std::vector<Eigen::Vector3d>& cloud_m,
                                        const std::optional<Eigen::Vector3d>& viewpoint_m) {
  Object& o = *objects_.at(object);
  requireRegistrable(o);
  if (!o.registration) o.registration.emplace(config_.registration);
  pointsNearObject(object, near_points_);
  o.near_points.reset(near_points_, config_.contact_distance_m);
  const RegistrationReport report =
      o.registration->registerCloud(o.body, cloud_m, viewpoint_m, &o.near_points);
  if (!report.held) {
    o.registration_error = report.surface_error;
    o.stale = true;
    ++stats_.objects_moved;
  }
  return report;
}

RegistrationFitter Scene::registrationFitter(std::size_t object) const {
  const Object& o = *objects_.at(object);
  requireRegistrable(o);
  return RegistrationFitter(o.body, o.rest_shape, config_.registration, config_.contact_distance_m);
}

void Scene::observeRegistered(std::size_t object, std::vector<Eigen::Vector3d>& points_m,
                              const TrackedFit& fit, const SurfaceError& error) {
  observeFitted(object, points_m, fit);
  objects_[object]->registration_error = error;
}

const SurfaceError& Scene::registrationError(std::size_t object) const {
  return objects_.at(object)->registration_error;
}

void Scene::pointsNearObject(std::size_t object, std::vector<Eigen::Vector3d>& points_m) {
  Object& o = *objects_.at(object);
  points_m.clear();
  if (!config_.registration.exclude_near_other_objects || objects_.size() < 2) return;
  // The others' hierarchies where they are now: a kinematic object posed since the last
  // cycle is where its pose put it.
  refreshStaleTrees();
  const Sphere& root = o.tree.current(0).sphere;
  const double reach = config_.registration.iterations * config_.registration.max_correspondence_m +
                       config_.contact_distance_m;
  for (std::size_t other = 0; other < objects_.size(); ++other) {
    if (other != object) appendPointsWithin(other, root.center, root.radius + reach, points_m);
  }
}

void Scene::appendPointsWithin(std::size_t object, const Eigen::Vector3d& center_m, double radius_m,
                               std::vector<Eigen::Vector3d>& points_m) {
  SphereTree& tree = objects_[object]->tree;
  const auto& positions = objects_[object]->body.positions();
  proximity_stack_.clear();
  proximity_stack_.push_back(0);
  while (!proximity_stack_.empty()) {
    const std::uint32_t node = proximity_stack_.back();
    proximity_stack_.pop_back();
    const NodeState& state = tree.current(node);
    if ((center_m - state.sphere.center).norm() > state.sphere.radius + radius_m) continue;
    if (!state.isLeaf()) {
      for (std::uint32_t child = 0; child < state.child_count; ++child) {
        proximity_stack_.push_back(state.first_child + child);
      }
      continue;
    }
    for (std::uint32_t k = 0; k < state.point_count; ++k) {
      const Eigen::Vector3d& point = positions[tree.pointIndices()[state.first_point + k]];
      if ((point - center_m).norm() <= radius_m) points_m.push_back(point);
    }
  }
}

}  // namespace deformable_collision
