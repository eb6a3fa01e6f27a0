// A tracked object's model fitted to a depth camera's cloud, without the cloud's points of
// the scene's other objects.
#include <stdexcept>

#include "deformable_collision/core/scene/detail/scene_object.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// Leaves out the cloud points within the contact distance of another object: a camera's
/// cloud of a squeezed object holds the jaws squeezing it, whose faces lie about where the
/// object's hidden faces were, close enough to be taken for them.
struct Scene::NearOtherObjects final : CloudPointFilter {
  NearOtherObjects(Scene& scene, std::size_t object) : scene(scene), object(object) {}
  bool excludes(const Eigen::Vector3d& point_m) override {
    return scene.nearOtherObject(object, point_m, scene.config_.contact_distance_m);
  }
  Scene& scene;
  std::size_t object;
};

RegistrationReport Scene::registerCloud(std::size_t object,
                                        const std::vector<Eigen::Vector3d>& cloud_m,
                                        const std::optional<Eigen::Vector3d>& viewpoint_m) {
  Object& o = *objects_.at(object);
  if (o.config.kind != ObjectKind::kTracked) {
    throw std::invalid_argument("object '" + o.config.name + "' is " + toString(o.config.kind) +
                                ", only tracked objects are registered to clouds");
  }
  if (!o.registration) o.registration.emplace(config_.registration);
  NearOtherObjects near_other_objects(*this, object);
  const bool filtered = config_.registration.exclude_near_other_objects && objects_.size() > 1;
  // The others' hierarchies where they are now: a kinematic object posed since the last
  // cycle is where its pose put it.
  if (filtered) refreshStaleTrees();
  const RegistrationReport report = o.registration->registerCloud(
      o.body, cloud_m, viewpoint_m, filtered ? &near_other_objects : nullptr);
  if (!report.held) {
    o.registration_residual_m = report.mean_residual_m;
    o.stale = true;
    ++stats_.objects_moved;
  }
  return report;
}

bool Scene::nearOtherObject(std::size_t object, const Eigen::Vector3d& point_m, double distance_m) {
  const double squared_distance = distance_m * distance_m;
  for (std::size_t other = 0; other < objects_.size(); ++other) {
    if (other == object) continue;
    SphereTree& tree = objects_[other]->tree;
    const auto& positions = objects_[other]->body.positions();
    proximity_stack_.clear();
    proximity_stack_.push_back(0);
    while (!proximity_stack_.empty()) {
      const std::uint32_t node = proximity_stack_.back();
      proximity_stack_.pop_back();
      const NodeState& state = tree.current(node);
      if ((point_m - state.sphere.center).norm() > state.sphere.radius + distance_m) continue;
      if (!state.isLeaf()) {
        for (std::uint32_t child = 0; child < state.child_count; ++child) {
          proximity_stack_.push_back(state.first_child + child);
        }
        continue;
      }
      for (std::uint32_t k = 0; k < state.point_count; ++k) {
        const std::uint32_t point = tree.pointIndices()[state.first_point + k];
        if ((positions[point] - point_m).squaredNorm() < squared_distance) return true;
      }
    }
  }
  return false;
}

}  // namespace deformable_collision
