#include "deformable_collision/ros/cloud_transform.h"

#include <tf2/exceptions.h>

#include <cmath>
#include <sstream>

namespace deformable_collision {

CloudTransformLookup lookUpCloudTransform(const tf2::BufferCore& buffer,
                                          const std::string& target_frame,
                                          const std::string& source_frame, const ros::Time& stamp) {
  CloudTransformLookup lookup;
  try {
    lookup.transform = buffer.lookupTransform(target_frame, source_frame, stamp).transform;
    lookup.status = CloudTransformStatus::kFound;
  } catch (const tf2::TransformException& e) {
    // Extrapolation (the pose at the stamp lags) and connectivity (the tree is still being
    // joined) may resolve; a frame no transform ever named only if its publisher is wrong.
    lookup.error = e.what();
    lookup.status = buffer._frameExists(source_frame) ? CloudTransformStatus::kNotYet
                                                      : CloudTransformStatus::kUnknownFrame;
  }
  return lookup;
}

std::optional<Eigen::Isometry3d> toIsometry(const geometry_msgs::Transform& transform) {
  const Eigen::Quaterniond rotation(transform.rotation.w, transform.rotation.x,
                                    transform.rotation.y, transform.rotation.z);
  const Eigen::Vector3d translation(transform.translation.x, transform.translation.y,
                                    transform.translation.z);
  const double norm = rotation.norm();
  if (!translation.allFinite() || !std::isfinite(norm) || norm < 1e-6) return std::nullopt;
  Eigen::Isometry3d isometry = Eigen::Isometry3d::Identity();
  isometry.linear() = rotation.normalized().toRotationMatrix();
  isometry.translation() = translation;
  return isometry;
}

geometry_msgs::TransformStamped toTransformStamped(const Eigen::Isometry3d& pose,
                                                   const ros::Time& stamp,
                                                   const std::string& parent,
                                                   const std::string& child) {
  geometry_msgs::TransformStamped stamped;
  stamped.header.stamp = stamp;
  stamped.header.frame_id = parent;
  stamped.child_frame_id = child;
  stamped.transform.translation.x = pose.translation().x();
  stamped.transform.translation.y = pose.translation().y();
  stamped.transform.translation.z = pose.translation().z();
  const Eigen::Quaterniond rotation(pose.linear());
  stamped.transform.rotation.x = rotation.x();
  stamped.transform.rotation.y = rotation.y();
  stamped.transform.rotation.z = rotation.z();
  stamped.transform.rotation.w = rotation.w();
  return stamped;
}

std::string farCoordinateProblem(const std::vector<Eigen::Vector3d>& points, double bound_m,
                                 const std::string& frame) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    // One comparison per coordinate for the usual point, which is near and finite.
    if ((points[i].array().abs() <= bound_m).all()) continue;
    if (points[i].array().isNaN().all()) continue;
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(points[i][axis]) <= bound_m) continue;
      std::ostringstream problem;
      problem << "point " << i << " has "
              << "xyz"[axis] << " = " << points[i][axis] << " m in '" << frame
              << "', beyond max_coordinate_m = " << bound_m;
      return problem.str();
    }
  }
  return "";
}

}  // namespace deformable_collision
