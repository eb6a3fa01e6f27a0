#include "deformable_collision/ros/deformable_collision_node.h"

#include <boost/bind/bind.hpp>
#include <boost/make_shared.hpp>

#include <algorithm>

#include "deformable_collision/core/point_spacing.h"
#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {
namespace {

/// At most one report per problem (per object, for dropped clouds) in this period.
constexpr std::chrono::seconds kReportPeriod(5);
constexpr double kThrottlePeriodS = std::chrono::duration<double>(kReportPeriod).count();
/// Per object: enough for a sensor at 30 Hz whose tf lags by a few frames.
constexpr std::size_t kMaxAwaitingClouds = 8;
/// The listener's subscriptions to /tf and /tf_static are made when the node starts, and on
/// a loaded machine their first transforms can take about this long: before, no frame is
/// known, and an unknown frame only means that tf has not filled yet.
constexpr double kTfFillMinimumS = 1.0;

NodeConfig loadConfig(const ros::NodeHandle& private_handle) {
  XmlRpc::XmlRpcValue params;
  if (!private_handle.getParam(private_handle.getNamespace(), params)) {
    throw std::invalid_argument("no parameters under " + private_handle.getNamespace() +
                                ": load a config (see config/demo.yaml)");
  }
  std::vector<std::string> warnings;
  NodeConfig config = parseNodeConfig(params, warnings);
  for (const std::string& warning : warnings) ROS_WARN("%s", warning.c_str());
  return config;
}

double millisecondsBetween(std::chrono::steady_clock::time_point from,
                           std::chrono::steady_clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

}  // namespace

DeformableCollisionNode::DeformableCollisionNode(ros::NodeHandle node_handle,
                                                 ros::NodeHandle private_handle)
    : node_handle_(node_handle),
      private_handle_(private_handle),
      config_(loadConfig(private_handle)),
      started_(Clock::now()),
      scene_(config_.scene),
      tf_listener_(tf_buffer_, node_handle) {
  contacts_publisher_ = private_handle_.advertise<ContactArray>("contacts", 10);
  hierarchy_publisher_ = private_handle_.advertise<visualization_msgs::MarkerArray>("hierarchy", 1);
  stats_publisher_ = private_handle_.advertise<Stats>("stats", 10);
  slots_.resize(config_.objects.size());
  for (std::size_t i = 0; i < slots_.size(); ++i) slots_[i].params = config_.objects[i];
  loadModels();
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    ObjectSlot& slot = slots_[i];
    named_objects_.push_back({slot.params.object.name, std::nullopt});
    slot.deformed = private_handle_.advertise<sensor_msgs::PointCloud2>(
        "deformed/" + slot.params.object.name, 1);
    slot.subscriber = node_handle_.subscribe<sensor_msgs::PointCloud2>(
        slot.params.topic, 2,
        boost::bind(&DeformableCollisionNode::onCloud, this, boost::placeholders::_1, i),
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  }
  set_level_service_ =
      private_handle_.advertiseService("set_level", &DeformableCollisionNode::onSetLevel, this);
  get_contacts_service_ =
      private_handle_.advertiseService("get_contacts", &DeformableCollisionNode::onGetContacts, this);
  timer_ = node_handle_.createTimer(ros::Duration(1.0 / config_.rate_hz),
                                    &DeformableCollisionNode::onTimer, this);
  ROS_INFO("deformable_collision: %zu objects, %.1f Hz, dt %.4f s, contact distance %.4f m, "
           "fixed frame '%s'",
           slots_.size(), config_.rate_hz, config_.scene.dt_s, config_.scene.contact_distance_m,
           config_.fixed_frame.c_str());
}

void DeformableCollisionNode::onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud,
                                      std::size_t index) {
  ObjectSlot& slot = slots_[index];
  ++stats_message_.clouds_received;
  const auto arrival = Clock::now();
  // Behind older clouds that wait for their transform, in arrival order: a tracked object
  // must not step back, and a sensor whose tf always lags keeps every cloud. A cloud in a
  // frame tf does not know would only take the place of one that can still be placed.
  if (!slot.awaiting_transform.empty()) {
    const std::string problem = unknownFrameProblem(slot, cloud->header.frame_id);
    if (!problem.empty()) {
      dropCloud(slot, ros::console::levels::Error, problem);
      return;
    }
    if (slot.awaiting_transform.size() == kMaxAwaitingClouds) {
      slot.awaiting_transform.pop_front();
      dropCloud(slot, ros::console::levels::Warn,
                "more than " + std::to_string(kMaxAwaitingClouds) + " clouds wait for their transform");
    }
    slot.awaiting_transform.push_back({cloud, arrival});
    retryAwaitingClouds(index, arrival);
    return;
  }
  if (!processCloud(index, *cloud, arrival, config_.tf_wait_s == 0.0)) {
    slot.awaiting_transform.push_back({cloud, arrival});
  }
}

bool DeformableCollisionNode::tfFilling() const {
  // The longer of the two: a tf_wait_s above the minimum says that the transforms of this
  // setup may lag that long, and at start-up that includes the first one naming a frame.
  const double fill_s = std::max(config_.tf_wait_s, kTfFillMinimumS);
  return std::chrono::duration<double>(Clock::now() - started_).count() < fill_s;
}

const std::string& DeformableCollisionNode::targetFrame(const ObjectSlot& slot) const {
  return slot.params.object.kind == ObjectKind::kKinematic ? slot.params.follow_frame
                                                           : config_.fixed_frame;
}

std::string DeformableCollisionNode::unknownFrameProblem(const ObjectSlot& slot,
                                                         const std::string& frame) const {
  if (frame.empty() || frame == targetFrame(slot) || tfFilling() || tf_buffer_._frameExists(frame)) {
    return "";
  }
  return "tf knows no frame '" + frame + "', so the cloud is dropped without waiting tf_wait_s";
}

void DeformableCollisionNode::retryAwaitingClouds() {
  const auto now = Clock::now();
  for (std::size_t index = 0; index < slots_.size(); ++index) retryAwaitingClouds(index, now);
}

void DeformableCollisionNode::retryAwaitingClouds(std::size_t index, Clock::time_point now) {
  auto& awaiting = slots_[index].awaiting_transform;
  while (!awaiting.empty()) {
    const AwaitingCloud& oldest = awaiting.front();
    const bool last_try =
        std::chrono::duration<double>(now - oldest.arrival).count() >= config_.tf_wait_s;
    // tf arrives in time order: while the oldest cannot be placed, the newer wait too.
    if (!processCloud(index, *oldest.cloud, oldest.arrival, last_try)) return;
    awaiting.pop_front();
  }
}

bool DeformableCollisionNode::processCloud(std::size_t index, const sensor_msgs::PointCloud2& cloud,
                                           Clock::time_point arrival, bool last_try) {
  // An exception leaving a callback would take the whole nodelet manager down.
  try {
    return handleCloud(cloud, index, arrival, last_try) != CloudOutcome::kAwaitingTransform;
  } catch (const std::exception& e) {
    dropCloud(slots_[index], ros::console::levels::Error, e.what());
    return true;
  }
}

void DeformableCollisionNode::dropCloud(ObjectSlot& slot, ros::console::levels::Level level,
                                        const std::string& problem) {
  ++stats_message_.clouds_rejected;
  ++slot.drops_unreported;
  // Throttled per object, so that one noisy topic cannot hide another one's problems.
  const auto now = Clock::now();
  if (slot.last_report && now - *slot.last_report < kReportPeriod) return;
  const std::string dropped_before =
      slot.drops_unreported > 1
          ? " (" + std::to_string(slot.drops_unreported - 1) + " more dropped since the last report)"
          : "";
  ROS_LOG(level, ROSCONSOLE_DEFAULT_NAME, "cloud on %s dropped, object '%s' unchanged: %s%s",
          slot.subscriber.getTopic().c_str(), slot.params.object.name.c_str(), problem.c_str(),
          dropped_before.c_str());
  slot.last_report = now;
  slot.drops_unreported = 0;
}

CloudReadResult DeformableCollisionNode::readObjectCloud(const ObjectSlot& slot,
                                                        const sensor_msgs::PointCloud2& cloud) {
  // A tracked object keeps non-finite points as unobserved slots, so that point i of every
  // cloud is the same point even when the first cloud has holes (organized depth clouds).
  const bool tracked = slot.params.on_cloud == OnCloud::kTrack;
  CloudReadResult read =
      readCloudPoints(cloud, tracked ? NonFinitePoints::kKeepAsNaN : NonFinitePoints::kDrop,
                      config_.max_points_per_object, cloud_points_);
  if (!read.ok()) return read;
  // A registered object's view may miss it: the registration holds the model and says so.
  const bool registered = slot.params.on_cloud == OnCloud::kRegister && slot.index;
  if (cloud_points_.empty() && !registered) {
    read.error = "the cloud is empty";
  } else if (tracked && slot.index && cloud_points_.size() != slot.tracked_cloud_size) {
    read.error = "it has " + std::to_string(cloud_points_.size()) + " points, the first had " +
                 std::to_string(slot.tracked_cloud_size) +
                 " (a tracked object keeps its points; on_cloud: reset takes a new shape)";
  }
  return read;
}

void DeformableCollisionNode::selectTrackedPoints(const std::vector<std::uint32_t>& indices) {
  tracked_points_.resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) tracked_points_[k] = cloud_points_[indices[k]];
}

DeformableCollisionNode::CloudOutcome DeformableCollisionNode::handleCloud(
    const sensor_msgs::PointCloud2& cloud, std::size_t index, Clock::time_point arrival,
    bool last_try) {
  ObjectSlot& slot = slots_[index];
  if (const std::optional<CloudOutcome> waiting = awaitModel(slot, last_try)) return *waiting;
  const bool first = !slot.index;
  if (!first && slot.params.on_cloud == OnCloud::kIgnore) return CloudOutcome::kApplied;

  const auto reject = [&](const std::string& problem) {
    dropCloud(slot, ros::console::levels::Error, problem);
    return CloudOutcome::kRejected;
  };
  const CloudReadResult read = readObjectCloud(slot, cloud);
  if (!read.ok()) return reject(read.error);
  std::string problem;
  switch (transformPoints(slot, cloud, last_try, cloud_points_, problem)) {
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
  problem = farCoordinateProblem(cloud_points_, config_.max_coordinate_m, targetFrame(slot));
  if (!problem.empty()) return reject(problem);
  // A kinematic object is placed by its frame's pose, which may come later too.
  if (slot.params.object.kind == ObjectKind::kKinematic && !last_try &&
      !tf_buffer_.canTransform(config_.fixed_frame, slot.params.follow_frame, ros::Time(0))) {
    return CloudOutcome::kAwaitingTransform;
  }
  const bool tracked = slot.params.on_cloud == OnCloud::kTrack;
  std::vector<std::uint32_t> first_finite;
  if (tracked && first) {
    for (std::uint32_t i = 0; i < cloud_points_.size(); ++i) {
      if (cloud_points_[i].allFinite()) first_finite.push_back(i);
    }
    if (first_finite.empty()) return reject("every point is non-finite");
  }
  if (tracked) selectTrackedPoints(first ? first_finite : slot.tracked_indices);
  try {
    applyCloud(slot, tracked ? tracked_points_ : cloud_points_, first);
  } catch (const std::exception& e) {
    return reject(e.what());
  }
  if (tracked && first) {
    slot.tracked_indices = std::move(first_finite);
    slot.tracked_cloud_size = cloud_points_.size();
  }
  stats_message_.non_finite_points += read.non_finite;
  if (!slot.pending_since) slot.pending_since = arrival;
  return CloudOutcome::kApplied;
}

void DeformableCollisionNode::applyCloud(ObjectSlot& slot, std::vector<Eigen::Vector3d>& points,
                                         bool first) {
  std::optional<Eigen::Isometry3d> pose;
  if (slot.params.object.kind == ObjectKind::kKinematic) {
    // A kinematic rest shape lives in its frame: without that frame's pose it has no place.
    const geometry_msgs::TransformStamped stamped =
        tf_buffer_.lookupTransform(config_.fixed_frame, slot.params.follow_frame, ros::Time(0));
    pose = toIsometry(stamped.transform);
    if (!pose) throw std::invalid_argument("the pose of " + slot.params.follow_frame + " is not finite");
  }
  if (first) {
    slot.index = scene_.addObject(slot.params.object, points);
    ROS_INFO("object '%s': rest shape of %zu points from %s, %s", slot.params.object.name.c_str(),
             points.size(), slot.subscriber.getTopic().c_str(),
             toString(slot.params.object.kind));
    warnIfPorous(slot.params.object.name, points);
  } else if (slot.params.on_cloud == OnCloud::kReset) {
    scene_.resetRestShape(*slot.index, points);
  } else if (slot.params.on_cloud == OnCloud::kRegister) {
    registerCloud(slot, points);
  } else {
    scene_.observe(*slot.index, points);
  }
  if (pose) {
    scene_.setPose(*slot.index, *pose);
    slot.last_pose = *pose;
  }
}

void DeformableCollisionNode::warnIfPorous(const std::string& name,
                                            const std::vector<Eigen::Vector3d>& points) const {
  // Against a dense cloud a sparse one still shows contacts; two clouds sparser than this
  // can cross without a single pair of points coming within the contact distance.
  const double spacing = typicalPointSpacing(points);
  if (spacing > 2.0 * config_.scene.contact_distance_m) {
    ROS_WARN("object '%s': its points are about %.4f m apart, more than twice "
             "contact_distance_m = %.4f m, so clouds as sparse can pass between them; raise "
             "contact_distance_m towards the spacing", name.c_str(), spacing,
             config_.scene.contact_distance_m);
  }
}

DeformableCollisionNode::TransformOutcome DeformableCollisionNode::transformPoints(
    const ObjectSlot& slot, const sensor_msgs::PointCloud2& cloud, bool last_try,
    std::vector<Eigen::Vector3d>& points, std::string& problem) {
  const std::string& target_frame = targetFrame(slot);
  cloud_viewpoint_.reset();
  if (cloud.header.frame_id.empty()) {
    problem = "header.frame_id is empty";
    return TransformOutcome::kRefused;
  }
  if (cloud.header.frame_id == target_frame) return TransformOutcome::kDone;
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
  for (auto& p : points) p = *transform * p;
  cloud_viewpoint_ = transform->translation();
  return TransformOutcome::kDone;
}

void DeformableCollisionNode::followFrames() {
  for (ObjectSlot& slot : slots_) {
    if (!slot.index || slot.params.object.kind != ObjectKind::kKinematic) continue;
    std::optional<Eigen::Isometry3d> pose;
    try {
      pose = toIsometry(
          tf_buffer_.lookupTransform(config_.fixed_frame, slot.params.follow_frame, ros::Time(0))
              .transform);
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(kThrottlePeriodS, "object '%s' keeps its last pose: %s",
                        slot.params.object.name.c_str(), e.what());
      continue;
    }
    // An unchanged pose costs nothing: the object's points and spheres stay as they are.
    if (!pose || (slot.last_pose && pose->matrix() == slot.last_pose->matrix())) continue;
    scene_.setPose(*slot.index, *pose);
    slot.last_pose = *pose;
  }
}

void DeformableCollisionNode::onTimer(const ros::TimerEvent&) {
  try {
    placeModels();
    retryAwaitingClouds();
    runCycle();
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE(kThrottlePeriodS, "cycle failed: %s", e.what());
  }
}

void DeformableCollisionNode::runCycle() {
  CycleTimes times;
  times.start = Clock::now();
  followFrames();
  scene_.cycle();
  times.cycled = Clock::now();
  const CycleStats& cycle = scene_.stats();
  std_msgs::Header header;
  header.stamp = ros::Time::now();
  header.frame_id = config_.fixed_frame;

  if (contacts_publisher_.getNumSubscribers() > 0) {
    auto message = boost::make_shared<ContactArray>();
    message->header = header;
    fillContactArray(scene_, scene_.contacts(), cycle.level, *message);
    contacts_publisher_.publish(message);
  }
  times.contacts_published = Clock::now();
  const std::optional<Clock::time_point> oldest_input = takeOldestInput();

  if (hierarchy_publisher_.getNumSubscribers() > 0 && scene_.objectCount() > 0) {
    auto markers = boost::make_shared<visualization_msgs::MarkerArray>();
    markers_.build(scene_, cycle.level, scene_.contacts(), config_.markers_colliding_only, header,
                   *markers);
    hierarchy_publisher_.publish(markers);
  }
  const std::size_t points = publishDeformed(header);
  times.published = Clock::now();
  publishStats(header, times, oldest_input, points);
}

std::optional<DeformableCollisionNode::Clock::time_point> DeformableCollisionNode::takeOldestInput() {
  std::optional<Clock::time_point> oldest_input;
  for (ObjectSlot& slot : slots_) {
    if (slot.pending_since && (!oldest_input || *slot.pending_since < *oldest_input)) {
      oldest_input = slot.pending_since;
    }
    slot.pending_since.reset();
  }
  return oldest_input;
}

std::size_t DeformableCollisionNode::publishDeformed(const std_msgs::Header& header) {
  std::size_t points = 0;
  for (const ObjectSlot& slot : slots_) {
    if (!slot.index) continue;
    const auto& positions = scene_.body(*slot.index).positions();
    points += positions.size();
    if (slot.deformed.getNumSubscribers() == 0) continue;
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    cloud->header = header;
    writeCloudPoints(positions, *cloud);
    slot.deformed.publish(cloud);
  }
  return points;
}

void DeformableCollisionNode::publishStats(const std_msgs::Header& header, const CycleTimes& times,
                                           std::optional<Clock::time_point> oldest_input,
                                           std::size_t points) {
  const CycleStats& cycle = scene_.stats();
  Stats& stats = stats_message_;
  // Cycles and overruns count whether or not anyone listens: a later subscriber sees all.
  ++stats.cycles;
  const double cycle_ms = millisecondsBetween(times.start, times.published);
  if (cycle_ms > 1000.0 / config_.rate_hz) ++stats.overruns;
  if (stats_publisher_.getNumSubscribers() == 0) return;
  stats.header = header;
  stats.level = static_cast<std::uint8_t>(cycle.level);
  stats.max_level = static_cast<std::uint8_t>(scene_.maxLevel());
  stats.shape_matching_ms = cycle.shape_matching_ms;
  stats.detection_ms = cycle.detection_ms;
  stats.response_ms = cycle.response_ms;
  stats.publish_ms = millisecondsBetween(times.cycled, times.published);
  stats.cycle_ms = cycle_ms;
  stats.input_latency_ms =
      oldest_input ? millisecondsBetween(*oldest_input, times.contacts_published) : 0.0;
  stats.objects = static_cast<std::uint32_t>(scene_.objectCount());
  stats.points = static_cast<std::uint32_t>(points);
  stats.objects_moved = static_cast<std::uint32_t>(cycle.objects_moved);
  stats.spheres_updated = static_cast<std::uint32_t>(cycle.spheres_updated);
  stats.node_pairs_tested = static_cast<std::uint32_t>(cycle.node_pairs_tested);
  stats.point_tests = static_cast<std::uint32_t>(cycle.point_tests);
  stats.contacts = static_cast<std::uint32_t>(cycle.contacts);
  fillRegistrationStats(stats);
  stats_publisher_.publish(stats);
}

bool DeformableCollisionNode::onSetLevel(SetLevel::Request& request, SetLevel::Response& response) {
  answerSetLevel(scene_, request, response);
  return true;
}

bool DeformableCollisionNode::onGetContacts(GetContacts::Request& request,
                                            GetContacts::Response& response) {
  for (std::size_t i = 0; i < slots_.size(); ++i) named_objects_[i].scene_index = slots_[i].index;
  answerGetContacts(scene_, named_objects_, request, query_contacts_, response);
  response.contacts.header.stamp = ros::Time::now();
  response.contacts.header.frame_id = config_.fixed_frame;
  return true;
}

}  // namespace deformable_collision
