#include "deformable_collision/ros/robot_links.h"

#include <Eigen/Geometry>
#include <urdf/model.h>

#include <stdexcept>

#include "deformable_collision/ros/mesh_file.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

Eigen::Isometry3d toIsometry(const urdf::Pose& pose) {
  const urdf::Rotation& r = pose.rotation;
  Eigen::Isometry3d transform(Eigen::Quaterniond(r.w, r.x, r.y, r.z).normalized());
  transform.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return transform;
}

/// One <collision> element's surface, in its own frame (before its <origin>).
Points sampleGeometry(const urdf::Geometry& geometry, const SurfaceSampling& sampling) {
  switch (geometry.type) {
    case urdf::Geometry::BOX: {
      const urdf::Vector3& size = static_cast<const urdf::Box&>(geometry).dim;
      return sampleBoxSurface({size.x, size.y, size.z}, sampling);
    }
    case urdf::Geometry::CYLINDER: {
      const auto& cylinder = static_cast<const urdf::Cylinder&>(geometry);
      return sampleCylinderSurface(cylinder.radius, cylinder.length, sampling);
    }
    case urdf::Geometry::SPHERE:
      return sampleSphereSurface(static_cast<const urdf::Sphere&>(geometry).radius, sampling);
    case urdf::Geometry::MESH: {
      const auto& mesh = static_cast<const urdf::Mesh&>(geometry);
      const Eigen::Vector3d scale(mesh.scale.x, mesh.scale.y, mesh.scale.z);
      return sampleMeshSurface(readMeshFile(mesh.filename, scale), sampling);
    }
  }
  throw std::invalid_argument("a geometry of unknown type " + std::to_string(geometry.type));
}

/// A link's <collision> elements; urdf keeps the first also apart from the array.
std::vector<urdf::CollisionSharedPtr> collisionsOf(const urdf::Link& link) {
  if (!link.collision_array.empty()) return link.collision_array;
  if (link.collision) return {link.collision};
  return {};
}

}  // namespace

RobotLinks::RobotLinks(const std::string& urdf_xml) {
  auto model = std::make_shared<urdf::Model>();
  model_ = model;
  if (!model->initString(urdf_xml)) {
    throw std::invalid_argument(
        "the robot description is not a URDF that urdf::Model parses (its reasons are logged "
        "above)");
  }
}

std::vector<Eigen::Vector3d> RobotLinks::sampleSurface(const std::string& link,
                                                       const SurfaceSampling& sampling) const {
  const std::string prefix = "robot link '" + link + "': ";
  const urdf::LinkConstSharedPtr found = model_->getLink(link);
  if (!found) throw std::invalid_argument(prefix + "no such link in the robot description");
  const std::vector<urdf::CollisionSharedPtr> collisions = collisionsOf(*found);
  if (collisions.empty()) throw std::invalid_argument(prefix + "has no collision geometry");
  Points points;
  for (std::size_t i = 0; i < collisions.size(); ++i) {
    // The elements share the link's limit of points.
    const SurfaceSampling remaining{sampling.spacing_m, sampling.max_points - points.size()};
    try {
      if (!collisions[i]->geometry) throw std::invalid_argument("no geometry");
      const Eigen::Isometry3d origin = toIsometry(collisions[i]->origin);
      for (const Eigen::Vector3d& p : sampleGeometry(*collisions[i]->geometry, remaining)) {
        points.push_back(origin * p);
      }
    } catch (const std::exception& e) {
      throw std::invalid_argument(prefix + "collision " + std::to_string(i) + ": " + e.what());
    }
  }
  return points;
}

}  // namespace deformable_collision
