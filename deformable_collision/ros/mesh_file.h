#pragma once

#include <Eigen/Core>

#include <string>

#include "deformable_collision/core/robot/surface_sampling.h"

namespace deformable_collision {

/// The triangles of the mesh file at `uri` (package://, file:// or another scheme
/// resource_retriever knows; STL, COLLADA and the other formats assimp reads), in metres:
/// every mesh of the file placed by its nodes' transforms, a COLLADA file's <unit> applied
/// but not its up axis (a URDF mesh is in its link's frame as written, as rviz shows it),
/// then scaled by `scale` along each axis.
/// @throw std::invalid_argument naming the URI: it cannot be retrieved, assimp cannot read
/// it, or it holds no triangle.
TriangleMesh readMeshFile(const std::string& uri, const Eigen::Vector3d& scale);

}  // namespace deformable_collision
