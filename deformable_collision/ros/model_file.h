#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

namespace deformable_collision {

/// The points, in metres, of a scan or CAD model of an object: a PLY or PCD file (by its
/// extension, case-insensitive), read with PCL's I/O. x, y and z may be float32 or float64,
/// in any layout PCL reads (ASCII, binary, binary compressed PCD). Points with a non-finite
/// coordinate are dropped, so the model's order is the file's order of its finite points.
/// @throw std::invalid_argument naming the path and what is wrong: no such file, an
/// extension other than .ply or .pcd, a file PCL cannot read, no x/y/z fields, or no finite
/// point.
std::vector<Eigen::Vector3d> readModelFile(const std::string& path);

/// Writes `points` as a binary little-endian PLY of float32 x y z vertices.
/// @throw std::invalid_argument when the file cannot be written or a point is not finite.
void writeModelFile(const std::string& path, const std::vector<Eigen::Vector3d>& points);

}  // namespace deformable_collision
