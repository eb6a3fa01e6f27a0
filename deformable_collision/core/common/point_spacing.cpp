#include "deformable_collision/core/common/point_spacing.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace deformable_collision {

double typicalPointSpacing(const std::vector<Eigen::Vector3d>& points, std::size_t samples) {
  if (points.size() < 2 || samples == 0) return 0.0;
  const std::size_t count = std::min(samples, points.size());
  std::vector<double> nearest;
  nearest.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = k * points.size() / count;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t j = 0; j < points.size(); ++j) {
      if (j != i) best = std::min(best, (points[j] - points[i]).squaredNorm());
    }
    nearest.push_back(std::sqrt(best));
  }
  const auto middle = nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2);
  std::nth_element(nearest.begin(), middle, nearest.end());
  return *middle;
}

}  // namespace deformable_collision
