#include "deformable_collision/core/registration/detail/spread_points.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace deformable_collision {
namespace detail {

std::vector<std::uint32_t> spreadPoints(const std::vector<Eigen::Vector3d>& points,
                                        std::size_t target) {
  std::vector<std::uint32_t> chosen;
  if (points.size() <= target) {
    chosen.resize(points.size());
    for (std::uint32_t i = 0; i < chosen.size(); ++i) chosen[i] = i;
    return chosen;
  }
  Eigen::AlignedBox3d box;
  for (const auto& p : points) box.extend(p);
  const double extent = std::max(box.sizes().maxCoeff(), std::numeric_limits<double>::min());
  std::vector<std::pair<std::uint64_t, std::uint32_t>> cells(points.size());
  // A surface fills cells as the square of their count per side, a volume as the cube:
  // shrink the cells until about `target` are occupied, starting where a volume would be.
  double cell = extent / std::cbrt(static_cast<double>(target));
  for (int attempt = 0; attempt < 40; ++attempt) {
    for (std::uint32_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d scaled = (points[i] - box.min()) / cell;
      const auto axis = [&](int d) { return static_cast<std::uint64_t>(scaled[d]) & 0x1fffff; };
      cells[i] = {(axis(0) << 42) | (axis(1) << 21) | axis(2), i};
    }
    std::sort(cells.begin(), cells.end());
    chosen.clear();
    for (std::size_t k = 0; k < cells.size(); ++k) {
      if (k == 0 || cells[k].first != cells[k - 1].first) chosen.push_back(cells[k].second);
    }
    if (chosen.size() <= target) break;
    cell *= 1.0 + 0.5 * (static_cast<double>(chosen.size()) / target - 1.0) + 0.01;
  }
  if (chosen.size() > target) chosen.resize(target);
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

}  // namespace detail
}  // namespace deformable_collision
