// The node's robot links (the `robot` block): their surfaces sampled from the robot
// description at start, each made a kinematic object once tf has its frame.
#include <stdexcept>

#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/deformable_collision_node.h"
#include "deformable_collision/ros/robot_links.h"

namespace deformable_collision {

namespace {

/// The robot description in parameter `param` of `handle`'s namespace; std::nullopt, with an
/// error naming the parameter, if it is not set or not a URDF.
std::optional<RobotLinks> readRobotDescription(const ros::NodeHandle& handle,
                                               const std::string& param) {
  std::string problem = " is not set or not text";
  std::string urdf_xml;
  if (handle.getParam(param, urdf_xml)) {
    try {
      return RobotLinks(urdf_xml);
    } catch (const std::invalid_argument& e) {
      problem = std::string(": ") + e.what();
    }
  }
  ROS_ERROR("robot: parameter '%s' (robot.description_param)%s; no robot link is an object",
            handle.resolveName(param).c_str(), problem.c_str());
  return std::nullopt;
}

}  // namespace

void DeformableCollisionNode::loadRobotLinks() {
  if (!config_.robot) return;
  const std::optional<RobotLinks> robot =
      readRobotDescription(node_handle_, config_.robot->description_param);
  if (!robot) return;
  const SurfaceSampling sampling{config_.robot->point_spacing_m, config_.max_points_per_object};
  for (ObjectSlot& slot : slots_) {
    if (slot.params.robot_link.empty()) continue;
    try {
      slot.model_points = robot->sampleSurface(slot.params.robot_link, sampling);
    } catch (const std::invalid_argument& e) {
      ROS_ERROR("%s; it is not an object", e.what());
    }
  }
}

std::optional<Eigen::Isometry3d> DeformableCollisionNode::linkPose(const ObjectSlot& slot) const {
  const ObjectParams& params = slot.params;
  const CloudTransformLookup lookup =
      lookUpCloudTransform(tf_buffer_, config_.fixed_frame, params.follow_frame, ros::Time(0));
  if (lookup.status != CloudTransformStatus::kFound) {
    ROS_WARN_DELAYED_THROTTLE(5.0, "robot link '%s' waits for tf from '%s' to '%s'",
                              params.robot_link.c_str(), params.follow_frame.c_str(),
                              config_.fixed_frame.c_str());
    return std::nullopt;
  }
  const std::optional<Eigen::Isometry3d> pose = toIsometry(lookup.transform);
  if (!pose) {
    ROS_ERROR_THROTTLE(5.0, "robot link '%s': the pose of its frame is not finite",
                       params.robot_link.c_str());
  }
  return pose;
}

bool DeformableCollisionNode::placeLink(ObjectSlot& slot) {
  const std::optional<Eigen::Isometry3d> pose = linkPose(slot);
  if (!pose) return false;
  const ObjectParams& params = slot.params;
  // The surface in the link's frame is the rest shape; the pose places it, as each cycle will.
  try {
    slot.index = scene_.addObject(params.object, std::move(slot.model_points));
  } catch (const std::exception& e) {
    ROS_ERROR("robot link '%s': %s; it is not an object", params.robot_link.c_str(), e.what());
  }
  slot.model_points = {};
  if (!slot.index) return false;
  scene_.setPose(*slot.index, *pose);
  slot.last_pose = *pose;
  slot.exists = true;
  const std::vector<Eigen::Vector3d>& points = scene_.body(*slot.index).restPositions();
  ROS_INFO("object '%s': robot link '%s', %zu surface points (spacing %.4f m), kinematic",
           params.object.name.c_str(), params.robot_link.c_str(), points.size(),
           config_.robot->point_spacing_m);
  warnIfPorous(params.object.name, points);
  return true;
}

}  // namespace deformable_collision
