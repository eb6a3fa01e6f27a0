#pragma once

#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/cloud_handoff.h"
#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/ros/object_slot.h"
#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {

/// The node's reader side, run by its reader threads: converts each object's cloud,
/// transforms it by tf into the object's frame and checks it, makes new objects
/// (Scene::prepareObject), fits tracked ones to their clouds (TrackedFitter) and registers
/// registered ones (RegistrationFitter), then hands each to the cycle (CloudHandoff). A
/// cloud whose transform has not come waits, in arrival order, up to tf_wait_s of ROS time
/// (a bag's clock when it plays with --clock). Clouds of different objects are read on
/// different threads at once (the subscriptions' callbacks, never two of one object at once,
/// and the retry timer's): each object's state has a mutex, the ROS time watch one, the
/// counters are atomic, and the drop reports (either thread) have a mutex of their own.
class CloudReader {
 public:
  using Clock = std::chrono::steady_clock;

  /// Reads into `handoff`; `wake_cycle` wakes the cycle for a cloud that may start one. The
  /// references must outlive the reader; `scene` is only asked to prepare objects, which
  /// reads what its construction fixed.
  CloudReader(const NodeConfig& config, std::vector<ObjectSlot>& slots, const Scene& scene,
              CloudHandoff& handoff, const tf2_ros::Buffer& tf_buffer,
              std::function<void()> wake_cycle);

  /// A cloud of object `slot` arrived (the subscription's callback).
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud, std::size_t slot);
  /// Tries the clouds that wait for their transform, in order; drops those that waited
  /// too long, and all of them when ROS time went back (the retry timer's callback).
  void retryAwaitingClouds();
  /// The work per registered cloud and the distance to other objects' points within which
  /// cloud points are left out, from each registered object's next cloud on (a
  /// reconfiguration). Either thread; values already checked (>= 1, > 0).
  void setRegistrationTuning(int iterations, std::size_t max_cloud_points,
                             double contact_distance_m) {
    registration_iterations_ = iterations;
    registration_max_cloud_points_ = max_cloud_points;
    registration_contact_distance_m_ = contact_distance_m;
  }
  /// Counts a dropped cloud and says why, at most once per 5 s per object. Either thread.
  void dropCloud(ObjectSlot& slot, ros::console::levels::Level level, const std::string& problem);

  std::uint64_t cloudsReceived() const { return clouds_received_; }
  std::uint64_t cloudsRejected() const { return clouds_rejected_; }
  std::uint64_t nonFinitePoints() const { return non_finite_points_; }
  /// The time onCloud() and retryAwaitingClouds() took since construction, summed over the
  /// reader's threads: their load, which registrations make the largest part of.
  double busySeconds() const { return static_cast<double>(busy_ns_) * 1e-9; }

 private:
  struct AwaitingCloud {
    sensor_msgs::PointCloud2ConstPtr cloud;
    Clock::time_point arrival;
    ros::Time arrival_ros;           ///< What tf_wait_s is measured from.
    std::uint64_t jumps_before = 0;  ///< Jumps back of ROS time seen before it came.
  };
  /// ROS time as watchRosTime() read it, and the jumps back seen until then.
  struct RosTimeSeen {
    ros::Time now;
    std::uint64_t jumps = 0;
  };
  /// The reader's state of one object, touched only under its mutex: the clouds of
  /// different objects are read on different threads at once, one object's in order.
  struct ObjectReader {
    std::mutex mutex;
    ReadCloud cloud;  ///< The cloud being read; handed over by a swap.
    /// Clouds whose transform was not there yet, oldest first, retried in that order on
    /// the retry timer and on each new cloud, each until tf_wait_s after its arrival.
    std::deque<AwaitingCloud> awaiting_transform;
    /// on_cloud track, once the reader has made the object from its first cloud: the
    /// object's fitter, that cloud's size and the indices of its finite points (the
    /// object's points).
    std::optional<TrackedFitter> fitter;
    std::size_t tracked_cloud_size = 0;
    std::vector<std::uint32_t> tracked_indices;
    /// on_cloud register, once the object exists: its registration, taken from the slot,
    /// and the other objects' points near it, as the cycle last gave them.
    std::optional<RegistrationFitter> registration;
    std::vector<Eigen::Vector3d> near_points;
    /// The tuning `registration` was last given.
    int iterations = 0;
    std::size_t max_cloud_points = 0;
    double contact_distance_m = 0.0;
  };
  enum class CloudOutcome { kApplied, kRejected, kAwaitingTransform };
  enum class TransformOutcome { kDone, kRefused, kNotYet, kMissing };

  /// onCloud() but for counting the time it takes.
  /// Counts a cloud of `slot` that arrived at `arrival` and learns the clouds' rate.
  static void countArrival(ObjectSlot& slot, Clock::time_point arrival);
  void receiveCloud(const sensor_msgs::PointCloud2ConstPtr& cloud, std::size_t slot);
  /// Adds the time since `start` to busy_ns_.
  void countBusy(Clock::time_point start);
  /// Whether tf may still be learning its frames, so that an unknown frame may yet come.
  bool tfFilling() const;
  /// Whether, since ROS time went back, tf still holds the transforms of the time before
  /// between these frames; once it does not, false from then on.
  bool tfFromBeforeJump(const std::string& target_frame, const std::string& source_frame);
  bool tfFromBeforeJumpPossible() const;
  /// The frame a cloud of this object is placed in: its follow_frame or the fixed frame.
  const std::string& targetFrame(const ObjectSlot& slot) const;
  /// Why a cloud cannot ever be placed because tf knows no such frame; empty if it can be.
  std::string unknownFrameProblem(const ObjectSlot& slot, const std::string& frame) const;
  void retryAwaitingClouds(std::size_t slot, const ros::Time& now);
  /// Whether a tracked object's waiting cloud must wait for a followed frame at `stamp` too.
  bool followFramesBehind(std::size_t slot, const ros::Time& stamp) const;
  /// Reads and notes ROS time; if it went back (a looped bag), the waiting clouds, whose
  /// transforms belonged to the time before, are dropped. Call it holding no object's mutex.
  RosTimeSeen watchRosTime();
  /// Drops object `index`'s waiting clouds that came before the jumps back of ROS time
  /// counted in `jumps`.
  void dropCloudsFromBefore(std::size_t index, std::uint64_t jumps);
  /// False if the cloud waits for its transform.
  bool processCloud(std::size_t slot, const sensor_msgs::PointCloud2& cloud,
                    Clock::time_point arrival, bool last_try);
  /// `last_try`: a missing transform refuses the cloud instead of making it wait.
  CloudOutcome handleCloud(const sensor_msgs::PointCloud2& cloud, std::size_t slot,
                           Clock::time_point arrival, bool last_try);
  /// Whether the object waits for its model (model_file) to be placed: its cloud then waits
  /// too, or on the last try is dropped.
  std::optional<CloudOutcome> waitForModel(ObjectSlot& slot, bool exists, bool last_try);
  /// Reads, transforms and checks the cloud into `read`; the outcome if it is not taken.
  std::optional<CloudOutcome> readAndPlace(const sensor_msgs::PointCloud2& cloud, std::size_t slot,
                                           bool last_try, ReadCloud& read, CloudReadResult& result);
  /// Reads the cloud into `points`; its error also says why the object cannot take it
  /// (empty, or a tracked object's cloud of another size than `tracked_size`, its first's,
  /// or 0 before that).
  CloudReadResult readObjectCloud(const ObjectSlot& slot, const sensor_msgs::PointCloud2& cloud,
                                  std::size_t tracked_size,
                                  std::vector<Eigen::Vector3d>& points) const;
  /// Why a tracked object refuses a cloud of `points` points.
  static std::string trackedSizeProblem(std::size_t points, std::size_t first_points);
  /// Makes a new object (or a new rest shape) of the cloud, or fits a tracked object's.
  void prepare(std::size_t slot, bool exists, ReadCloud& read);
  /// A tracked object's first cloud, made into the object in `read.prepared`: the reader
  /// then fits the clouds after it.
  static void startTracking(ObjectReader& reader, ReadCloud& read);
  /// Fits a tracked object's cloud into `read.fit`, its fitted points into `read.points`,
  /// for the cycle to take over.
  static void fitTrackedCloud(ObjectReader& reader, ReadCloud& read);
  /// Registers a registered object's cloud into `read.registration`, its fit (unless held)
  /// into `read.fit` and `read.points`, for the cycle to take over.
  void registerCloud(ObjectSlot& slot, ObjectReader& reader, ReadCloud& read) const;
  /// kNotYet: the transform may still come; kMissing: it did not come in time; kRefused:
  /// it never will (no frame, an unknown frame once tf has filled, not finite).
  TransformOutcome transformPoints(const ObjectSlot& slot, const sensor_msgs::PointCloud2& cloud,
                                   bool last_try, ReadCloud& read, std::string& problem);
  /// Hands a read cloud to the cycle, waking it if the cloud may start one.
  void handOver(std::size_t slot, ReadCloud& read);

  const NodeConfig& config_;
  std::vector<ObjectSlot>& slots_;
  const Scene& scene_;
  CloudHandoff& handoff_;
  const tf2_ros::Buffer& tf_buffer_;
  const std::function<void()> wake_cycle_;
  const Clock::time_point started_;
  /// Guards the ROS time watch: latest_ros_, fill_started_ros_, jumps_, tf_from_before_jump_.
  /// Taken after an object's mutex, never before one.
  mutable std::mutex time_mutex_;
  ros::Time latest_ros_;              ///< The latest ROS time seen, to notice a jump back.
  ros::Time fill_started_ros_;        ///< The first ROS time seen, or the last jump back's.
  std::uint64_t jumps_ = 0;           ///< Jumps back of ROS time seen.
  bool tf_from_before_jump_ = false;  ///< See tfFromBeforeJump().
  std::vector<ObjectReader> readers_;
  std::mutex report_mutex_;
  std::atomic<std::uint64_t> clouds_received_{0};
  std::atomic<std::uint64_t> clouds_rejected_{0};
  std::atomic<std::uint64_t> non_finite_points_{0};
  std::atomic<std::uint64_t> busy_ns_{0};
  std::atomic<int> registration_iterations_;
  std::atomic<std::size_t> registration_max_cloud_points_;
  std::atomic<double> registration_contact_distance_m_;
};

}  // namespace deformable_collision
