#include "deformable_collision/ros/node_config.h"

#include <ros/names.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "deformable_collision/core/common/worker_pool.h"
#include "deformable_collision/ros/detail/param_reader.h"

namespace deformable_collision {
namespace {

using detail::ParamReader;
using detail::typeName;
using XmlRpc::XmlRpcValue;

/// Name, topic and follow_frame: what names the object to ROS, each checked as ROS and tf2
/// would take it.
void readObjectNames(ParamReader& read, ObjectParams& params) {
  std::string& name = params.object.name;
  name = read.requiredText("name");
  // The name becomes a topic (~deformed/<name>) and a marker namespace.
  const bool graph_name = std::isalpha(static_cast<unsigned char>(name[0])) &&
                          std::all_of(name.begin(), name.end(), [](char c) {
                            return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
                          });
  if (!graph_name) {
    ParamReader::fail(read.name("name"),
                      "= '" + name +
                          "' must start with a letter and hold only letters, "
                          "digits and '_' (it names the topic ~deformed/<name>)");
  }
  params.topic = read.requiredText("topic");
  std::string topic_problem;
  if (!ros::names::validate(params.topic, topic_problem)) {
    ParamReader::fail(read.name("topic"),
                      "= '" + params.topic + "' is not a valid topic name: " + topic_problem);
  }
  params.follow_frame = read.text("follow_frame", "");
  if (!params.follow_frame.empty() && params.follow_frame[0] == '/') {
    ParamReader::fail(read.name("follow_frame"),
                      "= '" + params.follow_frame + "' starts with '/', which tf2 refuses");
  }
}

/// The deformation mode as given, and whether it was given at all: a kinematic object is
/// rigid whatever the default, but refuses an explicit other mode.
struct ModeParam {
  std::string text;
  DeformationMode mode;
  bool given;
};

ModeParam readMode(ParamReader& read) {
  const bool given = read.find("mode") != nullptr;
  const std::string mode = read.text("mode", toString(DeformationMode::kLinear));
  const auto parsed = parseDeformationMode(mode);
  if (!parsed) {
    ParamReader::fail(read.name("mode"),
                      "= '" + mode + "' must be " + enumNameList(kDeformationModeNames));
  }
  return {mode, *parsed, given};
}

/// Whether the clouds of an object with this on_cloud move a tracked object.
bool followsClouds(OnCloud on_cloud) {
  return on_cloud == OnCloud::kTrack || on_cloud == OnCloud::kRegister;
}

/// The kind follows from `dynamic`, `follow_frame` and `on_cloud`; the combinations that
/// contradict each other are refused by the key that conflicts.
ObjectKind objectKind(const ParamReader& read, const ObjectParams& params, bool dynamic,
                      const ModeParam& mode) {
  const std::string on_cloud = std::string("= '") + toString(params.on_cloud) + "'";
  if (dynamic) {
    if (!params.follow_frame.empty()) {
      ParamReader::fail(read.name("follow_frame"),
                        "is set on a dynamic object; follow_frame moves a kinematic one "
                        "(dynamic: false)");
    }
    if (followsClouds(params.on_cloud)) {
      ParamReader::fail(read.name("on_cloud"),
                        on_cloud +
                            " needs dynamic: false (a tracked object follows its clouds, "
                            "a dynamic one is simulated)");
    }
    return ObjectKind::kDynamic;
  }
  if (!params.follow_frame.empty()) {
    if (followsClouds(params.on_cloud)) {
      ParamReader::fail(read.name("on_cloud"),
                        on_cloud + " conflicts with follow_frame (the frame moves the object)");
    }
    if (mode.given && mode.mode != DeformationMode::kRigid) {
      ParamReader::fail(read.name("mode"),
                        "= '" + mode.text + "' but an object that follows a frame is rigid");
    }
    return ObjectKind::kKinematic;
  }
  return followsClouds(params.on_cloud) ? ObjectKind::kTracked : ObjectKind::kStatic;
}

/// model_file and model_frame, read only by on_cloud register: a tracked object needs the
/// cloud's own points in the cloud's order, and the others take their shape from a cloud.
void readModel(ParamReader& read, ObjectParams& params) {
  params.model_file = read.text("model_file", "");
  params.model_frame = read.text("model_frame", "");
  if (!params.model_file.empty() && params.on_cloud != OnCloud::kRegister) {
    ParamReader::fail(read.name("model_file"),
                      std::string("is read only with on_cloud: register, not '") +
                          toString(params.on_cloud) + "' (whose rest shape is a cloud)");
  }
  if (!params.model_frame.empty() && params.model_file.empty()) {
    ParamReader::fail(read.name("model_frame"), "places model_file, which is not set");
  }
  if (!params.model_frame.empty() && params.model_frame[0] == '/') {
    ParamReader::fail(read.name("model_frame"),
                      "= '" + params.model_frame + "' starts with '/', which tf2 refuses");
  }
}

/// The node-wide `register` block: the work and the thresholds of every registration.
void readRegistration(const XmlRpcValue& block, RegistrationConfig& registration) {
  ParamReader read(block, "register");
  constexpr long kLargestCount = std::numeric_limits<int>::max();
  registration.iterations =
      static_cast<int>(read.integer("iterations", registration.iterations, 1, 1000));
  registration.max_correspondence_m =
      read.number("max_correspondence_m", registration.max_correspondence_m, 0.0, 1e3, true);
  registration.max_cloud_points = static_cast<std::size_t>(read.integer(
      "max_cloud_points", static_cast<long>(registration.max_cloud_points), 1, kLargestCount));
  registration.max_model_points = static_cast<std::size_t>(read.integer(
      "max_model_points", static_cast<long>(registration.max_model_points), 1, kLargestCount));
  registration.min_match_ratio =
      read.number("min_match_ratio", registration.min_match_ratio, 0.0, 1.0);
  registration.exclude_near_other_objects =
      read.flag("exclude_near_other_objects", registration.exclude_near_other_objects);
  read.finish();
}

void readDiagnostics(const XmlRpcValue& block, DiagnosticsParams& diagnostics) {
  ParamReader read(block, "diagnostics");
  diagnostics.period_s = read.number("period_s", diagnostics.period_s, 0.0, 3600.0, true);
  diagnostics.latency_warn_ms =
      read.number("latency_warn_ms", diagnostics.latency_warn_ms, 0.0, 1e7, true);
  diagnostics.latency_error_ms =
      read.number("latency_error_ms", diagnostics.latency_error_ms, 0.0, 1e7, true);
  if (diagnostics.latency_error_ms < diagnostics.latency_warn_ms) {
    ParamReader::fail(read.name("latency_error_ms"), "is below latency_warn_ms");
  }
  read.finish();
}

void readShapeMatching(ParamReader& read, ShapeMatchingConfig& shape) {
  shape.clusters = static_cast<int>(read.integer("clusters", shape.clusters, 1, 4096));
  shape.stiffness = read.number("stiffness", shape.stiffness, 0.0, 1.0);
  shape.beta = read.number("beta", shape.beta, 0.0, 1.0);
  shape.damping = read.number("damping", shape.damping, 0.0, 1.0);
  shape.mass_kg = read.number("mass_kg", shape.mass_kg, 0.0, 1e9, true);
  shape.preserve_volume = read.flag("preserve_volume", shape.preserve_volume);
  shape.cluster_overlap_ratio =
      read.number("cluster_overlap_ratio", shape.cluster_overlap_ratio, 0.0, 1.0);
}

/// A tracked object's force per metre of indentation: other kinds' forces come from the
/// simulation (dynamic) or from their partners.
void readContactStiffness(ParamReader& read, ObjectConfig& object) {
  object.contact_stiffness_n_per_m =
      read.number("contact_stiffness_n_per_m", object.contact_stiffness_n_per_m, 0.0, 1e9);
  if (object.contact_stiffness_n_per_m > 0.0 && object.kind != ObjectKind::kTracked) {
    ParamReader::fail(read.name("contact_stiffness_n_per_m"),
                      std::string("is read only by tracked objects (on_cloud track or "
                                  "register), not a ") +
                          toString(object.kind) + " one");
  }
}

/// Whether the object's contacts with itself are detected, and at what rest distance.
void readSelfCollision(ParamReader& read, ObjectConfig& object) {
  object.self_collision = read.flag("self_collision", false);
  object.self_rest_distance_m =
      read.number("self_rest_distance_m", object.self_rest_distance_m, 0.0, 1e3);
  if (object.self_collision &&
      (object.kind == ObjectKind::kStatic || object.kind == ObjectKind::kKinematic)) {
    ParamReader::fail(read.name("self_collision"),
                      std::string("needs a dynamic or tracked object, not a ") +
                          toString(object.kind) + " one, which never deforms");
  }
}

/// One entry of `objects`, read in the order of its checks, so that the first problem of an
/// entry is the one reported.
ObjectParams parseObject(const XmlRpcValue& entry, const std::string& path) {
  ParamReader read(entry, path);
  ObjectParams params;
  readObjectNames(read, params);
  const bool dynamic = read.flag("dynamic", true);

  const std::string on_cloud = read.text("on_cloud", toString(OnCloud::kIgnore));
  const auto parsed_on_cloud = parseOnCloud(on_cloud);
  if (!parsed_on_cloud) {
    ParamReader::fail(read.name("on_cloud"),
                      "= '" + on_cloud + "' must be " + enumNameList(kOnCloudNames));
  }
  params.on_cloud = *parsed_on_cloud;
  params.expected_rate_hz = read.number("expected_rate_hz", 0.0, 0.0, 1e4);
  const ModeParam mode = readMode(read);

  ObjectConfig& object = params.object;
  object.kind = objectKind(read, params, dynamic, mode);
  readModel(read, params);
  object.shape.mode = object.kind == ObjectKind::kKinematic ? DeformationMode::kRigid : mode.mode;
  readShapeMatching(read, object.shape);
  readContactStiffness(read, object);
  readSelfCollision(read, object);
  read.finish();
  return params;
}

/// The `objects` list: every entry, their names and topics each used once, and model_frame
/// defaulting to the fixed frame.
void readObjects(ParamReader& read, NodeConfig& config) {
  const XmlRpcValue* objects = read.find("objects");
  if (objects == nullptr) ParamReader::fail("objects", "is missing: list the objects to simulate");
  if (objects->getType() != XmlRpcValue::TypeArray || objects->size() == 0) {
    ParamReader::fail("objects", "must be a non-empty list of dictionaries");
  }
  std::set<std::string> names, topics;
  for (int i = 0; i < objects->size(); ++i) {
    const std::string path = "objects[" + std::to_string(i) + "]";
    ObjectParams object = parseObject((*objects)[i], path);
    if (!names.insert(object.object.name).second) {
      ParamReader::fail(path + ".name",
                        "= '" + object.object.name + "' is used by an earlier object");
    }
    if (!topics.insert(object.topic).second) {
      ParamReader::fail(path + ".topic", "= '" + object.topic + "' is used by an earlier object");
    }
    if (!object.model_file.empty() && object.model_frame.empty()) {
      object.model_frame = config.fixed_frame;
    }
    config.objects.push_back(std::move(object));
  }
}

/// Entry `index` of robot.links: a URDF link name, which is also its tf frame.
std::string readLinkName(const XmlRpcValue& links, int index) {
  const std::string key = "robot.links[" + std::to_string(index) + "]";
  const XmlRpcValue& entry = links[index];
  if (entry.getType() != XmlRpcValue::TypeString) {
    ParamReader::fail(key, std::string("must be a link name, got ") + typeName(entry.getType()));
  }
  const std::string link = static_cast<std::string>(entry);
  if (link.empty()) ParamReader::fail(key, "is empty");
  if (link[0] == '/') {
    ParamReader::fail(key, "= '" + link + "' starts with '/', which tf2 refuses as its frame");
  }
  return link;
}

/// A robot link as an object: rigid, kinematic, following the link's frame.
ObjectParams linkObject(const std::string& link) {
  ObjectParams params;
  params.robot_link = link;
  params.follow_frame = link;
  params.object.name = robotLinkObjectName(link);
  params.object.kind = ObjectKind::kKinematic;
  params.object.shape.mode = DeformationMode::kRigid;
  return params;
}

/// robot.links: each listed once, each object name (the link's, mapped) used once among all
/// objects.
void readLinks(ParamReader& read, NodeConfig& config) {
  const XmlRpcValue* links = read.find("links");
  if (links == nullptr) ParamReader::fail("robot.links", "is missing: list the links to take");
  if (links->getType() != XmlRpcValue::TypeArray || links->size() == 0) {
    ParamReader::fail("robot.links", "must be a non-empty list of link names");
  }
  std::set<std::string> names;
  for (const ObjectParams& object : config.objects) names.insert(object.object.name);
  std::set<std::string> listed;
  for (int i = 0; i < links->size(); ++i) {
    const std::string key = "robot.links[" + std::to_string(i) + "]";
    const std::string link = readLinkName(*links, i);
    if (!listed.insert(link).second) ParamReader::fail(key, "= '" + link + "' is listed twice");
    ObjectParams object = linkObject(link);
    if (!names.insert(object.object.name).second) {
      ParamReader::fail(key, "= '" + link + "' would be the object '" + object.object.name +
                                 "', a name another object has");
    }
    config.objects.push_back(std::move(object));
  }
}

/// The `robot` block, read after contact_distance_m (point_spacing_m's default) and objects.
void readRobot(const XmlRpcValue& block, NodeConfig& config) {
  ParamReader read(block, "robot");
  RobotParams robot;
  robot.description_param = read.text("description_param", robot.description_param);
  std::string problem;
  if (robot.description_param.empty()) ParamReader::fail("robot.description_param", "is empty");
  if (!ros::names::validate(robot.description_param, problem)) {
    ParamReader::fail("robot.description_param",
                      "= '" + robot.description_param + "' is not a parameter name: " + problem);
  }
  robot.point_spacing_m =
      read.number("point_spacing_m", config.scene.contact_distance_m, 0.0, 1e6, true);
  readLinks(read, config);
  read.finish();
  config.robot = robot;
}

/// cycle_on and cycle_on_all; cycle_on_all only where clouds start the cycles.
void readCycleOn(ParamReader& read, NodeConfig& config) {
  const std::string cycle_on = read.text("cycle_on", toString(config.cycle_on));
  const auto parsed = parseEnum(kCycleOnNames, cycle_on);
  if (!parsed) {
    ParamReader::fail("cycle_on", "= '" + cycle_on + "' must be " + enumNameList(kCycleOnNames));
  }
  config.cycle_on = *parsed;
  config.cycle_on_all = read.flag("cycle_on_all", config.cycle_on_all);
  if (config.cycle_on_all && config.cycle_on != CycleOn::kClouds) {
    ParamReader::fail("cycle_on_all", "is read only with cycle_on: clouds");
  }
}

/// dt_s: seconds per cycle, or `stamp` with cycle_on: clouds (the clouds' stamps time the
/// cycles); read after rate_hz and cycle_on.
void readStep(ParamReader& read, NodeConfig& config, std::vector<std::string>& warnings) {
  const std::string key = read.renamed("dt_s", "dt", warnings);
  const XmlRpcValue* value = read.find(key);
  if (value == nullptr || value->getType() != XmlRpcValue::TypeString) {
    config.scene.dt_s = read.number(key, config.scene.dt_s, 0.0, 0.1, true);
    return;
  }
  const std::string text = static_cast<std::string>(*value);
  if (text != "stamp") {
    ParamReader::fail(read.name(key), "= '" + text + "' must be a number in (0, 0.1] or 'stamp'");
  }
  if (config.cycle_on != CycleOn::kClouds) {
    ParamReader::fail(read.name(key),
                      "= 'stamp' needs cycle_on: clouds (the clouds' stamps time the cycles)");
  }
  config.dt_from_stamps = true;
  config.scene.dt_s = std::min(1.0 / config.rate_hz, 0.1);
}

/// level: an integer (-1: the finest), or `auto` with cycle_budget_ms, which is read only then.
void readLevel(ParamReader& read, SceneConfig& scene) {
  const XmlRpcValue* level = read.find("level");
  const bool budget_given = read.find("cycle_budget_ms") != nullptr;
  if (level == nullptr || level->getType() != XmlRpcValue::TypeString) {
    scene.level = static_cast<int>(read.integer("level", scene.level, -1, 255));
    if (budget_given) ParamReader::fail("cycle_budget_ms", "is read only with level: auto");
    return;
  }
  const std::string text = static_cast<std::string>(*level);
  if (text != "auto") {
    ParamReader::fail("level", "= '" + text + "' must be an integer in [-1, 255] or 'auto'");
  }
  if (!budget_given) {
    ParamReader::fail("level",
                      "= 'auto' needs cycle_budget_ms (> 0: ms of detection and "
                      "response per cycle)");
  }
  scene.cycle_budget_ms = read.number("cycle_budget_ms", 0.0, 0.0, 1e6, true);
}

/// An object named by distance_pairs[i].`key`: one of the objects (robot links included).
std::string readPairObject(ParamReader& read, const std::string& key, const NodeConfig& config) {
  const std::string name = read.requiredText(key);
  const bool known = std::any_of(config.objects.begin(), config.objects.end(),
                                 [&](const ObjectParams& o) { return o.object.name == name; });
  if (!known) ParamReader::fail(read.name(key), "= '" + name + "' is not an object");
  return name;
}

/// distance_pairs, read after objects and robot: pairs of distinct objects.
void readDistancePairs(const XmlRpcValue& list, NodeConfig& config) {
  if (list.getType() != XmlRpcValue::TypeArray) {
    ParamReader::fail("distance_pairs",
                      "must be a list of {object_a, object_b, max_distance_m, level}");
  }
  for (int i = 0; i < list.size(); ++i) {
    ParamReader read(list[i], "distance_pairs[" + std::to_string(i) + "]");
    DistancePairParams pair;
    pair.object_a = readPairObject(read, "object_a", config);
    pair.object_b = readPairObject(read, "object_b", config);
    if (pair.object_a == pair.object_b) {
      ParamReader::fail(read.name("object_b"), "= '" + pair.object_b + "' is object_a too");
    }
    pair.max_distance_m = read.number("max_distance_m", pair.max_distance_m, 0.0, 1e6);
    pair.level = static_cast<int>(read.integer("level", pair.level, -1, 255));
    read.finish();
    config.distance_pairs.push_back(pair);
  }
}

/// Clouds start cycles only if some object's clouds are read every time: a tracked or
/// registered one.
void checkCloudsStartCycles(const NodeConfig& config) {
  if (config.cycle_on != CycleOn::kClouds) return;
  const bool any = std::any_of(config.objects.begin(), config.objects.end(),
                               [](const ObjectParams& o) { return followsClouds(o.on_cloud); });
  if (!any) {
    ParamReader::fail("cycle_on",
                      "= 'clouds' needs an object with on_cloud: track or register, "
                      "whose clouds start the cycles");
  }
}

}  // namespace

std::string robotLinkObjectName(const std::string& link) {
  std::string name = link;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') c = '_';
  }
  if (name.empty() || !std::isalpha(static_cast<unsigned char>(name[0]))) name = "link_" + name;
  return name;
}

NodeConfig parseNodeConfig(const XmlRpc::XmlRpcValue& params, std::vector<std::string>& warnings) {
  ParamReader read(params, "");
  NodeConfig config;
  config.fixed_frame = read.text("fixed_frame", config.fixed_frame);
  if (config.fixed_frame.empty()) ParamReader::fail("fixed_frame", "is empty");
  if (config.fixed_frame[0] == '/') {
    ParamReader::fail("fixed_frame",
                      "= '" + config.fixed_frame + "' starts with '/', which tf2 refuses");
  }
  config.rate_hz = read.number("rate_hz", config.rate_hz, 0.0, 10000.0, true);
  readCycleOn(read, config);
  config.max_points_per_object = static_cast<std::size_t>(
      read.integer("max_points_per_object", static_cast<long>(config.max_points_per_object), 1,
                   std::numeric_limits<int>::max()));

  config.tf_wait_s = read.number("tf_wait_s", config.tf_wait_s, 0.0, 60.0);
  config.max_coordinate_m =
      read.number("max_coordinate_m", config.max_coordinate_m, 0.0, 1e12, true);
  SceneConfig& scene = config.scene;
  readStep(read, config, warnings);
  scene.gravity_mps2 =
      read.vector3(read.renamed("gravity_mps2", "gravity", warnings), scene.gravity_mps2);
  readLevel(read, scene);
  scene.contact_distance_m =
      read.number("contact_distance_m", scene.contact_distance_m, 0.0, 1e6, true);
  scene.friction = read.number("friction", scene.friction, 0.0, 1e3);
  scene.contact_forces = read.flag("contact_forces", scene.contact_forces);
  // The machine's cores, at most 8: the stages that share out gain little beyond that.
  const long cores = std::clamp<long>(std::thread::hardware_concurrency(), 1, 8);
  scene.threads = static_cast<int>(read.integer("threads", cores, 1, WorkerPool::kMaxThreads));
  if (const XmlRpcValue* tree = read.find("tree")) {
    ParamReader tree_read(*tree, "tree");
    scene.tree.leaf_size =
        static_cast<int>(tree_read.integer("leaf_size", scene.tree.leaf_size, 1, 1 << 20));
    scene.tree.branching =
        static_cast<int>(tree_read.integer("branching", scene.tree.branching, 2, 64));
    scene.tree.exact_radius_points = static_cast<int>(
        tree_read.integer("exact_radius_points", scene.tree.exact_radius_points, 0, 1 << 20));
    tree_read.finish();
  }
  if (const XmlRpcValue* registration = read.find("register")) {
    readRegistration(*registration, scene.registration);
  }
  if (const XmlRpcValue* markers = read.find("markers")) {
    ParamReader markers_read(*markers, "markers");
    config.markers_colliding_only =
        markers_read.flag("colliding_only", config.markers_colliding_only);
    config.force_marker_scale_m_per_n =
        markers_read.number("force_scale_m_per_n", config.force_marker_scale_m_per_n, 0.0, 1e3);
    markers_read.finish();
  }

  if (const XmlRpcValue* diagnostics = read.find("diagnostics")) {
    readDiagnostics(*diagnostics, config.diagnostics);
  }
  readObjects(read, config);
  if (const XmlRpcValue* robot = read.find("robot")) readRobot(*robot, config);
  // The reconfigure servers' own namespace (NodeReconfigure): what they set there is theirs,
  // and the loaded config, not it, is where a restarted node starts.
  read.find("reconfigure");
  if (const XmlRpcValue* pairs = read.find("distance_pairs")) readDistancePairs(*pairs, config);
  checkCloudsStartCycles(config);
  read.finish();
  return config;
}

}  // namespace deformable_collision
