#include "deformable_collision/ros/cloud_reader.h"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "deformable_collision/ros/cloud_transform.h"

namespace deformable_collision {
namespace {

/// At most one report per object of its dropped clouds in this period.
constexpr std::chrono::seconds kReportPeriod(5);
/// Per object: enough for a sensor at 30 Hz whose tf lags by a few frames.
constexpr std::size_t kMaxAwaitingClouds = 8;
/// The listener's subscriptions to /tf and /tf_static are made when the node starts, and on
/// a loaded machine their first transforms can take about this long: before, no frame is
/// known, and an unknown frame only means that tf has not filled yet.
constexpr double kTfFillMinimumS = 1.0;

}  // namespace

CloudReader::CloudReader(const NodeConfig& config, std::vector<ObjectSlot>& slots,
                         const Scene& scene, CloudHandoff& handoff,
                         const tf2_ros::Buffer& tf_buffer, std::function<void()> wake_cycle)
    : config_(config),
      slots_(slots),
      scene_(scene),
      handoff_(handoff),
      tf_buffer_(tf_buffer),
      wake_cycle_(std::move(wake_cycle)),
      started_(Clock::now()),
      readers_(slots.size()),
      registration_iterations_(config.scene.registration.iterations),
      registration_max_cloud_points_(config.scene.registration.max_cloud_points),
      registration_contact_distance_m_(config.scene.contact_distance_m) {}

void CloudReader::onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud, std::size_t index) {
  const auto start = Clock::now();
  receiveCloud(cloud, index);
  countBusy(start);
}

void CloudReader::countBusy(Clock::time_point start) {
  busy_ns_ += static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count());
}

void CloudReader::receiveCloud(const sensor_msgs::PointCloud2ConstPtr& cloud, std::size_t index) {
  ObjectSlot& slot = slots_[index];
  ++clouds_received_;
  const auto arrival = Clock::now();
  const RosTimeSeen seen = watchRosTime();
  countArrival(slot, arrival);
  std::lock_guard<std::mutex> lock(readers_[index].mutex);
  auto& awaiting = readers_[index].awaiting_transform;
  // Behind older clouds that wait for their transform, in arrival order: a tracked object
  // must not step back, and a sensor whose tf always lags keeps every cloud. A cloud in a
  // frame tf does not know would only take the place of one that can still be placed.
  if (!awaiting.empty()) {
    const std::string problem = unknownFrameProblem(slot, cloud->header.frame_id);
    if (!problem.empty()) {
      dropCloud(slot, ros::console::levels::Error, problem);
      return;
    }
    if (awaiting.size() == kMaxAwaitingClouds) {
      awaiting.pop_front();
      dropCloud(
          slot, ros::console::levels::Warn,
          "more than " + std::to_string(kMaxAwaitingClouds) + " clouds wait for their transform");
    }
    awaiting.push_back({cloud, arrival, seen.now, seen.jumps});
    retryAwaitingClouds(index, seen.now);
    return;
  }
  if (!processCloud(index, *cloud, arrival, config_.tf_wait_s == 0.0)) {
    awaiting.push_back({cloud, arrival, seen.now, seen.jumps});
  }
}

void CloudReader::countArrival(ObjectSlot& slot, Clock::time_point arrival) {
  ++slot.clouds_received;
  const Clock::rep last = slot.last_arrival.exchange(arrival.time_since_epoch().count());
  if (last == 0) return;
  const double interval_s =
      std::chrono::duration<double>(arrival.time_since_epoch() - Clock::duration(last)).count();
  const double mean_s = slot.mean_interval_s.load();
  // A pause of the sensor is not its rate: an interval counts for at most four times the
  // mean, so a rate that really drops is still learned within a few clouds.
  slot.mean_interval_s.store(
      mean_s == 0.0 ? interval_s : 0.9 * mean_s + 0.1 * std::min(interval_s, 4.0 * mean_s));
}

bool CloudReader::tfFilling() const {
  // The longer of the two: a tf_wait_s above the minimum says that the transforms of this
  // setup may lag that long, and at start-up that includes the first one naming a frame. In
  // ROS time too, from the first time seen or the last jump back, after which tf starts
  // empty again: a bag may start long after the node.
  const double fill_s = std::max(config_.tf_wait_s, kTfFillMinimumS);
  if (std::chrono::duration<double>(Clock::now() - started_).count() < fill_s) return true;
  std::lock_guard<std::mutex> lock(time_mutex_);
  // Not started when last seen (sim time before the first /clock): the clock may have
  // started since, but tf cannot have filled.
  return fill_started_ros_.isZero() || (ros::Time::now() - fill_started_ros_).toSec() < fill_s;
}

bool CloudReader::tfFromBeforeJump(const std::string& target_frame,
                                   const std::string& source_frame) {
  if (!tfFromBeforeJumpPossible()) return false;
  // tf's listener drops its transforms only when the first of the new time comes: until
  // then, the newest it has is from the time before the jump, ahead of the clock.
  try {
    const ros::Time newest =
        tf_buffer_.lookupTransform(target_frame, source_frame, ros::Time(0)).header.stamp;
    if (newest > ros::Time::now()) return true;
  } catch (const tf2::TransformException&) {
  }
  std::lock_guard<std::mutex> lock(time_mutex_);
  tf_from_before_jump_ = false;
  return false;
}

bool CloudReader::tfFromBeforeJumpPossible() const {
  std::lock_guard<std::mutex> lock(time_mutex_);
  return tf_from_before_jump_;
}

const std::string& CloudReader::targetFrame(const ObjectSlot& slot) const {
  return slot.params.object.kind == ObjectKind::kKinematic ? slot.params.follow_frame
                                                           : config_.fixed_frame;
}

std::string CloudReader::unknownFrameProblem(const ObjectSlot& slot,
                                             const std::string& frame) const {
  if (frame.empty() || frame == targetFrame(slot) || tfFilling() ||
      tf_buffer_._frameExists(frame)) {
    return "";
  }
  return "tf knows no frame '" + frame + "', so the cloud is dropped without waiting tf_wait_s";
}

void CloudReader::retryAwaitingClouds() {
  const auto start = Clock::now();
  const ros::Time now = watchRosTime().now;
  for (std::size_t index = 0; index < slots_.size(); ++index) {
    std::lock_guard<std::mutex> lock(readers_[index].mutex);
    retryAwaitingClouds(index, now);
  }
  countBusy(start);
}

CloudReader::RosTimeSeen CloudReader::watchRosTime() {
  RosTimeSeen seen;
  {
    // Read under the lock, so that the reader threads see ROS time in the order they read it:
    // one that read it earlier and came later would take its time for a jump back.
    std::lock_guard<std::mutex> lock(time_mutex_);
    seen.now = ros::Time::now();
    const bool went_back = seen.now < latest_ros_;
    if (latest_ros_.isZero() || went_back) fill_started_ros_ = seen.now;
    latest_ros_ = seen.now;
    jumps_ += went_back;
    seen.jumps = jumps_;
    if (!went_back) return seen;
    tf_from_before_jump_ = true;
  }
  for (std::size_t index = 0; index < slots_.size(); ++index) {
    dropCloudsFromBefore(index, seen.jumps);
  }
  return seen;
}

void CloudReader::dropCloudsFromBefore(std::size_t index, std::uint64_t jumps) {
  std::lock_guard<std::mutex> lock(readers_[index].mutex);
  auto& awaiting = readers_[index].awaiting_transform;
  // A cloud that another reader thread read after the jump stays.
  const auto from_before = [&](const AwaitingCloud& c) { return c.jumps_before < jumps; };
  const auto kept = std::remove_if(awaiting.begin(), awaiting.end(), from_before);
  for (auto it = kept; it != awaiting.end(); ++it) {
    dropCloud(slots_[index], ros::console::levels::Warn,
              "ROS time went back while it waited for its transform (a looped bag?)");
  }
  awaiting.erase(kept, awaiting.end());
}

void CloudReader::retryAwaitingClouds(std::size_t index, const ros::Time& now) {
  auto& awaiting = readers_[index].awaiting_transform;
  while (!awaiting.empty()) {
    AwaitingCloud& oldest = awaiting.front();
    // A cloud that came before ROS time started (sim time before the first /clock) waits from
    // the first time seen, not from 0.
    if (oldest.arrival_ros.isZero()) oldest.arrival_ros = now;
    // ROS time, so that a bag played slower than real time gives its tf as long as live.
    const bool last_try = (now - oldest.arrival_ros).toSec() >= config_.tf_wait_s;
    // tf arrives in time order: while the oldest cannot be placed, the newer wait too.
    if (!last_try && followFramesBehind(index, oldest.cloud->header.stamp)) return;
    if (!processCloud(index, *oldest.cloud, oldest.arrival, last_try)) return;
    awaiting.pop_front();
  }
}

bool CloudReader::followFramesBehind(std::size_t index, const ros::Time& stamp) const {
  // A tracked cloud that waited for tf comes from a sensor whose tf lags: the followed frames'
  // poses at its stamp, which its cycle uses, come with its own, but tf2's listener inserts a
  // TFMessage one transform at a time, so they are waited for too. Only frames whose pose at
  // the stamp can still come: an unknown frame or one older than tf's buffer never will.
  if (slots_[index].params.object.kind != ObjectKind::kTracked || stamp.isZero()) return false;
  return std::any_of(slots_.begin(), slots_.end(), [&](const ObjectSlot& other) {
    if (other.params.object.kind != ObjectKind::kKinematic) return false;
    const std::string& frame = other.params.follow_frame;
    if (tf_buffer_.canTransform(config_.fixed_frame, frame, stamp)) return false;
    try {
      return tf_buffer_.lookupTransform(config_.fixed_frame, frame, ros::Time(0)).header.stamp <
             stamp;
    } catch (const tf2::TransformException&) {
      return false;
    }
  });
}

bool CloudReader::processCloud(std::size_t index, const sensor_msgs::PointCloud2& cloud,
                               Clock::time_point arrival, bool last_try) {
  // An exception leaving a callback would take the whole nodelet manager down.
  try {
    return handleCloud(cloud, index, arrival, last_try) != CloudOutcome::kAwaitingTransform;
  } catch (const std::exception& e) {
    dropCloud(slots_[index], ros::console::levels::Error, e.what());
    return true;
  }
}

void CloudReader::dropCloud(ObjectSlot& slot, ros::console::levels::Level level,
                            const std::string& problem) {
  ++clouds_rejected_;
  ++slot.clouds_dropped;
  std::lock_guard<std::mutex> lock(report_mutex_);
  ++slot.drops_unreported;
  // Throttled per object, so that one noisy topic cannot hide another one's problems.
  const auto now = Clock::now();
  if (slot.last_report && now - *slot.last_report < kReportPeriod) return;
  const std::string dropped_before = slot.drops_unreported > 1
                                         ? " (" + std::to_string(slot.drops_unreported - 1) +
                                               " more dropped since the last report)"
                                         : "";
  ROS_LOG(level, ROSCONSOLE_DEFAULT_NAME, "cloud on %s dropped, object '%s' unchanged: %s%s",
          slot.subscriber.getTopic().c_str(), slot.params.object.name.c_str(), problem.c_str(),
          dropped_before.c_str());
  slot.last_report = now;
  slot.drops_unreported = 0;
}

CloudReadResult CloudReader::readObjectCloud(const ObjectSlot& slot,
                                             const sensor_msgs::PointCloud2& cloud,
                                             std::size_t tracked_size,
                                             std::vector<Eigen::Vector3d>& points) const {
  // A tracked object keeps non-finite points as unobserved slots, so that point i of every
  // cloud is the same point even when the first cloud has holes (organized depth clouds).
  const bool tracked = slot.params.on_cloud == OnCloud::kTrack;
  CloudReadResult read =
      readCloudPoints(cloud, tracked ? NonFinitePoints::kKeepAsNaN : NonFinitePoints::kDrop,
                      config_.max_points_per_object, points);
  if (!read.ok()) return read;
  // A registered object's view may miss it: the registration holds the model and says so.
  const bool registered = slot.params.on_cloud == OnCloud::kRegister && slot.exists;
  if (points.empty() && !registered) {
    read.error = "the cloud is empty";
  } else if (tracked && tracked_size != 0 && points.size() != tracked_size) {
    read.error = trackedSizeProblem(points.size(), tracked_size);
  }
  return read;
}

std::string CloudReader::trackedSizeProblem(std::size_t points, std::size_t first_points) {
  return "it has " + std::to_string(points) + " points, the first had " +
         std::to_string(first_points) +
         " (a tracked object keeps its points; on_cloud: reset takes a new shape)";
}

CloudReader::CloudOutcome CloudReader::handleCloud(const sensor_msgs::PointCloud2& cloud,
                                                   std::size_t index, Clock::time_point arrival,
                                                   bool last_try) {
  ObjectSlot& slot = slots_[index];
  ObjectReader& reader = readers_[index];
  // A tracked object exists for the reader once it has made it: the clouds after the first
  // are fits of that object, which the first cloud brings into the scene (CloudHandoff::put).
  const bool tracked = slot.params.on_cloud == OnCloud::kTrack;
  const bool exists = tracked ? reader.fitter.has_value() : slot.exists.load();
  if (const auto waiting = waitForModel(slot, exists, last_try)) return *waiting;
  if (exists && slot.params.on_cloud == OnCloud::kIgnore) return CloudOutcome::kApplied;
  ReadCloud& read = reader.cloud;
  CloudReadResult result;
  if (const auto outcome = readAndPlace(cloud, index, last_try, read, result)) return *outcome;
  if (tracked && !exists &&
      std::none_of(read.points.begin(), read.points.end(),
                   [](const Eigen::Vector3d& p) { return p.allFinite(); })) {
    dropCloud(slot, ros::console::levels::Error, "every point is non-finite");
    return CloudOutcome::kRejected;
  }
  prepare(index, exists, read);
  non_finite_points_ += result.non_finite;
  read.stamp = cloud.header.stamp;
  read.arrival = arrival;
  read.float64 = result.datatype == sensor_msgs::PointField::FLOAT64;
  handOver(index, read);
  return CloudOutcome::kApplied;
}

std::optional<CloudReader::CloudOutcome> CloudReader::waitForModel(ObjectSlot& slot, bool exists,
                                                                   bool last_try) {
  if (exists || slot.params.model_file.empty()) return std::nullopt;
  // The cycle places the model once tf has model_frame; until then its clouds wait.
  if (!last_try) return CloudOutcome::kAwaitingTransform;
  dropCloud(slot, ros::console::levels::Warn,
            "its model waits for the transform from model_frame '" + slot.params.model_frame +
                "' to '" + config_.fixed_frame + "'");
  return CloudOutcome::kRejected;
}

std::optional<CloudReader::CloudOutcome> CloudReader::readAndPlace(
    const sensor_msgs::PointCloud2& cloud, std::size_t index, bool last_try, ReadCloud& read,
    CloudReadResult& result) {
  ObjectSlot& slot = slots_[index];
  const auto reject = [&](const std::string& problem) {
    dropCloud(slot, ros::console::levels::Error, problem);
    return CloudOutcome::kRejected;
  };
  result = readObjectCloud(slot, cloud, readers_[index].tracked_cloud_size, read.points);
  if (!result.ok()) return reject(result.error);
  std::string problem;
  switch (transformPoints(slot, cloud, last_try, read, problem)) {
    case TransformOutcome::kDone:
      break;
    case TransformOutcome::kNotYet:
      return CloudOutcome::kAwaitingTransform;
    case TransformOutcome::kMissing:
      dropCloud(slot, ros::console::levels::Warn, problem);
      return CloudOutcome::kRejected;
    case TransformOutcome::kRefused:
      return reject(problem);
  }
  // Finite but absurd coordinates would be taken as the object's shape or pose.
  problem = farCoordinateProblem(read.points, config_.max_coordinate_m, targetFrame(slot));
  if (!problem.empty()) return reject(problem);
  // A kinematic object is placed by its frame's pose, which may come later too.
  if (slot.params.object.kind == ObjectKind::kKinematic && !last_try &&
      !tf_buffer_.canTransform(config_.fixed_frame, slot.params.follow_frame, ros::Time(0))) {
    return CloudOutcome::kAwaitingTransform;
  }
  return std::nullopt;
}

void CloudReader::prepare(std::size_t index, bool exists, ReadCloud& read) {
  const ObjectSlot& slot = slots_[index];
  ObjectReader& reader = readers_[index];
  const bool tracked = slot.params.on_cloud == OnCloud::kTrack;
  read.prepared = Scene::PreparedObject();
  read.fitted = false;
  read.registration.reset();
  if (tracked && exists) {
    fitTrackedCloud(reader, read);
  } else if (exists && slot.params.on_cloud == OnCloud::kRegister) {
    registerCloud(slots_[index], reader, read);
  } else if (!exists || slot.params.on_cloud == OnCloud::kReset) {
    // A new shape's clusters and hierarchy (tens of milliseconds for thousands of points) are
    // built here, off the cycle's thread, which then only puts the object in the scene. The
    // rest shape is the cloud's finite points (a tracked cloud keeps its holes as NaN).
    std::vector<Eigen::Vector3d> rest_shape;
    rest_shape.reserve(read.points.size());
    std::copy_if(read.points.begin(), read.points.end(), std::back_inserter(rest_shape),
                 [](const Eigen::Vector3d& p) { return p.allFinite(); });
    read.prepared = scene_.prepareObject(slot.params.object, std::move(rest_shape));
    if (tracked) startTracking(reader, read);
  }
}

void CloudReader::startTracking(ObjectReader& reader, ReadCloud& read) {
  reader.fitter = read.prepared.trackedFitter();
  reader.tracked_cloud_size = read.points.size();
  reader.tracked_indices.clear();
  for (std::uint32_t i = 0; i < read.points.size(); ++i) {
    if (read.points[i].allFinite()) reader.tracked_indices.push_back(i);
  }
}

void CloudReader::fitTrackedCloud(ObjectReader& reader, ReadCloud& read) {
  // A first cloud without holes makes every later one the object's points as they are;
  // otherwise the cloud is taken down to the object's points where it lies (the indices
  // ascend, so none is overwritten before it is read), keeping its buffer's capacity.
  if (reader.tracked_indices.size() != read.points.size()) {
    for (std::size_t k = 0; k < reader.tracked_indices.size(); ++k) {
      read.points[k] = read.points[reader.tracked_indices[k]];
    }
    read.points.resize(reader.tracked_indices.size());
  }
  reader.fitter->fit(read.points, read.fit);
  read.fitted = true;
}

void CloudReader::registerCloud(ObjectSlot& slot, ObjectReader& reader, ReadCloud& read) const {
  // The cycle made the fitter before it said that the object exists, and leaves it to us.
  if (!reader.registration) {
    if (!slot.fitter) throw std::logic_error("the object exists without its registration");
    reader.registration = std::move(slot.fitter);
    slot.fitter.reset();
  }
  const int iterations = registration_iterations_;
  const std::size_t max_cloud_points = registration_max_cloud_points_;
  if (iterations != reader.iterations || max_cloud_points != reader.max_cloud_points) {
    reader.registration->setWorkPerCloud(iterations, max_cloud_points);
    reader.iterations = iterations;
    reader.max_cloud_points = max_cloud_points;
  }
  const double contact_distance_m = registration_contact_distance_m_;
  if (contact_distance_m != reader.contact_distance_m) {
    reader.registration->setContactDistance(contact_distance_m);
    reader.contact_distance_m = contact_distance_m;
  }
  if (slot.near_points.take(reader.near_points))
    reader.registration->setPointsNearObject(reader.near_points);
  read.registration = reader.registration->fit(read.points, read.viewpoint, read.fit);
  read.fitted = !read.registration->held;
  read.fit_error = read.registration->surface_error;
}

CloudReader::TransformOutcome CloudReader::transformPoints(const ObjectSlot& slot,
                                                           const sensor_msgs::PointCloud2& cloud,
                                                           bool last_try, ReadCloud& read,
                                                           std::string& problem) {
  const std::string& target_frame = targetFrame(slot);
  read.viewpoint.reset();
  if (cloud.header.frame_id.empty()) {
    problem = "header.frame_id is empty";
    return TransformOutcome::kRefused;
  }
  if (cloud.header.frame_id == target_frame) return TransformOutcome::kDone;
  if (!last_try && tfFromBeforeJump(target_frame, cloud.header.frame_id))
    return TransformOutcome::kNotYet;
  const CloudTransformLookup lookup =
      lookUpCloudTransform(tf_buffer_, target_frame, cloud.header.frame_id, cloud.header.stamp);
  if (lookup.status == CloudTransformStatus::kUnknownFrame) {
    problem = unknownFrameProblem(slot, cloud.header.frame_id);
    if (!problem.empty()) return TransformOutcome::kRefused;
  }
  if (lookup.status != CloudTransformStatus::kFound) {
    // The pose at the cloud's stamp may still come: a sensor's tf is often published after
    // its data.
    if (!last_try) return TransformOutcome::kNotYet;
    problem = "no transform from '" + cloud.header.frame_id + "' to '" + target_frame +
              "' within tf_wait_s = " + std::to_string(config_.tf_wait_s) + " s: " + lookup.error;
    return TransformOutcome::kMissing;
  }
  const std::optional<Eigen::Isometry3d> transform = toIsometry(lookup.transform);
  if (!transform) {
    problem = "the transform from '" + cloud.header.frame_id + "' to '" + target_frame +
              "' is not finite";
    return TransformOutcome::kRefused;
  }
  for (auto& p : read.points) p = *transform * p;
  read.viewpoint = transform->translation();
  return TransformOutcome::kDone;
}

void CloudReader::handOver(std::size_t index, ReadCloud& read) {
  handoff_.put(index, read);
  if (config_.cycle_on == CycleOn::kClouds &&
      slots_[index].params.object.kind == ObjectKind::kTracked) {
    wake_cycle_();
  }
}

}  // namespace deformable_collision
