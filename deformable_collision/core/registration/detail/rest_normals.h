#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {
namespace detail {

/// The rest shape's surface at each chosen point: the direction in which its nearest
/// neighbours spread least, turned away from the shape's centre (outwards on a convex
/// shape, which is what tells the camera's side from the hidden one), and whether the
/// neighbourhood is flat enough for that to be a surface normal (not an edge or a corner).
struct RestNormals {
  std::vector<Eigen::Vector3d> outward;
  std::vector<char> flat;
};

/// The rest normals of the points `chosen` of `rest`.
RestNormals restNormals(const std::vector<Eigen::Vector3d>& rest,
                        const std::vector<std::uint32_t>& chosen);

}  // namespace detail
}  // namespace deformable_collision
