#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "deformable_collision/GetContacts.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/Stats.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/cloud_handoff.h"
#include "deformable_collision/ros/cloud_reader.h"
#include "deformable_collision/ros/contact_service.h"
#include "deformable_collision/ros/counted_publisher.h"
#include "deformable_collision/ros/distance_outputs.h"
#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/ros/node_diagnostics.h"
#include "deformable_collision/ros/node_outputs.h"
#include "deformable_collision/ros/node_reconfigure.h"
#include "deformable_collision/ros/object_slot.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "deformable_collision/ros/publish_queue.h"

namespace deformable_collision {

/// The ROS side of the package: reads the configuration, turns clouds into scene objects,
/// runs the scene's cycle on a timer or on arriving clouds, and publishes what is
/// subscribed. Threads of its own, so that reading a cloud never delays a cycle:
/// - the reader (reader_queue_, `threads` spinner threads, at most one per object with a
///   topic; one object's clouds in order, one at a time) runs the cloud subscriptions and the
///   retries of clouds waiting for tf: reader_ (CloudReader) converts, transforms and
///   checks each cloud, makes new objects, fits tracked ones to their clouds and registers
///   registered ones, and hands each to the cycle through handoff_.
/// - the cycle (cycle_thread_, serving cycle_queue_) runs the timer, the cycles, the
///   services and the outputs' connect and disconnect callbacks (CountedPublisher). It
///   alone touches scene_, the cycle members of slots_ (index, poses, model, registration,
///   the deformed publisher's count), taken_, outputs_ (NodeOutputs) and diagnostics_.
/// Between them: handoff_ and each slot's near_points (their own mutexes), a registered
/// slot's fitter (the cycle's until it sets `exists`, then the reader's), the atomics of
/// slots_, the reader's counters and drop reports (its own mutex), and the wake-up flag. tf_buffer_
/// is thread-safe and filled by the listener's own thread. Everything else is set in the
/// constructor and only read afterwards.
class DeformableCollisionNode {
 public:
  /// Loads and validates every parameter before subscribing to anything.
  /// @throw std::invalid_argument naming the bad parameter.
  DeformableCollisionNode(ros::NodeHandle node_handle, ros::NodeHandle private_handle);
  /// Stops reading, then cycling, before anything they use goes.
  ~DeformableCollisionNode();

 private:
  using Clock = std::chrono::steady_clock;

  // The cycle (deformable_collision_node.cpp, node_registration.cpp).
  /// Applies each of `objects`' clouds in taken_ to its object and notes it for the next
  /// cycle's stamp and latencies.
  void applyTakenClouds(const std::vector<std::size_t>& objects);
  /// After a cycle, its clouds are no longer the next one's.
  void forgetAppliedClouds();
  /// Whether the cloud changed the object (an ignored object's is left alone).
  bool applyCloud(ObjectSlot& slot, ReadCloud& cloud);
  /// Puts the object the reader made from a cloud into the scene.
  void addObject(ObjectSlot& slot, ReadCloud& cloud);
  /// Points far apart compared with the contact distance let other clouds through: say so.
  void warnIfPorous(const std::string& name, const std::vector<Eigen::Vector3d>& points) const;
  /// Reads every model_file, so that a bad one stops the node at start, naming the object.
  /// @throw std::invalid_argument
  /// Advertises the outputs and services, subscribes to the clouds, starts the timers.
  void connect();
  /// Wakes the cycle for a cloud that may start one (the reader's hand-over).
  void wakeCycle();
  void loadModels();
  /// Creates the object of a slot from its model file at model_frame's latest pose, once tf
  /// has it; whether the object exists.
  bool placeModel(ObjectSlot& slot);
  /// Whether a model still waits for its frame.
  bool placeModels();
  // The robot links (node_robot.cpp).
  /// Samples each robot link's surface into its slot's model_points; a link that cannot be
  /// sampled, or all of them without a robot description, are logged and left out.
  void loadRobotLinks();
  /// The latest pose of a robot link's frame; std::nullopt (logged, throttled) if tf has none.
  std::optional<Eigen::Isometry3d> linkPose(const ObjectSlot& slot) const;
  /// Creates a robot link's object from its surface at its frame's pose, once tf has it;
  /// whether the object exists.
  bool placeLink(ObjectSlot& slot);
  /// Marks an object as in the scene for the reader; a registered one gets its fitter first.
  void announceToReader(ObjectSlot& slot);
  /// Takes the reader's registration of a cloud: its fit, and its report for ~stats.
  void takeRegistration(ObjectSlot& slot, ReadCloud& cloud);
  /// Gives each registered object's reader the other objects' points near it, as they are
  /// after this cycle.
  void shareNearPoints();
  /// Says that a registration held the model, at most once per 5 s per object.
  void reportHeld(ObjectSlot& slot);
  void fillRegistrationStats(Stats& stats) const;
  /// Poses the kinematic objects from tf at `stamp` (zero: the latest).
  void followFrames(const ros::Time& stamp);
  /// Notes ROS time `now`; if it went back (a looped bag), what was measured in the time
  /// before starts again, with one log line.
  void watchRosTime(const ros::Time& now);
  void cycleLoop();
  /// cycle_on clouds: a cycle if a cloud starts one and rate_hz allows it, else the clouds
  /// read meanwhile applied already; sets the wait until the next check.
  void cycleOnClouds();
  void onTimer(const ros::TimerEvent& event);
  using CycleTimes = NodeOutputs::CycleTimes;

  /// runCycle, an exception logged instead of ending the thread.
  void runCycleLogged();
  void runCycle();
  /// Scene::detectAhead for the clouds applied early, an exception logged.
  void detectAheadLogged();
  /// dt_s: stamp: the step from the last cycle's stamp to `stamp`.
  void stepToStamp(const ros::Time& stamp);
  /// The newest stamp of the tracked clouds applied for this cycle (early or by it); zero if
  /// none.
  ros::Time newestAppliedStamp() const;
  /// The arrival of the oldest cloud applied for this cycle, and each such cloud's latencies.
  std::optional<Clock::time_point> recordLatencies(const CycleTimes& times);
  /// Publishes the subscribed ~wrench/<object> of the kinematic objects, in their frames.
  void publishWrenches(const ros::Time& stamp);
  /// Publishes the subscribed ~deformed/<object> clouds; returns the points of all objects.
  std::size_t publishDeformed(const std_msgs::Header& header);
  void publishStats(const std_msgs::Header& header, const CycleTimes& times,
                    std::optional<Clock::time_point> oldest_input, std::size_t points);
  bool onSetLevel(SetLevel::Request& request, SetLevel::Response& response);
  /// The services' view of the objects, with the scene indices they have now.
  const std::vector<NamedObject>& namedObjects();
  bool onGetContacts(GetContacts::Request& request, GetContacts::Response& response);
  bool onGetDistance(GetDistance::Request& request, GetDistance::Response& response);

  // The queues come first: handles, subscribers and timers that use them go before them.
  ros::CallbackQueue reader_queue_;
  ros::CallbackQueue cycle_queue_;
  ros::NodeHandle node_handle_;
  ros::NodeHandle private_handle_;
  NodeConfig config_;
  Scene scene_;
  std::vector<ObjectSlot> slots_;
  CloudHandoff handoff_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;

  ros::ServiceServer set_level_service_;
  ros::ServiceServer get_contacts_service_;
  ros::ServiceServer get_distance_service_;
  ros::Timer timer_;
  ros::Timer retry_timer_;

  /// Set by the reader when it queues wake_ on cycle_queue_, cleared by the cycle before it
  /// looks at handoff_: one wake-up waits at most, and none is lost.
  std::atomic<bool> wake_pending_{false};
  std::atomic<bool> stopping_{false};
  ros::CallbackInterfacePtr wake_;
  CloudReader reader_;
  NodeReconfigure reconfigure_;  ///< The cycle's: its servers run on the cycle's queue.

  // The cycle's.
  std::vector<ReadCloud> taken_;
  std::vector<std::size_t> taken_slots_;
  std::vector<Eigen::Vector3d> near_points_;  ///< shareNearPoints()' buffer.
  /// A cloud applied to its object since the last cycle, early or by the cycle itself.
  struct AppliedCloud {
    bool pending = false;  ///< Applied, its contacts not yet published.
    ros::Time stamp;
    Clock::time_point arrival;
  };
  std::vector<AppliedCloud> applied_;
  std::vector<std::size_t> applied_slots_;  ///< Those pending, in the order applied.
  /// Clouds applied early and then replaced by a newer one before a cycle used them.
  std::uint64_t clouds_superseded_ = 0;
  std::optional<Clock::time_point> last_cycle_start_;
  /// The last cloud applied early and not yet detected ahead of its cycle; unset when there
  /// is none.
  std::optional<Clock::time_point> last_early_application_;
  ros::Time last_cycle_stamp_;
  ros::Time latest_ros_;  ///< The latest ROS time a cycle saw, to notice a jump back.
  bool models_waiting_ = false;
  const Clock::duration cycle_period_;  ///< 1 / rate_hz
  Clock::duration cycle_wait_;
  std::vector<SceneContact> query_contacts_;
  /// The services' view of slots_: names point into slots_[i].params, which never moves.
  std::vector<NamedObject> named_objects_;
  NodeOutputs outputs_;
  DistanceOutputs distance_outputs_;
  NodeDiagnostics diagnostics_;
  /// The markers and deformed clouds, published off the cycle's thread; after the
  /// publishers it uses, so it stops first. A slot per object's cloud and per marker array.
  PublishQueue<CountedPublisher> publish_queue_;

  // Last: they start after everything they use exists and stop before it goes.
  ros::AsyncSpinner reader_spinner_;
  std::thread cycle_thread_;
};

}  // namespace deformable_collision
