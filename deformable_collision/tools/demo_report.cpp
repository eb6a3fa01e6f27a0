// Watches a running deformable_collision node for a fixed time, asks it for contacts over
// its service like any client would, prints a report and exits (which ends `make demo`).
#include <ros/ros.h>

#include <algorithm>
#include <cstdio>

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

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "demo_report");
  ros::NodeHandle private_handle("~");
  const std::string node = private_handle.param<std::string>("node", "/deformable_collision");
  const double duration_s = private_handle.param("duration_s", 10.0);
  const double startup_timeout_s = private_handle.param("startup_timeout_s", 60.0);
  ros::NodeHandle node_handle(node);

  deformable_collision::Stats last;
  Summary shape_matching, detection, response, publish, cycle, latency, contacts;
  std::size_t cycles = 0;
  ros::WallTime first_cycle;
  const auto on_stats = [&](const deformable_collision::Stats::ConstPtr& stats) {
    if (stats->objects == 0) return;
    if (cycles == 0) first_cycle = ros::WallTime::now();
    ++cycles;
    last = *stats;
    shape_matching.add(stats->shape_matching_ms);
    detection.add(stats->detection_ms);
    response.add(stats->response_ms);
    publish.add(stats->publish_ms);
    cycle.add(stats->cycle_ms);
    contacts.add(stats->contacts);
    if (stats->input_latency_ms > 0.0) latency.add(stats->input_latency_ms);
  };
  ros::Subscriber stats_subscriber = node_handle.subscribe<deformable_collision::Stats>(
      "stats", 100, boost::function<void(const deformable_collision::Stats::ConstPtr&)>(on_stats));
  // Subscribed so that the node builds its contacts as a user's controller would make it.
  ros::Subscriber contacts_subscriber = node_handle.subscribe<deformable_collision::ContactArray>(
      "contacts", 1,
      boost::function<void(const deformable_collision::ContactArray::ConstPtr&)>(
          [](const deformable_collision::ContactArray::ConstPtr&) {}));

  const ros::WallTime started = ros::WallTime::now();
  ros::WallRate poll(100.0);
  while (ros::ok()) {
    ros::spinOnce();
    const ros::WallTime now = ros::WallTime::now();
    if (cycles == 0 && (now - started).toSec() > startup_timeout_s) {
      std::fprintf(stderr, "demo_report: no cycle with objects from %s/stats within %.0f s\n",
                   node.c_str(), startup_timeout_s);
      return 1;
    }
    if (cycles > 0 && (now - first_cycle).toSec() >= duration_s) break;
    poll.sleep();
  }
  if (!ros::ok()) return 1;

  deformable_collision::GetContacts query;
  query.request.level = deformable_collision::GetContacts::Request::RUNNING;
  const bool answered =
      ros::service::call(node + "/get_contacts", query) && query.response.success;

  std::printf("\n=== deformable_collision demo report (%.1f s, %zu cycles) ===\n", duration_s, cycles);
  std::printf("objects %u, points %u, level of detail %u of %u (leaves)\n", last.objects,
              last.points, last.level, last.max_level);
  std::printf("per cycle, mean / max ms: shape matching %.3f / %.3f, detection %.3f / %.3f, "
              "response %.3f / %.3f, publish %.3f / %.3f, whole %.3f / %.3f\n",
              shape_matching.mean(), shape_matching.max, detection.mean(), detection.max,
              response.mean(), response.max, publish.mean(), publish.max, cycle.mean(), cycle.max);
  std::printf("contacts per cycle: mean %.1f, max %.0f, last %u\n", contacts.mean(), contacts.max,
              last.contacts);
  if (latency.count > 0) {
    std::printf("cloud arrival to contacts published: mean %.3f ms, max %.3f ms (%zu cycles)\n",
                latency.mean(), latency.max, latency.count);
  }
  std::printf("overruns %lu of %lu cycles; clouds received %lu, rejected %lu; non-finite points %lu\n",
              static_cast<unsigned long>(last.overruns), static_cast<unsigned long>(last.cycles),
              static_cast<unsigned long>(last.clouds_received),
              static_cast<unsigned long>(last.clouds_rejected),
              static_cast<unsigned long>(last.non_finite_points));
  if (answered) {
    std::printf("%s/get_contacts: %s\n", node.c_str(), query.response.message.c_str());
  } else {
    std::printf("%s/get_contacts: no answer (%s)\n", node.c_str(), query.response.message.c_str());
  }
  return answered ? 0 : 1;
}
