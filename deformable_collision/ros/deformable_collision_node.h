#pragma once

#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/Stats.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/core/scene.h"
#include "deformable_collision/ros/contact_service.h"
#include "deformable_collision/ros/hierarchy_markers.h"
#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {

/// The ROS side of the package: reads the configuration, turns clouds into scene objects,
/// runs the scene's cycle on a timer and publishes what is subscribed. All callbacks run
/// on the node handles' queue, one at a time (the nodelet's single-threaded handles).
class DeformableCollisionNode {
 public:
  /// Loads and validates every parameter before subscribing to anything.
  /// @throw std::invalid_argument naming the bad parameter.
  DeformableCollisionNode(ros::NodeHandle node_handle, ros::NodeHandle private_handle);

 private:
  using Clock = std::chrono::steady_clock;

  struct AwaitingCloud {
    sensor_msgs::PointCloud2ConstPtr cloud;
    Clock::time_point arrival;
  };

  struct ObjectSlot {
    ObjectParams params;
    std::optional<std::size_t> index;  ///< In the scene, once a cloud set its rest shape.
    ros::Subscriber subscriber;
    ros::Publisher deformed;
    std::optional<Clock::time_point> pending_since;  ///< Oldest cloud not yet cycled.
    std::optional<Eigen::Isometry3d> last_pose;      ///< Kinematic objects.
    /// Tracked objects: the cloud indices of the object's points (the first cloud's finite
    /// ones) and that cloud's size, which every later cloud must have.
    std::vector<std::uint32_t> tracked_indices;
    std::size_t tracked_cloud_size = 0;
    /// Clouds whose transform was not there yet, oldest first, retried in that order each
    /// cycle and on each new cloud, each until tf_wait_s after its arrival.
    std::deque<AwaitingCloud> awaiting_transform;
    std::optional<Clock::time_point> last_report;  ///< Of a dropped cloud.
    std::size_t drops_unreported = 0;
    /// on_cloud register: model_file's points in model_frame until tf places them, the last
    /// cloud's registration, and the clouds held since start and since the last report.
    std::vector<Eigen::Vector3d> model_points;
    RegistrationReport registration;
    std::uint64_t clouds_held = 0;
    std::optional<Clock::time_point> last_held_report;
    std::size_t held_unreported = 0;
  };

  enum class CloudOutcome { kApplied, kRejected, kAwaitingTransform };
  enum class TransformOutcome { kDone, kRefused, kNotYet, kMissing };

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud, std::size_t slot);
  /// Whether tf may still be learning its frames, so that an unknown frame may yet come.
  bool tfFilling() const;
  /// The frame a cloud of this object is placed in: its follow_frame or the fixed frame.
  const std::string& targetFrame(const ObjectSlot& slot) const;
  /// Why a cloud cannot ever be placed because tf knows no such frame; empty if it can be.
  std::string unknownFrameProblem(const ObjectSlot& slot, const std::string& frame) const;
  /// Tries the clouds that wait for their transform, in order; drops those that waited
  /// too long.
  void retryAwaitingClouds();
  void retryAwaitingClouds(std::size_t slot, Clock::time_point now);
  /// False if the cloud waits for its transform.
  bool processCloud(std::size_t slot, const sensor_msgs::PointCloud2& cloud,
                    Clock::time_point arrival, bool last_try);
  /// Counts a dropped cloud and says why, at most once per 5 s per object.
  void dropCloud(ObjectSlot& slot, ros::console::levels::Level level, const std::string& problem);
  /// `last_try`: a missing transform refuses the cloud instead of making it wait.
  CloudOutcome handleCloud(const sensor_msgs::PointCloud2& cloud, std::size_t slot,
                           Clock::time_point arrival, bool last_try);
  /// Reads the cloud into cloud_points_; its error also says why the object cannot take it
  /// (empty, or a tracked object's cloud of another size).
  CloudReadResult readObjectCloud(const ObjectSlot& slot, const sensor_msgs::PointCloud2& cloud);
  /// tracked_points_: the points of cloud_points_ at `indices`, a tracked object's points.
  void selectTrackedPoints(const std::vector<std::uint32_t>& indices);
  void applyCloud(ObjectSlot& slot, std::vector<Eigen::Vector3d>& points, bool first);
  /// Points far apart compared with the contact distance let other clouds through: say so.
  void warnIfPorous(const std::string& name, const std::vector<Eigen::Vector3d>& points) const;
  /// kNotYet: the transform may still come; kMissing: it did not come in time; kRefused:
  /// it never will (no frame, an unknown frame once tf has filled, not finite).
  TransformOutcome transformPoints(const ObjectSlot& slot,
                                  const sensor_msgs::PointCloud2& cloud, bool last_try,
                                  std::vector<Eigen::Vector3d>& points, std::string& problem);
  /// Reads every model_file, so that a bad one stops the node at start, naming the object.
  /// @throw std::invalid_argument
  void loadModels();
  /// Creates the object of a slot from its model file at model_frame's latest pose, once tf
  /// has it; whether the object exists.
  bool placeModel(ObjectSlot& slot);
  void placeModels();
  /// A cloud of an object whose model waits for model_frame's pose waits with it, or on its
  /// last try is dropped; std::nullopt when the model is placed or there is none.
  std::optional<CloudOutcome> awaitModel(ObjectSlot& slot, bool last_try);
  /// Fits a registered object to a cloud in fixed_frame; keeps the report for ~stats.
  void registerCloud(ObjectSlot& slot, const std::vector<Eigen::Vector3d>& cloud_m);
  /// Says that a registration held the model, at most once per 5 s per object.
  void reportHeld(ObjectSlot& slot);
  void fillRegistrationStats(Stats& stats) const;
  void followFrames();
  void onTimer(const ros::TimerEvent& event);
  /// When the steps of one cycle ended, for ~stats.
  struct CycleTimes {
    Clock::time_point start;
    Clock::time_point cycled;
    Clock::time_point contacts_published;
    Clock::time_point published;
  };

  void runCycle();
  /// The arrival of the oldest cloud applied since the last cycle, which is now consumed.
  std::optional<Clock::time_point> takeOldestInput();
  /// Publishes the subscribed ~deformed/<object> clouds; returns the points of all objects.
  std::size_t publishDeformed(const std_msgs::Header& header);
  void publishStats(const std_msgs::Header& header, const CycleTimes& times,
                    std::optional<Clock::time_point> oldest_input, std::size_t points);
  bool onSetLevel(SetLevel::Request& request, SetLevel::Response& response);
  bool onGetContacts(GetContacts::Request& request, GetContacts::Response& response);

  ros::NodeHandle node_handle_;
  ros::NodeHandle private_handle_;
  NodeConfig config_;
  Clock::time_point started_;
  Scene scene_;
  std::vector<ObjectSlot> slots_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;

  ros::Publisher contacts_publisher_;
  ros::Publisher hierarchy_publisher_;
  ros::Publisher stats_publisher_;
  ros::ServiceServer set_level_service_;
  ros::ServiceServer get_contacts_service_;
  ros::Timer timer_;

  HierarchyMarkers markers_;
  std::vector<Eigen::Vector3d> cloud_points_;
  std::vector<Eigen::Vector3d> tracked_points_;
  /// The origin of the last cloud's frame in the target frame, the sensor's position, when
  /// the cloud came in a frame of its own (a camera's); unknown for a cloud in the target frame.
  std::optional<Eigen::Vector3d> cloud_viewpoint_;
  std::vector<SceneContact> query_contacts_;
  /// The services' view of slots_: names point into slots_[i].params, which never moves.
  std::vector<NamedObject> named_objects_;
  Stats stats_message_;
};

}  // namespace deformable_collision
