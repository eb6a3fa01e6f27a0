#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace deformable_collision {

/// The typical distance between neighbouring points of a cloud: the median, over up to
/// `samples` points spread evenly through the cloud, of the distance to their nearest other
/// point. Two clouds pass through each other's gaps unless the contact distance is about
/// this large. Costs samples x points distance tests; 0 for fewer than two points.
double typicalPointSpacing(const std::vector<Eigen::Vector3d>& points, std::size_t samples = 64);

}  // namespace deformable_collision
