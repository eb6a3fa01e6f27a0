#pragma once

#include <Eigen/Geometry>
#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <tf2/buffer_core.h>

#include <optional>
#include <string>
#include <vector>

namespace deformable_collision {

/// Whether a cloud's transform was found and, if not, whether it may still come.
enum class CloudTransformStatus {
  kFound,
  kUnknownFrame,  ///< tf has never heard of the cloud's frame: no transform names it.
  kNotYet,        ///< The frame is known, but not at this stamp or not yet linked to the target.
};

struct CloudTransformLookup {
  CloudTransformStatus status = CloudTransformStatus::kNotYet;
  geometry_msgs::Transform transform;  ///< Only when kFound.
  std::string error;                   ///< tf's own words when not found.
};

/// The transform from `source_frame` (a cloud's) to `target_frame` at `stamp`. Only the
/// source frame's absence makes it kUnknownFrame: a target frame tf does not know yet is a
/// tree still filling, which every cloud waits for alike.
CloudTransformLookup lookUpCloudTransform(const tf2::BufferCore& buffer,
                                          const std::string& target_frame,
                                          const std::string& source_frame, const ros::Time& stamp);

/// The transform as an isometry; std::nullopt unless it is finite with a unit-length
/// (after normalisation) rotation.
std::optional<Eigen::Isometry3d> toIsometry(const geometry_msgs::Transform& transform);

/// `pose` as tf's transform from `parent` to `child` at `stamp`.
geometry_msgs::TransformStamped toTransformStamped(const Eigen::Isometry3d& pose,
                                                   const ros::Time& stamp,
                                                   const std::string& parent,
                                                   const std::string& child);

/// Why a point lies implausibly far from the origin of `frame`: the first coordinate of
/// `points` beyond `bound_m` in magnitude, or empty if none is. Unobserved points (NaN in
/// every coordinate, a tracked cloud's holes) have no coordinate to check.
std::string farCoordinateProblem(const std::vector<Eigen::Vector3d>& points, double bound_m,
                                 const std::string& frame);

}  // namespace deformable_collision
