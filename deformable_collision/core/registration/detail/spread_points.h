// Internal to the core: the points a registration samples of a cloud or of the model.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_collision {
namespace detail {

/// Up to `target` indices of `points`, one per cell of a grid whose cell size is chosen so
/// that about `target` cells are occupied: the points spread evenly over the shape, in
/// ascending order. All of them if there are no more than `target`.
std::vector<std::uint32_t> spreadPoints(const std::vector<Eigen::Vector3d>& points,
                                        std::size_t target);

}  // namespace detail
}  // namespace deformable_collision
