// Watches a running deformable_collision node for a fixed time, asks it for contacts over
// its service like any client would, prints a report and exits (which ends `make demo`).
#include <ros/ros.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/Stats.h"

namespace {

struct Summary {
  double sum = 0.0;
  double max = 0.0;
  std::size_t count = 0;
  void add(double value) {
    sum += value;
    max = std::max(max, value);
    ++count;
  }
  double mean() const { return count ? sum / count : 0.0; }
};

/// What the node's ~stats said over the watch: the last message and each figure's summary.
struct StatsRecord {
  deformable_collision::Stats last;
  Summary shape_matching, detection, response, publish, cycle, latency, contacts;
  std::size_t cycles = 0;
  ros::WallTime first_cycle;

  void add(const deformable_collision::Stats& stats) {
    if (stats.objects == 0) return;
    if (cycles == 0) first_cycle = ros::WallTime::now();
    ++cycles;
    last = stats;
    shape_matching.add(stats.shape_matching_ms);
    detection.add(stats.detection_ms);
    response.add(stats.response_ms);
    publish.add(stats.publish_ms);
    cycle.add(stats.cycle_ms);
    contacts.add(stats.contacts);
    if (stats.input_latency_ms > 0.0) latency.add(stats.input_latency_ms);
  }
};

/// Spins until `duration_s` after the first cycle with objects; false if none came within
/// `startup_timeout_s` (said on stderr) or ROS shut down.
bool watch(const StatsRecord& record, const std::string& node, double duration_s,
           double startup_timeout_s) {
  const ros::WallTime started = ros::WallTime::now();
  ros::WallRate poll(100.0);
  while (ros::ok()) {
    ros::spinOnce();
    const ros::WallTime now = ros::WallTime::now();
    if (record.cycles == 0 && (now - started).toSec() > startup_timeout_s) {
      std::fprintf(stderr, "demo_report: no cycle with objects from %s/stats within %.0f s\n",
                   node.c_str(), startup_timeout_s);
      return false;
    }
    if (record.cycles > 0 && (now - record.first_cycle).toSec() >= duration_s) return true;
    poll.sleep();
  }
  return false;
}

void printReport(const StatsRecord& record, double duration_s) {
  const deformable_collision::Stats& last = record.last;
  std::printf("\n=== deformable_collision demo report (%.1f s, %zu cycles) ===\n", duration_s,
              record.cycles);
  std::printf("objects %u, points %u, level of detail %u of %u (leaves)\n", last.objects,
              last.points, last.level, last.max_level);
  std::printf("per cycle, mean / max ms: shape matching %.3f / %.3f, detection %.3f / %.3f, "
              "response %.3f / %.3f, publish %.3f / %.3f, whole %.3f / %.3f\n",
              record.shape_matching.mean(), record.shape_matching.max, record.detection.mean(),
              record.detection.max, record.response.mean(), record.response.max,
              record.publish.mean(), record.publish.max, record.cycle.mean(), record.cycle.max);
  std::printf("contacts per cycle: mean %.1f, max %.0f, last %u\n", record.contacts.mean(),
              record.contacts.max, last.contacts);
  if (record.latency.count > 0) {
    std::printf("cloud arrival to contacts published: mean %.3f ms, max %.3f ms (%zu cycles)\n",
                record.latency.mean(), record.latency.max, record.latency.count);
  }
  std::printf("overruns %lu of %lu cycles; clouds received %lu, rejected %lu; non-finite points %lu\n",
              static_cast<unsigned long>(last.overruns), static_cast<unsigned long>(last.cycles),
              static_cast<unsigned long>(last.clouds_received),
              static_cast<unsigned long>(last.clouds_rejected),
              static_cast<unsigned long>(last.non_finite_points));
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "demo_report");
  ros::NodeHandle private_handle("~");
  const std::string node = private_handle.param<std::string>("node", "/deformable_collision");
  const double duration_s = private_handle.param("duration_s", 10.0);
  const double startup_timeout_s = private_handle.param("startup_timeout_s", 60.0);
  ros::NodeHandle node_handle(node);

  StatsRecord record;
  ros::Subscriber stats_subscriber = node_handle.subscribe<deformable_collision::Stats>(
      "stats", 100, boost::function<void(const deformable_collision::Stats::ConstPtr&)>(
                        [&record](const deformable_collision::Stats::ConstPtr& stats) {
                          record.add(*stats);
                        }));
  // Subscribed so that the node builds its contacts as a user's controller would make it.
  ros::Subscriber contacts_subscriber = node_handle.subscribe<deformable_collision::ContactArray>(
      "contacts", 1,
      boost::function<void(const deformable_collision::ContactArray::ConstPtr&)>(
          [](const deformable_collision::ContactArray::ConstPtr&) {}));
  if (!watch(record, node, duration_s, startup_timeout_s)) return 1;

  deformable_collision::GetContacts query;
  query.request.level = deformable_collision::GetContacts::Request::RUNNING;
  const bool answered =
      ros::service::call(node + "/get_contacts", query) && query.response.success;
  printReport(record, duration_s);
  if (answered) {
    std::printf("%s/get_contacts: %s\n", node.c_str(), query.response.message.c_str());
  } else {
    std::printf("%s/get_contacts: no answer (%s)\n", node.c_str(), query.response.message.c_str());
  }
  return answered ? 0 : 1;
}
