#include "deformable_collision/ros/node_diagnostics.h"

#include <chrono>

namespace deformable_collision {

NodeDiagnostics::NodeDiagnostics(const DiagnosticsParams& params,
                                 const std::vector<ObjectSlot>& slots, const NodeOutputs& outputs)
    : params_(params), slots_(slots), outputs_(outputs), counted_(slots.size()) {}

void NodeDiagnostics::start(ros::NodeHandle& handle, const ros::NodeHandle& private_handle) {
  // The timer below sets the period (diagnostics.period_s): the updater, which would read
  // it from ~diagnostic_period, a key the configuration refuses, only publishes.
  updater_ = std::make_unique<diagnostic_updater::Updater>(
      handle, ros::NodeHandle(private_handle, "diagnostics"), private_handle.getNamespace());
  updater_->setHardwareID("none");
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    updater_->add("object " + slots_[i].params.object.name,
                  [this, i](diagnostic_updater::DiagnosticStatusWrapper& status) {
                    objectStatus(i, status);
                  });
  }
  updater_->add("cycle", [this](diagnostic_updater::DiagnosticStatusWrapper& status) {
    cycleStatus(status);
  });
  timer_ = handle.createTimer(ros::Duration(params_.period_s),
                              [this](const ros::TimerEvent&) { updater_->force_update(); });
}

ObjectPeriod NodeDiagnostics::objectPeriod(std::size_t index, ObjectSlot::Clock::time_point now) {
  const ObjectSlot& slot = slots_[index];
  ObjectCounts& counted = counted_[index];
  const ObjectCounts counts{slot.clouds_received.load(), slot.clouds_dropped.load(),
                            slot.clouds_held};
  ObjectPeriod period;
  period.has_topic = !slot.params.topic.empty();
  period.in_scene = slot.index.has_value();
  period.expects_clouds = slot.params.on_cloud != OnCloud::kIgnore || !period.in_scene;
  period.received = counts.received - counted.received;
  period.dropped = counts.dropped - counted.dropped;
  period.held = counts.held - counted.held;
  counted = counts;
  if (const ObjectSlot::Clock::rep last = slot.last_arrival.load(); last != 0) {
    period.since_last_cloud_s =
        std::chrono::duration<double>(now.time_since_epoch() - ObjectSlot::Clock::duration(last))
            .count();
  }
  period.interval_s = slot.params.expected_rate_hz > 0.0 ? 1.0 / slot.params.expected_rate_hz
                                                         : slot.mean_interval_s.load();
  return period;
}

void NodeDiagnostics::objectStatus(std::size_t index,
                                   diagnostic_updater::DiagnosticStatusWrapper& status) {
  objectHealth(objectPeriod(index, ObjectSlot::Clock::now()), status);
}

void NodeDiagnostics::cycleStatus(diagnostic_updater::DiagnosticStatusWrapper& status) {
  CyclePeriod period;
  period.cycles = outputs_.cycles() - cycles_counted_;
  period.overruns = outputs_.overruns() - overruns_counted_;
  cycles_counted_ = outputs_.cycles();
  overruns_counted_ = outputs_.overruns();
  const CloudLatencies& latencies = outputs_.latencies();
  if (latencies.periods() != latency_periods_counted_ && latencies.arrival().count > 0) {
    period.latency_p99_ms = latencies.arrival().p99_ms;
  }
  latency_periods_counted_ = latencies.periods();
  period.latency_warn_ms = params_.latency_warn_ms;
  period.latency_error_ms = params_.latency_error_ms;
  cycleHealth(period, status);
}

}  // namespace deformable_collision
