// libFuzzer target: parseNodeConfig on the parameters a config file can put on the
// parameter server. Each input edits a valid configuration (sets, replaces or removes
// keys at every depth, with values of every type and edge), so the fuzzer works on the
// validation instead of on building dictionaries. A configuration the parser accepts must
// hold its documented ranges and be one the core accepts.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <ros/names.h>

#include "deformable_collision/ros/node_config.h"
#include "deformable_collision/scenes/shapes.h"

namespace {

using XmlRpc::XmlRpcValue;

// dt and gravity are the deprecated names of dt_s and gravity_mps2.
const char* const kTopKeys[] = {"fixed_frame", "rate_hz",      "max_points_per_object",
                                "dt_s",        "gravity_mps2", "dt",
                                "gravity",     "level",        "contact_distance_m",
                                "friction",    "tree",         "markers",
                                "objects",     "rate",         "robot"};
const char* const kObjectKeys[] = {"name",
                                   "topic",
                                   "follow_frame",
                                   "dynamic",
                                   "on_cloud",
                                   "mode",
                                   "clusters",
                                   "stiffness",
                                   "beta",
                                   "damping",
                                   "mass_kg",
                                   "preserve_volume",
                                   "cluster_overlap_ratio",
                                   "mass"};
const char* const kTreeKeys[] = {"leaf_size", "branching", "exact_radius_points", "depth"};
const char* const kRobotKeys[] = {"links", "description_param", "point_spacing_m", "link"};
const char* const kStrings[] = {"",          "a",        "ball",     "floor",   "x y",
                                "/abs",      "~private", "a/b",      "a//b",    "1abc",
                                "track",     "reset",    "ignore",   "rigid",   "linear",
                                "quadratic", "world",    "jaw_link", "\xc3\xa4"};

template <std::size_t N>
const char* pick(FuzzedDataProvider& input, const char* const (&keys)[N]) {
  return keys[input.ConsumeIntegralInRange<std::size_t>(0, N - 1)];
}

XmlRpcValue scalar(FuzzedDataProvider& input) {
  switch (input.ConsumeIntegralInRange(0, 4)) {
    case 0: {
      const int edges[] = {0,
                           1,
                           -1,
                           2,
                           4096,
                           4097,
                           std::numeric_limits<int>::max(),
                           std::numeric_limits<int>::min()};
      return input.ConsumeBool() ? XmlRpcValue(edges[input.ConsumeIntegralInRange(0, 7)])
                                 : XmlRpcValue(input.ConsumeIntegral<int>());
    }
    case 1: {
      const double edges[] = {0.0,
                              -0.0,
                              1.0,
                              1e-300,
                              1e300,
                              -1.0,
                              0.1,
                              0.10000000000000001,
                              std::numeric_limits<double>::quiet_NaN(),
                              std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity()};
      return input.ConsumeBool() ? XmlRpcValue(edges[input.ConsumeIntegralInRange(0, 10)])
                                 : XmlRpcValue(input.ConsumeFloatingPoint<double>());
    }
    case 2:
      return XmlRpcValue(input.ConsumeBool());
    case 3:
      return XmlRpcValue(std::string(pick(input, kStrings)));
    default:
      return XmlRpcValue(input.ConsumeRandomLengthString(24));
  }
}

XmlRpcValue anyValue(FuzzedDataProvider& input, int depth) {
  const int kind = input.ConsumeIntegralInRange(0, depth > 0 ? 6 : 4);
  if (kind == 5) {
    XmlRpcValue list;
    const int size = input.ConsumeIntegralInRange(0, 4);
    list.setSize(size);
    for (int i = 0; i < size; ++i) list[i] = anyValue(input, depth - 1);
    return list;
  }
  if (kind == 6) {
    XmlRpcValue dictionary;
    const int size = input.ConsumeIntegralInRange(0, 2);
    for (int i = 0; i < size; ++i)
      dictionary[pick(input, kObjectKeys)] = anyValue(input, depth - 1);
    return dictionary;
  }
  return scalar(input);
}

/// A copy of a dictionary without `key` (XmlRpcValue cannot erase a member).
XmlRpcValue without(XmlRpcValue& dictionary, const std::string& key) {
  XmlRpcValue kept;
  kept.begin();  // Makes `kept` an empty dictionary even if nothing is copied.
  for (auto& member : dictionary) {
    if (member.first != key) kept[member.first] = member.second;
  }
  return kept;
}

XmlRpcValue object(const std::string& name, const std::string& topic) {
  XmlRpcValue entry;
  entry["name"] = name;
  entry["topic"] = topic;
  entry["mode"] = std::string("quadratic");
  entry["clusters"] = 2;
  entry["stiffness"] = 0.5;
  return entry;
}

XmlRpcValue validConfiguration() {
  XmlRpcValue params;
  params["fixed_frame"] = std::string("world");
  params["rate_hz"] = 30.0;
  params["contact_distance_m"] = 0.01;
  XmlRpcValue gravity;
  gravity.setSize(3);
  gravity[0] = 0.0;
  gravity[1] = 0.0;
  gravity[2] = -9.81;
  params["gravity_mps2"] = gravity;
  params["objects"].setSize(2);
  params["objects"][0] = object("ball", "ball/points");
  params["objects"][1] = object("floor", "floor/points");
  params["objects"][1]["dynamic"] = false;
  return params;
}

/// Sets `key` of `dictionary` to a random value, or removes it.
void edit(FuzzedDataProvider& input, XmlRpcValue& dictionary, const char* key) {
  if (dictionary.getType() != XmlRpcValue::TypeStruct) dictionary = XmlRpcValue();
  if (input.ConsumeIntegralInRange(0, 5) == 0) {
    dictionary = without(dictionary, key);
  } else {
    dictionary[key] = anyValue(input, 2);
  }
}

void check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_node_config: %s\n", what);
    std::abort();
  }
}

void checkAccepted(const deformable_collision::NodeConfig& config) {
  using deformable_collision::Scene;
  check(!config.fixed_frame.empty() && config.fixed_frame[0] != '/', "fixed_frame");
  check(config.rate_hz > 0 && std::isfinite(config.rate_hz), "rate_hz");
  check(config.max_points_per_object >= 1, "max_points_per_object");
  check(config.scene.dt_s > 0 && config.scene.dt_s <= 0.1, "dt_s");
  check(config.scene.gravity_mps2.allFinite(), "gravity_mps2");
  check(config.scene.contact_distance_m > 0 && std::isfinite(config.scene.contact_distance_m),
        "contact_distance_m");
  check(!config.objects.empty(), "objects");
  check(!config.robot ||
            (config.robot->point_spacing_m > 0 && std::isfinite(config.robot->point_spacing_m)),
        "robot.point_spacing_m");
  for (const auto& params : config.objects) {
    std::string error;
    check(ros::names::validate(params.topic, error), "an invalid topic name was accepted");
    check(params.follow_frame.empty() || params.follow_frame[0] != '/', "follow_frame");
    check(params.robot_link.empty() ||
              (params.topic.empty() && params.follow_frame == params.robot_link &&
               params.object.kind == deformable_collision::ObjectKind::kKinematic),
          "a robot link is a kinematic object on its frame, without a topic");
    const auto& shape = params.object.shape;
    check(shape.stiffness >= 0 && shape.stiffness <= 1 && shape.beta >= 0 && shape.beta <= 1 &&
              shape.mass_kg > 0 && std::isfinite(shape.mass_kg),
          "shape matching ranges");
  }
  // The core must take what the parser accepts: the scene, and each object with a small
  // cloud (the node drops a cloud the core refuses, but a configuration should not make
  // every cloud fail).
  Scene scene(config.scene);
  const auto points = deformable_collision::sampleEllipsoid(64, Eigen::Vector3d(0.1, 0.1, 0.1), 1);
  for (std::size_t i = 0; i < config.objects.size() && i < 3; ++i) {
    try {
      scene.addObject(config.objects[i].object, points);
    } catch (const std::invalid_argument&) {
      // Refusing this cloud is the core's right (more clusters than points, say).
    }
  }
  scene.cycle();
  for (std::size_t i = 0; i < scene.objectCount(); ++i) {
    for (const auto& p : scene.body(i).positions()) check(p.allFinite(), "a point became NaN");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  FuzzedDataProvider input(bytes, size);
  XmlRpcValue params = validConfiguration();
  const int edits = input.ConsumeIntegralInRange(0, 6);
  for (int e = 0; e < edits; ++e) {
    switch (input.ConsumeIntegralInRange(0, 6)) {
      case 0:
        edit(input, params, pick(input, kTopKeys));
        break;
      case 1:
      case 2: {
        if (params["objects"].getType() != XmlRpcValue::TypeArray || params["objects"].size() == 0)
          break;
        const int i = input.ConsumeIntegralInRange(0, params["objects"].size() - 1);
        if (params["objects"][i].getType() != XmlRpcValue::TypeStruct) break;
        edit(input, params["objects"][i], pick(input, kObjectKeys));
        break;
      }
      case 3: {
        if (params["objects"].getType() != XmlRpcValue::TypeArray) break;
        const int i = params["objects"].size();
        params["objects"][i] = input.ConsumeBool()
                                   ? object(pick(input, kStrings), pick(input, kStrings))
                                   : anyValue(input, 2);
        break;
      }
      case 4:
        edit(input, params["tree"], pick(input, kTreeKeys));
        break;
      case 5:
        edit(input, params["robot"], pick(input, kRobotKeys));
        break;
      default:
        edit(input, params["markers"], input.ConsumeBool() ? "colliding_only" : "all");
        break;
    }
  }
  deformable_collision::NodeConfig config;
  std::vector<std::string> warnings;
  try {
    config = deformable_collision::parseNodeConfig(params, warnings);
  } catch (const std::invalid_argument& e) {
    check(std::string(e.what()).rfind("parameter ", 0) == 0, "an error that names no parameter");
    return 0;
  }
  const std::size_t deprecated_keys = params.hasMember("dt") + params.hasMember("gravity");
  check(warnings.size() == deprecated_keys, "not one warning per deprecated key");
  checkAccepted(config);
  return 0;
}
