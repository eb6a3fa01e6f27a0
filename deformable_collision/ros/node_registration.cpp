// The node's objects with on_cloud: register: their models from model_file, the
// registrations of their clouds (on the reader thread) and what ~stats says of them.
#include <stdexcept>

#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/deformable_collision_node.h"
#include "deformable_collision/ros/model_file.h"

namespace deformable_collision {
namespace {

/// At most one report per object that its clouds were held, in this period.
constexpr std::chrono::seconds kHeldReportPeriod(5);

}  // namespace

void DeformableCollisionNode::loadModels() {
  for (ObjectSlot& slot : slots_) {
    const ObjectParams& params = slot.params;
    if (params.model_file.empty()) continue;
    try {
      slot.model_points = readModelFile(params.model_file);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("object '" + params.object.name + "': " + e.what());
    }
    // A model in millimetres or another unit would be an object metres across.
    const std::string problem =
        farCoordinateProblem(slot.model_points, config_.max_coordinate_m, params.model_frame);
    if (!problem.empty()) {
      throw std::invalid_argument("object '" + params.object.name + "': model file '" +
                                  params.model_file + "': " + problem);
    }
    placeModel(slot);
  }
}

bool DeformableCollisionNode::placeModel(ObjectSlot& slot) {
  if (slot.model_points.empty()) return slot.index.has_value();
  if (!slot.params.robot_link.empty()) return placeLink(slot);
  const ObjectParams& params = slot.params;
  std::optional<Eigen::Isometry3d> pose = Eigen::Isometry3d::Identity();
  if (params.model_frame != config_.fixed_frame) {
    const CloudTransformLookup lookup =
        lookUpCloudTransform(tf_buffer_, config_.fixed_frame, params.model_frame, ros::Time(0));
    if (lookup.status != CloudTransformStatus::kFound) return false;
    pose = toIsometry(lookup.transform);
    if (!pose) {
      ROS_ERROR_THROTTLE(5.0, "object '%s': the pose of model_frame '%s' is not finite",
                         params.object.name.c_str(), params.model_frame.c_str());
      return false;
    }
  }
  std::vector<Eigen::Vector3d> placed = slot.model_points;
  for (Eigen::Vector3d& p : placed) p = *pose * p;
  // The file's points are kept until the object exists, so that a failure tries again.
  slot.index = scene_.addObject(params.object, std::move(placed));
  announceToReader(slot);
  const std::size_t count = slot.model_points.size();
  slot.model_points = {};
  ROS_INFO("object '%s': rest shape of %zu points from %s at the pose of '%s', %s",
           params.object.name.c_str(), count, params.model_file.c_str(), params.model_frame.c_str(),
           toString(params.object.kind));
  warnIfPorous(params.object.name, scene_.body(*slot.index).positions());
  return true;
}

bool DeformableCollisionNode::placeModels() {
  bool waiting = false;
  for (ObjectSlot& slot : slots_) {
    // The file's points are dropped once the object is made from them.
    placeModel(slot);
    waiting = waiting || !slot.model_points.empty();
  }
  return waiting;
}

void DeformableCollisionNode::announceToReader(ObjectSlot& slot) {
  // The reader registers the clouds on a copy of the object, which must exist before the
  // reader is told that the object does.
  if (slot.params.on_cloud == OnCloud::kRegister)
    slot.fitter.emplace(scene_.registrationFitter(*slot.index));
  slot.exists = true;
}

void DeformableCollisionNode::takeRegistration(ObjectSlot& slot, ReadCloud& cloud) {
  if (!cloud.registration) return;
  slot.registration = *cloud.registration;
  if (slot.registration.held) reportHeld(slot);
  if (cloud.fitted) scene_.observeRegistered(*slot.index, cloud.points, cloud.fit, cloud.fit_error);
}

void DeformableCollisionNode::shareNearPoints() {
  for (ObjectSlot& slot : slots_) {
    if (!slot.index || slot.params.on_cloud != OnCloud::kRegister) continue;
    scene_.pointsNearObject(*slot.index, near_points_);
    slot.near_points.put(near_points_);
  }
}

void DeformableCollisionNode::reportHeld(ObjectSlot& slot) {
  ++slot.clouds_held;
  ++slot.held_unreported;
  const auto now = Clock::now();
  if (slot.last_held_report && now - *slot.last_held_report < kHeldReportPeriod) return;
  const RegistrationReport& report = slot.registration;
  ROS_WARN(
      "object '%s' held where it was: its cloud on %s matched %zu of %zu thinned points "
      "within register/max_correspondence_m, fewer than register/min_match_ratio = %.2f "
      "(%zu clouds held since the last report)",
      slot.params.object.name.c_str(), slot.subscriber.getTopic().c_str(), report.used_points,
      report.used_points + report.rejected_points, config_.scene.registration.min_match_ratio,
      slot.held_unreported);
  slot.last_held_report = now;
  slot.held_unreported = 0;
}

void DeformableCollisionNode::fillRegistrationStats(Stats& stats) const {
  std::size_t entry = 0;
  for (const ObjectSlot& slot : slots_) {
    if (slot.params.on_cloud != OnCloud::kRegister) continue;
    if (stats.registrations.size() <= entry) stats.registrations.emplace_back();
    RegistrationStats& out = stats.registrations[entry++];
    const RegistrationReport& report = slot.registration;
    out.object = slot.params.object.name;
    out.held = report.held;
    out.cloud_points = static_cast<std::uint32_t>(report.cloud_points);
    out.used_points = static_cast<std::uint32_t>(report.used_points);
    out.rejected_points = static_cast<std::uint32_t>(report.rejected_points);
    out.excluded_points = static_cast<std::uint32_t>(report.excluded_points);
    out.mean_residual_m = report.mean_residual_m;
    out.max_residual_m = report.max_residual_m;
    const SurfaceError error = slot.index ? scene_.registrationError(*slot.index) : SurfaceError{};
    out.seen_error_m = error.seen_m;
    out.hidden_error_m = error.hidden_m;
    out.time_ms = report.time_ms;
    out.clouds_held = slot.clouds_held;
  }
}

}  // namespace deformable_collision
