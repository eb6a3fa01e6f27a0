#include "deformable_collision/ros/deformable_collision_node.h"

#include <geometry_msgs/WrenchStamped.h>

#include <boost/bind/bind.hpp>
#include <boost/make_shared.hpp>

#include <algorithm>

#include "deformable_collision/core/common/point_spacing.h"
#include "deformable_collision/core/response/contact_totals.h"
#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/contact_array_serialization.h"
#include "deformable_collision/ros/message_vectors.h"

namespace deformable_collision {
namespace {

/// At most one report per problem in this period.
constexpr double kThrottlePeriodS = 5.0;
/// dt_s: stamp: the longest step, the top of dt_s's range.
constexpr double kLargestStepS = 0.1;
/// The cycle thread's wait when nothing is due; a wake-up (a cloud, a service call, the
/// timer, the destructor) ends it sooner.
constexpr std::chrono::milliseconds kIdleWait(100);
/// Clouds applied early are detected ahead of their cycle once none came for this long: a
/// pass for every cloud would pay the sweep and the copy of the kept contacts each time.
constexpr std::chrono::microseconds kQuietBeforeDetectingAhead(500);
/// ~hierarchy and ~contact_markers: the marker arrays a cycle queues besides its clouds.
constexpr std::size_t kQueuedMarkerArrays = 2;

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

/// Queued on the cycle's queue to end its wait; the cycle then looks at what came.
class WakeUp : public ros::CallbackInterface {
 public:
  CallResult call() override { return Success; }
};

/// Per object, whether its clouds start cycles (cycle_on: clouds): the tracked and
/// registered ones', read every time.
std::vector<bool> cloudsStartingCycles(const NodeConfig& config) {
  std::vector<bool> starting;
  for (const ObjectParams& object : config.objects) {
    starting.push_back(object.object.kind == ObjectKind::kTracked);
  }
  return starting;
}

/// The reader's threads: `threads`, but no more than there are objects with clouds, since
/// one object's clouds are read in order, one at a time.
std::uint32_t readerThreads(const NodeConfig& config) {
  const auto with_clouds = std::count_if(config.objects.begin(), config.objects.end(),
                                         [](const ObjectParams& o) { return !o.topic.empty(); });
  return static_cast<std::uint32_t>(
      std::max<std::ptrdiff_t>(1, std::min<std::ptrdiff_t>(config.scene.threads, with_clouds)));
}

}  // namespace

DeformableCollisionNode::DeformableCollisionNode(ros::NodeHandle node_handle,
                                                 ros::NodeHandle private_handle)
    : node_handle_(node_handle),
      private_handle_(private_handle),
      config_(loadConfig(private_handle)),
      scene_(config_.scene),
      slots_(config_.objects.size()),
      handoff_(cloudsStartingCycles(config_)),
      tf_listener_(tf_buffer_, node_handle),
      wake_(boost::make_shared<WakeUp>()),
      reader_(config_, slots_, scene_, handoff_, tf_buffer_, [this] { wakeCycle(); }),
      reconfigure_(scene_, config_, slots_, reader_),
      taken_(config_.objects.size()),
      applied_(config_.objects.size()),
      cycle_period_(std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(1.0 / config_.rate_hz))),
      cycle_wait_(kIdleWait),
      outputs_(Clock::now(), cycle_period_),
      distance_outputs_(config_.distance_pairs),
      diagnostics_(config_.diagnostics, slots_, outputs_),
      publish_queue_(config_.objects.size() + kQueuedMarkerArrays),
      reader_spinner_(readerThreads(config_), &reader_queue_) {
  for (std::size_t i = 0; i < slots_.size(); ++i) slots_[i].params = config_.objects[i];
  taken_slots_.reserve(slots_.size());
  applied_slots_.reserve(slots_.size());
  loadModels();
  loadRobotLinks();
  models_waiting_ = std::any_of(slots_.begin(), slots_.end(),
                                [](const ObjectSlot& slot) { return !slot.model_points.empty(); });

  connect();
  ROS_INFO(
      "deformable_collision: %zu objects, cycles on %s%s at %s%.1f Hz, dt %s%.4f s, contact "
      "distance %.4f m, fixed frame '%s'",
      slots_.size(), toString(config_.cycle_on), config_.cycle_on_all ? " (all objects')" : "",
      config_.cycle_on == CycleOn::kClouds ? "most " : "", config_.rate_hz,
      config_.dt_from_stamps ? "from the stamps, first " : "", config_.scene.dt_s,
      config_.scene.contact_distance_m, config_.fixed_frame.c_str());
  reader_spinner_.start();
  cycle_thread_ = std::thread(&DeformableCollisionNode::cycleLoop, this);
}

// Outputs and services go on the cycle's queue, the clouds and their tf retries on the
// reader's.
void DeformableCollisionNode::connect() {
  ros::NodeHandle reader_handle(node_handle_);
  reader_handle.setCallbackQueue(&reader_queue_);
  ros::NodeHandle cycle_handle(node_handle_);
  cycle_handle.setCallbackQueue(&cycle_queue_);
  ros::NodeHandle cycle_private_handle(private_handle_);
  cycle_private_handle.setCallbackQueue(&cycle_queue_);
  // Advertised on the cycle's queue, so that the cycle alone counts their subscribers.
  outputs_.advertise(cycle_private_handle);
  distance_outputs_.advertise(cycle_private_handle);
  diagnostics_.start(cycle_handle, private_handle_);
  reconfigure_.start(cycle_private_handle);
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    ObjectSlot& slot = slots_[i];
    named_objects_.push_back({slot.params.object.name, std::nullopt});
    slot.deformed.advertise<sensor_msgs::PointCloud2>(cycle_private_handle,
                                                      "deformed/" + slot.params.object.name, 1);
    if (slot.params.object.kind == ObjectKind::kKinematic) {
      slot.wrench.advertise<geometry_msgs::WrenchStamped>(cycle_private_handle,
                                                          "wrench/" + slot.params.object.name, 10);
    }
    // A ConstPtr callback: a cloud published in this process (a driver's nodelet in the
    // same manager) arrives as the publisher's shared pointer, never serialised.
    if (slot.params.topic.empty()) continue;  // A robot link has no cloud.
    slot.subscriber = reader_handle.subscribe<sensor_msgs::PointCloud2>(
        slot.params.topic, 2,
        boost::bind(&CloudReader::onCloud, &reader_, boost::placeholders::_1, i),
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  }
  retry_timer_ =
      reader_handle.createTimer(ros::Duration(1.0 / config_.rate_hz),
                                [this](const ros::TimerEvent&) { reader_.retryAwaitingClouds(); });
  set_level_service_ = cycle_private_handle.advertiseService(
      "set_level", &DeformableCollisionNode::onSetLevel, this);
  get_contacts_service_ = cycle_private_handle.advertiseService(
      "get_contacts", &DeformableCollisionNode::onGetContacts, this);
  get_distance_service_ = cycle_private_handle.advertiseService(
      "get_distance", &DeformableCollisionNode::onGetDistance, this);
  if (config_.cycle_on == CycleOn::kTimer) {
    timer_ = cycle_handle.createTimer(ros::Duration(1.0 / config_.rate_hz),
                                      &DeformableCollisionNode::onTimer, this);
  }
}

// One wake-up at a time: the cycle clears the flag before it looks at the handoff.
void DeformableCollisionNode::wakeCycle() {
  if (!wake_pending_.exchange(true)) cycle_queue_.addCallback(wake_);
}

DeformableCollisionNode::~DeformableCollisionNode() {
  reader_spinner_.stop();
  stopping_ = true;
  cycle_queue_.addCallback(wake_);
  if (cycle_thread_.joinable()) cycle_thread_.join();
}

void DeformableCollisionNode::cycleLoop() {
  while (!stopping_) {
    cycle_queue_.callAvailable(
        ros::WallDuration(std::chrono::duration<double>(cycle_wait_).count()));
    if (config_.cycle_on == CycleOn::kClouds && !stopping_) cycleOnClouds();
  }
}

void DeformableCollisionNode::cycleOnClouds() {
  // Cleared even when it is too soon for a cycle, so that every cloud of the wait wakes the
  // thread again (1900 times a second in the load test): leaving it set until the wait had
  // ended saved those wake-ups but made the load test's cycles longer (docs/design.md,
  // "The node's threads").
  wake_pending_ = false;
  if (models_waiting_) models_waiting_ = placeModels();
  // A model waiting for its frame is looked for at rate_hz, as the timer would.
  cycle_wait_ = models_waiting_ ? cycle_period_ : Clock::duration(kIdleWait);
  const bool ready = handoff_.ready(config_.cycle_on_all);
  const bool too_soon = last_cycle_start_ && Clock::now() < *last_cycle_start_ + cycle_period_;
  if (ready && !too_soon) {
    runCycleLogged();
    return;
  }
  // While the cycle waits for rate_hz or for the other objects' clouds, the clouds read
  // meanwhile are applied as they come: the cycle then applies only what came last, and the
  // clouds of a burst wait for one cycle's detection, not for their fits too
  // (docs/design.md, "The node's threads").
  handoff_.takeEarly(taken_, taken_slots_);
  applyTakenClouds(taken_slots_);
  Clock::time_point now = Clock::now();
  if (!taken_slots_.empty()) last_early_application_ = now;
  if (last_early_application_ && now - *last_early_application_ >= kQuietBeforeDetectingAhead) {
    detectAheadLogged();
    now = Clock::now();
  }
  if (ready)
    cycle_wait_ = std::max(Clock::duration::zero(), *last_cycle_start_ + cycle_period_ - now);
  if (last_early_application_) {
    cycle_wait_ =
        std::min(cycle_wait_, *last_early_application_ + kQuietBeforeDetectingAhead - now);
  }
}

void DeformableCollisionNode::detectAheadLogged() {
  // Detected or not, these clouds wait for the cycle now.
  last_early_application_.reset();
  try {
    scene_.detectAhead();
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE(kThrottlePeriodS, "detection ahead of the cycle failed: %s", e.what());
  }
}

void DeformableCollisionNode::onTimer(const ros::TimerEvent&) {
  if (models_waiting_) models_waiting_ = placeModels();
  runCycleLogged();
}

void DeformableCollisionNode::runCycleLogged() {
  try {
    runCycle();
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE(kThrottlePeriodS, "cycle failed: %s", e.what());
  }
  forgetAppliedClouds();
}

void DeformableCollisionNode::applyTakenClouds(const std::vector<std::size_t>& objects) {
  for (const std::size_t index : objects) {
    ObjectSlot& slot = slots_[index];
    try {
      if (!applyCloud(slot, taken_[index])) continue;
    } catch (const std::exception& e) {
      reader_.dropCloud(slot, ros::console::levels::Error, e.what());
      continue;
    }
    AppliedCloud& applied = applied_[index];
    if (applied.pending) {
      ++clouds_superseded_;
    } else {
      applied.pending = true;
      applied_slots_.push_back(index);
    }
    applied.stamp = taken_[index].stamp;
    applied.arrival = taken_[index].arrival;
  }
}

void DeformableCollisionNode::forgetAppliedClouds() {
  for (const std::size_t index : applied_slots_) applied_[index].pending = false;
  applied_slots_.clear();
}

bool DeformableCollisionNode::applyCloud(ObjectSlot& slot, ReadCloud& cloud) {
  if (slot.index && slot.params.on_cloud == OnCloud::kIgnore) return false;
  std::optional<Eigen::Isometry3d> pose;
  if (slot.params.object.kind == ObjectKind::kKinematic) {
    // A kinematic rest shape lives in its frame: without that frame's pose it has no place.
    const geometry_msgs::TransformStamped stamped =
        tf_buffer_.lookupTransform(config_.fixed_frame, slot.params.follow_frame, ros::Time(0));
    pose = toIsometry(stamped.transform);
    if (!pose)
      throw std::invalid_argument("the pose of " + slot.params.follow_frame + " is not finite");
  }
  if (!slot.index) {
    addObject(slot, cloud);
  } else if (slot.params.on_cloud == OnCloud::kReset) {
    scene_.resetRestShape(*slot.index, std::move(cloud.prepared));
    reconfigure_.reapply(slot);
  } else if (slot.params.on_cloud == OnCloud::kRegister) {
    takeRegistration(slot, cloud);
  }
  // A tracked object's clouds after its first are fits the reader made; the first one the
  // cycle takes may be one of them, bringing the object made from the cloud it replaced.
  if (cloud.fitted && slot.params.on_cloud == OnCloud::kTrack)
    scene_.observeFitted(*slot.index, cloud.points, cloud.fit);
  if (pose) {
    scene_.setPose(*slot.index, *pose);
    slot.last_pose = *pose;
  }
  slot.float64 = cloud.float64;
  return true;
}

void DeformableCollisionNode::addObject(ObjectSlot& slot, ReadCloud& cloud) {
  slot.index = scene_.addObject(std::move(cloud.prepared));
  reconfigure_.reapply(slot);
  // The rest shape: the cloud's finite points, which the cloud may not hold any more (a later
  // cloud of a tracked object brings it, its points fitted).
  const std::vector<Eigen::Vector3d>& points = scene_.body(*slot.index).restPositions();
  ROS_INFO("object '%s': rest shape of %zu points from %s, %s", slot.params.object.name.c_str(),
           points.size(), slot.subscriber.getTopic().c_str(), toString(slot.params.object.kind));
  warnIfPorous(slot.params.object.name, points);
  announceToReader(slot);
}

void DeformableCollisionNode::warnIfPorous(const std::string& name,
                                           const std::vector<Eigen::Vector3d>& points) const {
  // Against a dense cloud a sparse one still shows contacts; two clouds sparser than this
  // can cross without a single pair of points coming within the contact distance.
  const double spacing = typicalPointSpacing(points);
  const double contact_distance_m = scene_.config().contact_distance_m;
  if (spacing > 2.0 * contact_distance_m) {
    ROS_WARN(
        "object '%s': its points are about %.4f m apart, more than twice "
        "contact_distance_m = %.4f m, so clouds as sparse can pass between them; raise "
        "contact_distance_m towards the spacing",
        name.c_str(), spacing, contact_distance_m);
  }
}

void DeformableCollisionNode::followFrames(const ros::Time& stamp) {
  for (ObjectSlot& slot : slots_) {
    if (!slot.index || slot.params.object.kind != ObjectKind::kKinematic) continue;
    // At the clouds' stamp, which the outputs carry, so that contacts are those of one
    // instant (a bag replayed at any rate gives the same); the latest if tf is not there yet.
    const ros::Time at = !stamp.isZero() && tf_buffer_.canTransform(config_.fixed_frame,
                                                                    slot.params.follow_frame, stamp)
                             ? stamp
                             : ros::Time(0);
    std::optional<Eigen::Isometry3d> pose;
    try {
      pose = toIsometry(
          tf_buffer_.lookupTransform(config_.fixed_frame, slot.params.follow_frame, at).transform);
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

void DeformableCollisionNode::watchRosTime(const ros::Time& now) {
  if (now < latest_ros_) {
    ROS_WARN(
        "ROS time went back %.3f s (a looped bag?): the steps from stamps and the latency "
        "windows start again; tf clears its own buffer",
        (latest_ros_ - now).toSec());
    last_cycle_stamp_ = ros::Time();
    outputs_.latencies().restart(Clock::now());
  }
  latest_ros_ = now;
}

void DeformableCollisionNode::runCycle() {
  CycleTimes times;
  times.start = Clock::now();
  last_cycle_start_ = times.start;
  last_early_application_.reset();
  handoff_.takeForCycle(taken_, taken_slots_);
  applyTakenClouds(taken_slots_);
  times.clouds_applied = Clock::now();
  std_msgs::Header header;
  header.stamp = ros::Time::now();
  header.frame_id = config_.fixed_frame;
  watchRosTime(header.stamp);
  ros::Time clouds_stamp;
  if (config_.cycle_on == CycleOn::kClouds) {
    // The outputs of a cycle that clouds started carry those clouds' time.
    clouds_stamp = newestAppliedStamp();
    if (!clouds_stamp.isZero()) {
      if (config_.dt_from_stamps) stepToStamp(clouds_stamp);
      header.stamp = clouds_stamp;
    }
  }
  followFrames(clouds_stamp);
  scene_.cycle();
  shareNearPoints();
  times.cycled = Clock::now();
  outputs_.publishContacts(scene_, header);
  times.contacts_published = Clock::now();
  times.contacts_published_ros = ros::Time::now();
  const std::optional<Clock::time_point> oldest_input = recordLatencies(times);
  distance_outputs_.publish(scene_, namedObjects(), header);
  outputs_.publishMarkers(scene_, config_.markers_colliding_only, header, publish_queue_);
  outputs_.publishForces(scene_, config_.force_marker_scale_m_per_n, header, publish_queue_);
  publishWrenches(header.stamp);
  const std::size_t points = publishDeformed(header);
  times.published = Clock::now();
  publishStats(header, times, oldest_input, points);
}

ros::Time DeformableCollisionNode::newestAppliedStamp() const {
  ros::Time newest;
  for (const std::size_t index : applied_slots_) {
    if (slots_[index].params.object.kind == ObjectKind::kTracked)
      newest = std::max(newest, applied_[index].stamp);
  }
  return newest;
}

void DeformableCollisionNode::stepToStamp(const ros::Time& stamp) {
  // A stamp that does not advance (a repeated or older one) keeps the step as it was.
  if (!last_cycle_stamp_.isZero() && stamp <= last_cycle_stamp_) return;
  if (!last_cycle_stamp_.isZero()) {
    scene_.setTimeStep(std::min((stamp - last_cycle_stamp_).toSec(), kLargestStepS));
  }
  last_cycle_stamp_ = stamp;
}

std::optional<DeformableCollisionNode::Clock::time_point> DeformableCollisionNode::recordLatencies(
    const CycleTimes& times) {
  std::optional<Clock::time_point> oldest_input;
  for (const std::size_t index : applied_slots_) {
    const AppliedCloud& cloud = applied_[index];
    if (!oldest_input || cloud.arrival < *oldest_input) oldest_input = cloud.arrival;
    outputs_.latencies().add(cloud.arrival, cloud.stamp, times.contacts_published,
                             times.contacts_published_ros);
  }
  outputs_.latencies().closePeriodIfDue(times.contacts_published);
  return oldest_input;
}

// What a force-torque sensor at the object's frame would read of its soft contacts.
void DeformableCollisionNode::publishWrenches(const ros::Time& stamp) {
  for (const ObjectSlot& slot : slots_) {
    if (!slot.index || !slot.last_pose || !slot.wrench.subscribed()) continue;
    const Wrench wrench =
        wrenchOn(scene_.contacts(), static_cast<std::uint32_t>(*slot.index), *slot.last_pose);
    geometry_msgs::WrenchStamped message;
    message.header.stamp = stamp;
    message.header.frame_id = slot.params.follow_frame;
    message.wrench.force = toVectorMessage(wrench.force_n);
    message.wrench.torque = toVectorMessage(wrench.torque_nm);
    slot.wrench.publish(message);
  }
}

std::size_t DeformableCollisionNode::publishDeformed(const std_msgs::Header& header) {
  std::size_t points = 0;
  for (const ObjectSlot& slot : slots_) {
    if (!slot.index) continue;
    const auto& positions = scene_.body(*slot.index).positions();
    points += positions.size();
    if (!slot.deformed.subscribed()) continue;
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    cloud->header = header;
    writeCloudPoints(
        positions, *cloud,
        slot.float64 ? sensor_msgs::PointField::FLOAT64 : sensor_msgs::PointField::FLOAT32);
    publish_queue_.post(slot.deformed, cloud);
  }
  return points;
}

void DeformableCollisionNode::publishStats(const std_msgs::Header& header, const CycleTimes& times,
                                           std::optional<Clock::time_point> oldest_input,
                                           std::size_t points) {
  NodeOutputs::InputCounts counts;
  counts.clouds_received = reader_.cloudsReceived();
  counts.clouds_rejected = reader_.cloudsRejected();
  counts.clouds_coalesced = handoff_.coalesced() + clouds_superseded_;
  counts.non_finite_points = reader_.nonFinitePoints();
  counts.reader_busy_s = reader_.busySeconds();
  counts.reconfigurations_accepted = reconfigure_.accepted();
  counts.reconfigurations_refused = reconfigure_.refused();
  outputs_.publishStats(scene_, header, times, oldest_input, points, counts,
                        [this](Stats& stats) { fillRegistrationStats(stats); });
}

bool DeformableCollisionNode::onSetLevel(SetLevel::Request& request, SetLevel::Response& response) {
  answerSetLevel(scene_, request, response, config_.scene.cycle_budget_ms);
  return true;
}

const std::vector<NamedObject>& DeformableCollisionNode::namedObjects() {
  for (std::size_t i = 0; i < slots_.size(); ++i) named_objects_[i].scene_index = slots_[i].index;
  return named_objects_;
}

bool DeformableCollisionNode::onGetContacts(GetContacts::Request& request,
                                            GetContacts::Response& response) {
  answerGetContacts(scene_, scene_.detectionCosts(), namedObjects(), request, query_contacts_,
                    response);
  response.contacts.header.stamp = ros::Time::now();
  response.contacts.header.frame_id = config_.fixed_frame;
  return true;
}

bool DeformableCollisionNode::onGetDistance(GetDistance::Request& request,
                                            GetDistance::Response& response) {
  answerGetDistance(scene_, namedObjects(), request, response);
  response.header.stamp = ros::Time::now();
  response.header.frame_id = config_.fixed_frame;
  return true;
}

}  // namespace deformable_collision
