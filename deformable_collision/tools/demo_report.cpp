// Watches a running deformable_collision node for a fixed time, asks it for contacts over
// its service like any client would, prints a report and exits (which ends `make demo`).
// Where the scene publishes ground_truth/<object> (scene camera_gripper), it also scores the
// node's ~deformed/<object> against it; for each of ~wrench_objects (the robot_gripper
// scene's fingers) it prints the force the node's ~wrench/<object> read over time.
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <functional>
#include <list>
#include <map>
#include <string>
#include <vector>

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

/// The 99th percentile (nearest rank) of `values`, which it reorders; 0 if empty.
double percentile99(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  const std::size_t rank = (99 * values.size() + 99) / 100 - 1;
  std::nth_element(values.begin(), values.begin() + rank, values.end());
  return values[rank];
}

/// The node's per-cloud latency summaries (one per latency period) over the watch.
struct LatencyPeriods {
  std::uint64_t last_period = 0;
  std::size_t periods = 0;
  std::size_t clouds = 0;
  double arrival_sum_ms = 0.0, arrival_worst_p99_ms = 0.0, arrival_max_ms = 0.0;
  double stamp_sum_ms = 0.0, stamp_worst_p99_ms = 0.0, stamp_max_ms = 0.0;

  void add(const deformable_collision::Stats& stats) {
    if (stats.latency_periods == last_period) return;
    const bool first_seen = last_period == 0;
    last_period = stats.latency_periods;
    // The first summary seen may cover time before the watch began (the node's start).
    if (first_seen || stats.latency_clouds == 0) return;
    ++periods;
    clouds += stats.latency_clouds;
    arrival_sum_ms += stats.arrival_latency_mean_ms * stats.latency_clouds;
    arrival_worst_p99_ms = std::max(arrival_worst_p99_ms, stats.arrival_latency_p99_ms);
    arrival_max_ms = std::max(arrival_max_ms, stats.arrival_latency_max_ms);
    stamp_sum_ms += stats.stamp_latency_mean_ms * stats.latency_clouds;
    stamp_worst_p99_ms = std::max(stamp_worst_p99_ms, stats.stamp_latency_p99_ms);
    stamp_max_ms = std::max(stamp_max_ms, stats.stamp_latency_max_ms);
  }
};

/// What the node's ~stats said over the watch: the last message and each figure's summary.
struct StatsRecord {
  deformable_collision::Stats last;
  /// The last message of the warm-up: the node's counts since it are the figures'.
  deformable_collision::Stats before_figures;
  Summary input, shape_matching, detection, detection_ahead, response, publish, cycle, latency,
      contacts;
  std::vector<double> latencies_ms;  ///< Per cycle, of its oldest cloud.
  LatencyPeriods latency_periods;
  std::size_t cycles = 0;
  ros::WallTime first_cycle;
  ros::WallTime before_figures_time;  ///< When before_figures came (the first cycle without).
  ros::WallTime last_time;            ///< When `last` came.
  /// The figures leave out the cycles of this long after the first (objects being made).
  double warmup_s = 0.0;
  /// When the object count last grew, after the first cycle: a warm-up shorter than this
  /// leaves the making of objects in the figures (objects whose topics connect late).
  double last_object_made_s = 0.0;

  void add(const deformable_collision::Stats& stats) {
    if (stats.objects == 0) return;
    const ros::WallTime now = ros::WallTime::now();
    if (cycles == 0) first_cycle = before_figures_time = now;
    const double since_first_s = (now - first_cycle).toSec();
    if (stats.objects > last.objects) last_object_made_s = since_first_s;
    ++cycles;
    last = stats;
    last_time = now;
    if (since_first_s < warmup_s) {
      before_figures = stats;
      before_figures_time = now;
      return;
    }
    input.add(stats.input_ms);
    shape_matching.add(stats.shape_matching_ms);
    detection.add(stats.detection_ms);
    detection_ahead.add(stats.detection_ahead_ms);
    response.add(stats.response_ms);
    publish.add(stats.publish_ms);
    cycle.add(stats.cycle_ms);
    contacts.add(stats.contacts);
    if (stats.input_latency_ms > 0.0) {
      latency.add(stats.input_latency_ms);
      latencies_ms.push_back(stats.input_latency_ms);
    }
    latency_periods.add(stats);
  }
};

/// The registration error of one object: its ~deformed points against the scene's
/// ground_truth points of the same index, on the seen and the hidden side. Each ground truth
/// is scored against the node's last model before the next ground truth: by then the node
/// has registered the cloud taken with it.
class GroundTruthScore {
 public:
  explicit GroundTruthScore(std::string object) : object_(std::move(object)) {}

  void addGroundTruth(const sensor_msgs::PointCloud2::ConstPtr& truth) {
    // A ground truth arrives a render's time after its stamp, when models newer than that
    // stamp may have come already: the one to score is the newest stamped before it.
    if (pending_truth_) {
      const auto before_next = std::find_if(models_.rbegin(), models_.rend(),
                                            [&](const sensor_msgs::PointCloud2::ConstPtr& model) {
                                              return model->header.stamp < truth->header.stamp;
                                            });
      if (before_next != models_.rend() &&
          (*before_next)->header.stamp >= pending_truth_->header.stamp) {
        score(*pending_truth_, **before_next);
      }
    }
    pending_truth_ = truth;
  }
  void addModel(const sensor_msgs::PointCloud2::ConstPtr& model) {
    models_.push_back(model);
    if (models_.size() > kModelsKept) models_.pop_front();
  }

  void print() const {
    std::printf("registration of %s against ground_truth/%s over %zu clouds (%zu unmatched):\n",
                object_.c_str(), object_.c_str(), seen_mean_.count, unmatched_);
    std::printf("  seen side: mean %.2f mm (worst cloud %.2f mm), largest %.2f mm, %.0f points\n",
                1e3 * seen_mean_.mean(), 1e3 * seen_mean_.max, 1e3 * seen_max_.max,
                seen_count_.mean());
    std::printf("  hidden side: mean %.2f mm (worst cloud %.2f mm), largest %.2f mm, %.0f points\n",
                1e3 * hidden_mean_.mean(), 1e3 * hidden_mean_.max, 1e3 * hidden_max_.max,
                hidden_count_.mean());
  }

 private:
  void score(const sensor_msgs::PointCloud2& truth, const sensor_msgs::PointCloud2& model) {
    const std::size_t count = std::size_t(truth.width) * truth.height;
    if (truth.header.frame_id != model.header.frame_id ||
        std::size_t(model.width) * model.height != count) {
      ++unmatched_;
      return;
    }
    sensor_msgs::PointCloud2ConstIterator<float> truth_xyz(truth, "x"), visible(truth, "visible"),
        model_xyz(model, "x");
    Summary seen, hidden;
    for (std::size_t i = 0; i < count; ++i, ++truth_xyz, ++visible, ++model_xyz) {
      const double error = std::sqrt(std::pow(truth_xyz[0] - model_xyz[0], 2) +
                                     std::pow(truth_xyz[1] - model_xyz[1], 2) +
                                     std::pow(truth_xyz[2] - model_xyz[2], 2));
      (*visible > 0.5f ? seen : hidden).add(error);
    }
    seen_mean_.add(seen.mean());
    seen_max_.add(seen.max);
    seen_count_.add(seen.count);
    hidden_mean_.add(hidden.mean());
    hidden_max_.add(hidden.max);
    hidden_count_.add(hidden.count);
  }

  /// Models at the node's rate that a ground truth at the camera's rate may have to reach
  /// back over.
  static constexpr std::size_t kModelsKept = 64;
  std::string object_;
  sensor_msgs::PointCloud2::ConstPtr pending_truth_;
  std::deque<sensor_msgs::PointCloud2::ConstPtr> models_;
  Summary seen_mean_, seen_max_, seen_count_, hidden_mean_, hidden_max_, hidden_count_;
  std::size_t unmatched_ = 0;
};

/// The force ~wrench/<object> read, in bins of kWrenchBinS from the first message: the
/// mean magnitude and the mean along the frame's x (a finger's closing axis).
class WrenchRecord {
 public:
  static constexpr double kWrenchBinS = 0.5;

  WrenchRecord(ros::NodeHandle& node_handle, const std::string& object) : object_(object) {
    subscriber_ = node_handle.subscribe<geometry_msgs::WrenchStamped>(
        "wrench/" + object, 100,
        boost::function<void(const geometry_msgs::WrenchStamped::ConstPtr&)>(
            [this](const geometry_msgs::WrenchStamped::ConstPtr& m) { add(*m); }));
  }

  void print() const {
    std::printf("force on %s (N, in its frame; mean per %.1f s from its first wrench):\n",
                object_.c_str(), kWrenchBinS);
    for (const auto& [bin, force] : bins_) {
      std::printf("  t %4.1f s: |F| %7.3f, along x %+8.3f (%zu cycles)\n", bin * kWrenchBinS,
                  force.magnitude.mean(), force.along_x / force.magnitude.count,
                  force.magnitude.count);
    }
  }

 private:
  struct Bin {
    Summary magnitude;
    double along_x = 0.0;
  };
  void add(const geometry_msgs::WrenchStamped& m) {
    if (first_.isZero()) first_ = m.header.stamp;
    Bin& bin = bins_[static_cast<int>((m.header.stamp - first_).toSec() / kWrenchBinS)];
    const auto& f = m.wrench.force;
    bin.magnitude.add(std::sqrt(f.x * f.x + f.y * f.y + f.z * f.z));
    bin.along_x += f.x;
  }

  std::string object_;
  ros::Subscriber subscriber_;
  ros::Time first_;
  std::map<int, Bin> bins_;
};

/// Subscribes, for every ground_truth/<object> topic the master knows, to it and to the
/// node's ~deformed/<object>.
void scoreGroundTruths(ros::NodeHandle& node_handle, std::list<GroundTruthScore>& scores,
                       std::vector<ros::Subscriber>& subscribers) {
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  const std::string marker = "ground_truth/";
  for (const auto& topic : topics) {
    const std::size_t at = topic.name.rfind(marker);
    if (at == std::string::npos || (at > 0 && topic.name[at - 1] != '/')) continue;
    const std::string object = topic.name.substr(at + marker.size());
    GroundTruthScore& score = scores.emplace_back(object);
    using Callback = boost::function<void(const sensor_msgs::PointCloud2::ConstPtr&)>;
    subscribers.push_back(node_handle.subscribe<sensor_msgs::PointCloud2>(
        topic.name, 10, Callback([&score](const auto& truth) { score.addGroundTruth(truth); })));
    subscribers.push_back(node_handle.subscribe<sensor_msgs::PointCloud2>(
        "deformed/" + object, 10,
        Callback([&score](const auto& model) { score.addModel(model); })));
  }
}

/// Spins until `duration_s` after the first cycle with objects, calling `on_first_cycle`
/// when that comes; false if none came within `startup_timeout_s` (said on stderr) or ROS
/// shut down.
bool watch(const StatsRecord& record, const std::string& node, double duration_s,
           double startup_timeout_s, const std::function<void()>& on_first_cycle) {
  bool first_cycle_seen = false;
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
    if (record.cycles > 0 && !first_cycle_seen) {
      first_cycle_seen = true;
      on_first_cycle();
    }
    if (record.cycles > 0 && (now - record.first_cycle).toSec() >= duration_s) return true;
    poll.sleep();
  }
  return false;
}

void printLatencies(StatsRecord& record) {
  if (record.latency.count > 0) {
    std::printf(
        "cloud arrival to contacts published, oldest cloud of each cycle: mean %.3f ms, "
        "p99 %.3f ms, max %.3f ms (%zu cycles)\n",
        record.latency.mean(), percentile99(record.latencies_ms), record.latency.max,
        record.latency.count);
  }
  const LatencyPeriods& periods = record.latency_periods;
  if (periods.clouds > 0) {
    std::printf(
        "per cloud, over the node's %zu latency periods (%zu clouds), to contacts "
        "published: from arrival mean %.3f ms, worst p99 %.3f ms, max %.3f ms; from "
        "stamp mean %.3f ms, worst p99 %.3f ms, max %.3f ms\n",
        periods.periods, periods.clouds, periods.arrival_sum_ms / periods.clouds,
        periods.arrival_worst_p99_ms, periods.arrival_max_ms, periods.stamp_sum_ms / periods.clouds,
        periods.stamp_worst_p99_ms, periods.stamp_max_ms);
  }
}

void printReport(StatsRecord& record, double duration_s) {
  const deformable_collision::Stats& last = record.last;
  std::printf("\n=== deformable_collision demo report (%.1f s, %zu cycles", duration_s,
              record.cycles);
  if (record.warmup_s > 0.0) {
    std::printf("; figures from %zu cycles after a warm-up of %.1f s", record.cycle.count,
                record.warmup_s);
  }
  std::printf(") ===\n");
  std::printf(
      "objects %u (the last made %.1f s after the first cycle%s), points %u, level of "
      "detail %u of %u (leaves)\n",
      last.objects, record.last_object_made_s,
      record.warmup_s > 0.0 && record.last_object_made_s >= record.warmup_s ? ", after the warm-up"
                                                                            : "",
      last.points, last.level, last.max_level);
  std::printf(
      "per cycle, mean / max ms: input %.3f / %.3f, shape matching %.3f / %.3f, "
      "detection %.3f / %.3f (and ahead of the cycle %.3f / %.3f), response %.3f / %.3f, "
      "publish %.3f / %.3f, whole %.3f / %.3f\n",
      record.input.mean(), record.input.max, record.shape_matching.mean(),
      record.shape_matching.max, record.detection.mean(), record.detection.max,
      record.detection_ahead.mean(), record.detection_ahead.max, record.response.mean(),
      record.response.max, record.publish.mean(), record.publish.max, record.cycle.mean(),
      record.cycle.max);
  std::printf("contacts per cycle: mean %.1f, max %.0f, last %u\n", record.contacts.mean(),
              record.contacts.max, last.contacts);
  printLatencies(record);
  std::printf("overruns %lu of %lu cycles (%lu from their input)",
              static_cast<unsigned long>(last.overruns), static_cast<unsigned long>(last.cycles),
              static_cast<unsigned long>(last.overruns_from_input));
  if (record.warmup_s > 0.0) {
    const deformable_collision::Stats& before = record.before_figures;
    std::printf(", after the warm-up %lu of %lu (%lu)",
                static_cast<unsigned long>(last.overruns - before.overruns),
                static_cast<unsigned long>(last.cycles - before.cycles),
                static_cast<unsigned long>(last.overruns_from_input - before.overruns_from_input));
  }
  std::printf("; clouds received %lu, rejected %lu, coalesced %lu; non-finite points %lu\n",
              static_cast<unsigned long>(last.clouds_received),
              static_cast<unsigned long>(last.clouds_rejected),
              static_cast<unsigned long>(last.clouds_coalesced),
              static_cast<unsigned long>(last.non_finite_points));
  const double busy_s = last.reader_busy_s - record.before_figures.reader_busy_s;
  const double span_s = (record.last_time - record.before_figures_time).toSec();
  if (span_s > 0.0) {
    std::printf("reader threads busy %.1f%% of one core (%.3f s in %.1f s)\n",
                100.0 * busy_s / span_s, busy_s, span_s);
  }
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
  record.warmup_s = private_handle.param("warmup_s", 0.0);
  ros::Subscriber stats_subscriber = node_handle.subscribe<deformable_collision::Stats>(
      "stats", 100,
      boost::function<void(const deformable_collision::Stats::ConstPtr&)>(
          [&record](const deformable_collision::Stats::ConstPtr& stats) { record.add(*stats); }));
  // Subscribed so that the node builds its contacts as a user's controller would make it.
  ros::Subscriber contacts_subscriber = node_handle.subscribe<deformable_collision::ContactArray>(
      "contacts", 1,
      boost::function<void(const deformable_collision::ContactArray::ConstPtr&)>(
          [](const deformable_collision::ContactArray::ConstPtr&) {}));
  std::list<WrenchRecord> wrenches;  // a list: the subscribers hold `this`
  for (const std::string& object :
       private_handle.param("wrench_objects", std::vector<std::string>{})) {
    wrenches.emplace_back(node_handle, object);
  }
  std::list<GroundTruthScore> scores;  // a list: the subscribers hold references
  std::vector<ros::Subscriber> score_subscribers;
  if (!watch(record, node, duration_s, startup_timeout_s,
             [&] { scoreGroundTruths(node_handle, scores, score_subscribers); })) {
    return 1;
  }

  deformable_collision::GetContacts query;
  query.request.level = deformable_collision::GetContacts::Request::RUNNING;
  const bool answered = ros::service::call(node + "/get_contacts", query) && query.response.success;
  printReport(record, duration_s);
  for (const GroundTruthScore& score : scores) score.print();
  for (const WrenchRecord& wrench : wrenches) wrench.print();
  if (answered) {
    std::printf("%s/get_contacts: %s\n", node.c_str(), query.response.message.c_str());
  } else {
    std::printf("%s/get_contacts: no answer (%s)\n", node.c_str(), query.response.message.c_str());
  }
  return answered ? 0 : 1;
}
