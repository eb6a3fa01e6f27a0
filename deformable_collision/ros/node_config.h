#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/core/common/enum_names.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// What a later cloud of an object does once its first valid cloud has set the rest shape.
enum class OnCloud {
  kTrack,     ///< Observed positions of the same points (same count): registered each cloud.
  kRegister,  ///< An unordered, partial view (a depth camera's): the model is fitted to it.
  kReset,     ///< A new rest shape.
  kIgnore,    ///< Nothing.
};

inline constexpr EnumNames<OnCloud, 4> kOnCloudNames{{{OnCloud::kTrack, "track"},
                                                      {OnCloud::kRegister, "register"},
                                                      {OnCloud::kReset, "reset"},
                                                      {OnCloud::kIgnore, "ignore"}}};

/// The choice named `name` (kOnCloudNames); std::nullopt otherwise.
inline std::optional<OnCloud> parseOnCloud(const std::string& name) {
  return parseEnum(kOnCloudNames, name);
}
inline const char* toString(OnCloud on_cloud) { return enumName(kOnCloudNames, on_cloud); }

/// What starts a cycle: the timer at rate_hz, or a new cloud of a tracked or registered object
/// (at most at rate_hz).
enum class CycleOn { kTimer, kClouds };

inline constexpr EnumNames<CycleOn, 2> kCycleOnNames{
    {{CycleOn::kTimer, "timer"}, {CycleOn::kClouds, "clouds"}}};

inline const char* toString(CycleOn cycle_on) { return enumName(kCycleOnNames, cycle_on); }

/// One entry of the `objects` parameter.
struct ObjectParams {
  std::string topic;  ///< PointCloud2 input, resolved in the node's namespace.
  OnCloud on_cloud = OnCloud::kIgnore;
  std::string follow_frame;  ///< Kinematic objects: the tf frame they move with.
  /// on_cloud register: the rest shape's file (PLY or PCD, metres), empty for the first
  /// cloud's finite points; and the tf frame its coordinates are in (fixed_frame if unset).
  std::string model_file;
  std::string model_frame;
  /// A link of the `robot` block: its URDF name. Its collision geometry's surface, in its
  /// frame (follow_frame), is the rest shape; it has no topic.
  std::string robot_link;
  /// The rate its clouds are expected at, for /diagnostics; 0: learned from the clouds.
  double expected_rate_hz = 0.0;
  /// Name, kind and shape matching. The kind follows from `dynamic`, `follow_frame` and
  /// `on_cloud`: dynamic; kinematic (follows a frame); tracked (on_cloud track or
  /// register); or static.
  ObjectConfig object;
};

/// The `robot` block: links of the robot description, each a kinematic object after those of
/// `objects` (ObjectParams::robot_link).
struct RobotParams {
  /// The parameter holding the URDF, resolved in the node's namespace.
  std::string description_param = "robot_description";
  /// Every point of a link's surface lies within this of a sample: contact_distance_m unless
  /// set, so that whatever touches the surface has a sample within the contact distance.
  double point_spacing_m = 0.0;
};

/// The `diagnostics` block: how often /diagnostics is published (ROS time), and the 99th
/// percentile of the cloud-to-contacts latency above which the cycle's status warns and is
/// an error.
struct DiagnosticsParams {
  double period_s = 1.0;
  double latency_warn_ms = 100.0;
  double latency_error_ms = 1000.0;
};

/// One of `distance_pairs`: two objects whose closest points each cycle publishes on
/// ~distances, within max_distance_m, at `level` (-1: the finest, exact).
struct DistancePairParams {
  std::string object_a;
  std::string object_b;
  double max_distance_m = 1.0;
  int level = -1;
};

/// Every parameter of the node, in SI units, validated.
struct NodeConfig {
  std::string fixed_frame = "world";
  /// Cycles per second (kTimer), or at most that many (kClouds).
  double rate_hz = 100.0;
  CycleOn cycle_on = CycleOn::kTimer;
  /// kClouds: a cycle waits until every tracked or registered object has a cloud newer than
  /// the last cycle, instead of starting on the first one.
  bool cycle_on_all = false;
  /// `dt_s: stamp` (kClouds only): each cycle steps by the time between the stamps of the
  /// clouds that started it and the last cycle's, clamped to at most 0.1 s; the first cycle,
  /// and one whose stamps did not advance, step scene.dt_s (1 / rate_hz, at most 0.1 s).
  bool dt_from_stamps = false;
  std::size_t max_points_per_object = 1000000;
  /// How long a cloud waits for the transform of its stamp (a sensor's pose published late)
  /// before it is dropped with a warning. A cloud in a frame tf does not know at all is
  /// dropped at once, once the node has run max(tf_wait_s, 1 s) and tf has filled.
  double tf_wait_s = 0.5;
  /// Largest |x|, |y| or |z| of a point, in the frame the object is placed in (fixed_frame,
  /// or follow_frame for a kinematic object): a cloud with a point beyond it is dropped, as a
  /// coordinate that far is a sensor's garbage, not an object.
  double max_coordinate_m = 1e4;
  bool markers_colliding_only = false;
  /// ~contact_markers: metres of a force's segment per newton.
  double force_marker_scale_m_per_n = 0.01;
  DiagnosticsParams diagnostics;
  /// dt_s, gravity_mps2, level (or `auto` and cycle_budget_ms), contact_distance_m,
  /// friction, tree, register.
  SceneConfig scene;
  std::vector<ObjectParams> objects;
  std::optional<RobotParams> robot;
  std::vector<DistancePairParams> distance_pairs;
};

/// Fills a NodeConfig from the node's private parameters (a struct, as returned by
/// getParam on the private namespace), checking every value before anything is used.
/// Unknown keys are errors, so that a misspelt parameter is not silently replaced by its
/// default. A key given by its deprecated name (dt, gravity) is read with one line in
/// `warnings` naming the new key; both names at once are an error. The links of `robot` are
/// appended to `objects`, each named after its link (robotLinkObjectName()).
/// @throw std::invalid_argument whose message names the parameter and says what is wrong.
NodeConfig parseNodeConfig(const XmlRpc::XmlRpcValue& params, std::vector<std::string>& warnings);

/// The object name of a robot link: its name with every character other than a letter, a
/// digit or '_' replaced by '_', and "link_" before it unless it starts with a letter.
std::string robotLinkObjectName(const std::string& link);

}  // namespace deformable_collision
