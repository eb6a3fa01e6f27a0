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
  const double extent = box.sizes().maxCoeff();
  // Coincident points fill one cell of any size.
  if (!(extent > 0.0)) return {0};
  std::vector<std::pair<std::uint64_t, std::uint32_t>> cells(points.size());
  const auto oneInEachCell = [&](double cell) {
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
  };
  // Cells sized for a volume to fill `target` of them (doubled while a box's partial cells
  // at its far faces make them more) hold at most that many points of any shape; cells no
  // larger than the spacing of points spread along a line hold about one each. A surface
  // fills far fewer cells than a volume of the same size, so the size is bisected (in its
  // logarithm) between the two until the cells hold 90% to 100% of `target` points.
  double large = extent / std::cbrt(static_cast<double>(target));
  double small =
      std::max(extent / static_cast<double>(points.size()), std::numeric_limits<double>::min());
  oneInEachCell(large);
  while (chosen.size() > target) {
    small = large;
    large *= 2.0;
    oneInEachCell(large);
  }
  constexpr int kMostSteps = 40;
  for (int step = 0; step < kMostSteps; ++step) {
    if (chosen.size() <= target && chosen.size() >= 0.9 * target) break;
    const double middle = std::sqrt(large) * std::sqrt(small);  // No underflow when tiny.
    oneInEachCell(middle);
    (chosen.size() > target ? small : large) = middle;
  }
  if (chosen.size() > target) oneInEachCell(large);
  std::sort(chosen.begin(), chosen.end());
  return chosen;
}

}  // namespace detail
}  // namespace deformable_collision
