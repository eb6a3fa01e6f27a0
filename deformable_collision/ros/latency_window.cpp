#include "deformable_collision/ros/latency_window.h"

#include <algorithm>
#include <numeric>

namespace deformable_collision {

LatencySummary LatencyWindow::close() {
  LatencySummary summary;
  if (samples_ms_.empty()) return summary;
  const std::size_t count = samples_ms_.size();
  summary.count = static_cast<std::uint32_t>(count);
  summary.mean_ms = std::accumulate(samples_ms_.begin(), samples_ms_.end(), 0.0) / count;
  summary.max_ms = *std::max_element(samples_ms_.begin(), samples_ms_.end());
  const std::size_t rank = (99 * count + 99) / 100 - 1;  // ceil(0.99 count) - 1, in integers
  std::nth_element(samples_ms_.begin(), samples_ms_.begin() + rank, samples_ms_.end());
  summary.p99_ms = samples_ms_[rank];
  samples_ms_.clear();
  return summary;
}

}  // namespace deformable_collision
