#include "deformable_collision/ros/node_reconfigure.h"

namespace deformable_collision {
namespace {

/// dynamic_reconfigure's first call of a callback, with the values the server was given.
constexpr std::uint32_t kServerStart = ~0u;

/// Whether a kind of object has anything a reconfiguration may change.
bool hasMaterial(ObjectKind kind) {
  return kind == ObjectKind::kDynamic || kind == ObjectKind::kTracked;
}

}  // namespace

NodeReconfigure::NodeReconfigure(Scene& scene, NodeConfig& config, std::vector<ObjectSlot>& slots,
                                 CloudReader& reader)
    : scene_(scene), config_(config), slots_(slots), reader_(reader) {}

DeformableCollisionConfig NodeReconfigure::initialNodeConfig() const {
  DeformableCollisionConfig initial = DeformableCollisionConfig::__getDefault__();
  const SceneConfig& scene = config_.scene;
  initial.level = scene.cycle_budget_ms ? -1 : scene.level;
  initial.level_auto = scene.cycle_budget_ms.has_value();
  initial.cycle_budget_ms = scene.cycle_budget_ms.value_or(0.0);
  initial.contact_distance_m = scene.contact_distance_m;
  initial.friction = scene.friction;
  initial.markers_colliding_only = config_.markers_colliding_only;
  initial.force_marker_scale_m_per_n = config_.force_marker_scale_m_per_n;
  initial.register_iterations = scene.registration.iterations;
  initial.register_max_cloud_points = static_cast<int>(scene.registration.max_cloud_points);
  return initial;
}

ObjectMaterialConfig NodeReconfigure::initialObjectConfig(const ObjectParams& params) {
  ObjectMaterialConfig initial = ObjectMaterialConfig::__getDefault__();
  initial.stiffness = params.object.shape.stiffness;
  initial.damping = params.object.shape.damping;
  initial.contact_stiffness_n_per_m = params.object.contact_stiffness_n_per_m;
  return initial;
}

void NodeReconfigure::start(const ros::NodeHandle& handle) {
  const ros::NodeHandle reconfigure(handle, "reconfigure");
  node_current_ = initialNodeConfig();
  node_server_ = std::make_unique<dynamic_reconfigure::Server<DeformableCollisionConfig>>(
      node_mutex_, reconfigure);
  // The loaded config, not what an earlier run left on the parameter server, is the start.
  node_server_->updateConfig(node_current_);
  node_server_->setCallback(
      [this](DeformableCollisionConfig& c, std::uint32_t level) { onNode(c, level); });
  object_servers_.resize(slots_.size());
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    const ObjectParams& params = slots_[i].params;
    if (!hasMaterial(params.object.kind)) continue;
    ObjectServer& object = object_servers_[i];
    object.current = initialObjectConfig(params);
    object.mutex = std::make_unique<boost::recursive_mutex>();
    object.server = std::make_unique<dynamic_reconfigure::Server<ObjectMaterialConfig>>(
        *object.mutex, ros::NodeHandle(reconfigure, "objects/" + params.object.name));
    object.server->updateConfig(object.current);
    object.server->setCallback(
        [this, i](ObjectMaterialConfig& c, std::uint32_t level) { onObject(i, c, level); });
  }
}

void NodeReconfigure::onNode(DeformableCollisionConfig& requested, std::uint32_t level) {
  if (level == kServerStart) return;
  const std::string problem = nodeReconfigureProblem(requested, scene_.maxLevel());
  if (problem.empty()) {
    applyNode(requested);
    node_current_ = requested;
  } else {
    // The server publishes what the callback leaves: the old values.
    requested = node_current_;
  }
  count(problem.empty(), "reconfigure", problem);
}

void NodeReconfigure::applyNode(const DeformableCollisionConfig& requested) {
  applyToScene(scene_, requested, node_current_);
  config_.markers_colliding_only = requested.markers_colliding_only;
  config_.force_marker_scale_m_per_n = requested.force_marker_scale_m_per_n;
  reader_.setRegistrationTuning(requested.register_iterations,
                                static_cast<std::size_t>(requested.register_max_cloud_points),
                                requested.contact_distance_m);
}

void NodeReconfigure::onObject(std::size_t index, ObjectMaterialConfig& requested,
                               std::uint32_t level) {
  if (level == kServerStart) return;
  ObjectServer& object = object_servers_[index];
  const ObjectSlot& slot = slots_[index];
  const std::string problem =
      objectReconfigureProblem(requested, object.current, slot.params.object.kind);
  if (problem.empty()) {
    object.current = requested;
    reapply(slot);
  } else {
    requested = object.current;
  }
  count(problem.empty(), "reconfigure/objects/" + slot.params.object.name, problem);
}

void NodeReconfigure::reapply(const ObjectSlot& slot) {
  const std::size_t index = static_cast<std::size_t>(&slot - slots_.data());
  if (!slot.index || index >= object_servers_.size() || !object_servers_[index].server) return;
  applyMaterial(scene_, *slot.index, slot.params.object.kind, object_servers_[index].current);
}

void NodeReconfigure::count(bool accepted, const std::string& what, const std::string& problem) {
  if (accepted) {
    ++accepted_;
    ROS_INFO("%s: taken from the next cycle on", what.c_str());
  } else {
    ++refused_;
    ROS_WARN("%s refused, the old values kept: %s", what.c_str(), problem.c_str());
  }
}

}  // namespace deformable_collision
