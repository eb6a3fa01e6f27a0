#include "deformable_collision/ros/node_health.h"

#include <algorithm>
#include <string>

namespace deformable_collision {
namespace {

using diagnostic_msgs::DiagnosticStatus;
using diagnostic_updater::DiagnosticStatusWrapper;

void checkDrops(const ObjectPeriod& period, DiagnosticStatusWrapper& status) {
  if (period.dropped == 0) return;
  status.mergeSummaryf(
      period.dropped >= period.received ? DiagnosticStatus::ERROR : DiagnosticStatus::WARN,
      "%lu of %lu clouds dropped", static_cast<unsigned long>(period.dropped),
      static_cast<unsigned long>(period.received));
}

// A camera at 30 Hz misses 3 frames under load now and then; 10 is a stopped sensor.
void checkStale(const ObjectPeriod& period, DiagnosticStatusWrapper& status) {
  if (!period.expects_clouds || period.interval_s <= 0.0 || !period.since_last_cloud_s) return;
  const double since_s = *period.since_last_cloud_s;
  const auto level = since_s > std::max(10.0 * period.interval_s, 1.0)   ? DiagnosticStatus::ERROR
                     : since_s > std::max(3.0 * period.interval_s, 0.25) ? DiagnosticStatus::WARN
                                                                         : DiagnosticStatus::OK;
  if (level == DiagnosticStatus::OK) return;
  status.mergeSummaryf(level, "no cloud for %.2f s (one expected every %.3f s)", since_s,
                       period.interval_s);
}

}  // namespace

void objectHealth(const ObjectPeriod& period, DiagnosticStatusWrapper& status) {
  status.summary(DiagnosticStatus::OK, period.has_topic ? "clouds arrive" : "placed by tf");
  status.add("in scene", period.in_scene);
  if (!period.has_topic) {
    if (!period.in_scene) status.mergeSummary(DiagnosticStatus::WARN, "waiting for its frame");
    return;
  }
  status.add("clouds in period", period.received);
  status.add("clouds dropped in period", period.dropped);
  status.add("registrations held in period", period.held);
  status.add("expected cloud interval s", period.interval_s);
  if (period.since_last_cloud_s) {
    status.add("since last cloud s", *period.since_last_cloud_s);
  } else {
    status.mergeSummary(DiagnosticStatus::WARN, "no cloud yet");
  }
  checkDrops(period, status);
  checkStale(period, status);
  if (period.held > 0) {
    status.mergeSummaryf(DiagnosticStatus::WARN, "registration held the model for %lu clouds",
                         static_cast<unsigned long>(period.held));
  }
}

void cycleHealth(const CyclePeriod& period, DiagnosticStatusWrapper& status) {
  status.summary(DiagnosticStatus::OK, period.cycles > 0 ? "cycles keep to the rate" : "idle");
  status.add("cycles in period", period.cycles);
  status.add("overruns in period", period.overruns);
  if (period.overruns > 0) {
    status.mergeSummaryf(
        2 * period.overruns > period.cycles ? DiagnosticStatus::ERROR : DiagnosticStatus::WARN,
        "%lu of %lu cycles overran", static_cast<unsigned long>(period.overruns),
        static_cast<unsigned long>(period.cycles));
  }
  if (!period.latency_p99_ms) return;
  const double p99_ms = *period.latency_p99_ms;
  status.add("latency p99 ms", p99_ms);
  if (p99_ms <= period.latency_warn_ms) return;
  status.mergeSummaryf(
      p99_ms > period.latency_error_ms ? DiagnosticStatus::ERROR : DiagnosticStatus::WARN,
      "cloud-to-contacts latency p99 %.1f ms", p99_ms);
}

}  // namespace deformable_collision
