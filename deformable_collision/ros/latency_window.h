#pragma once

#include <cstdint>
#include <vector>

namespace deformable_collision {

/// Mean, 99th percentile and largest of the latencies of one period; all 0 when it had none.
struct LatencySummary {
  std::uint32_t count = 0;
  double mean_ms = 0.0;
  double p99_ms = 0.0;  ///< Nearest rank: the smallest latency at least 99 % of them do not exceed.
  double max_ms = 0.0;
};

/// The latencies of the current period. Its buffer keeps its capacity from one period to the
/// next, so once it has grown to a period's count, adding allocates nothing.
class LatencyWindow {
 public:
  void add(double latency_ms) { samples_ms_.push_back(latency_ms); }
  /// The summary of the period's latencies, which are then dropped for the next period.
  LatencySummary close();
  /// Drops the period's latencies unsummarised.
  void clear() { samples_ms_.clear(); }

 private:
  std::vector<double> samples_ms_;
};

}  // namespace deformable_collision
