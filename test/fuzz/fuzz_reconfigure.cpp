// libFuzzer target: any sequence of reconfigurations, as the servers would pass them (each
// value clamped to the .cfg's range), checked and taken as the node takes them, between
// cycles of a small scene of every kind of object. A taken one must hold in the scene, a
// refused one leave it as it was, and no cycle may produce a non-finite point or contact.
// Every input starts from the same state.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>

#include "deformable_collision/ros/reconfigure_checks.h"
#include "deformable_collision/scenes/shapes.h"

namespace {

using namespace deformable_collision;

void check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_reconfigure: %s\n", what);
    std::abort();
  }
}

/// A double drawn anywhere, an edge or within [low, high].
double anyValue(FuzzedDataProvider& input, double low, double high) {
  switch (input.ConsumeIntegralInRange(0, 2)) {
    case 0:
      return input.ConsumeFloatingPointInRange(low, high);
    case 1:
      return input.PickValueInArray({std::numeric_limits<double>::quiet_NaN(), -1.0, 0.0, 1e-300,
                                     std::numeric_limits<double>::infinity(), high});
    default:
      return input.ConsumeFloatingPoint<double>();
  }
}

struct State {
  std::unique_ptr<Scene> scene;
  DeformableCollisionConfig node;
  std::vector<ObjectMaterialConfig> materials;
};

/// A small scene of every kind of object in touch: a static floor, a dynamic ball resting on
/// it, a tracked box pressed into it and a kinematic jaw against the ball.
std::unique_ptr<Scene> smallScene() {
  SceneConfig config;
  config.contact_distance_m = 0.02;
  auto scene = std::make_unique<Scene>(config);
  const auto object = [](const char* name, ObjectKind kind) {
    ObjectConfig o;
    o.name = name;
    o.kind = kind;
    o.shape.clusters = kind == ObjectKind::kDynamic ? 2 : 1;
    return o;
  };
  scene->addObject(object("floor", ObjectKind::kStatic), gridLayers(12, 2, 0.02));
  auto ball = sampleEllipsoid(150, {0.05, 0.05, 0.05}, 1);
  for (auto& p : ball) p.z() += 0.055;
  scene->addObject(object("ball", ObjectKind::kDynamic), ball);
  auto box = gridLayers(4, 4, 0.02);
  for (auto& p : box) p += Eigen::Vector3d(-0.08, 0.0, 0.05);
  scene->addObject(object("box", ObjectKind::kTracked), box);
  scene->addObject(object("jaw", ObjectKind::kKinematic), gridLayers(3, 3, 0.02));
  scene->setPose(3, Eigen::Isometry3d(Eigen::Translation3d(0.07, 0.0, 0.08)));
  return scene;
}

State freshState() {
  State s;
  s.scene = smallScene();
  s.node = DeformableCollisionConfig::__getDefault__();
  s.node.contact_distance_m = s.scene->config().contact_distance_m;
  s.node.friction = s.scene->config().friction;
  for (std::size_t i = 0; i < s.scene->objectCount(); ++i) {
    ObjectMaterialConfig material = ObjectMaterialConfig::__getDefault__();
    material.stiffness = s.scene->objectConfig(i).shape.stiffness;
    material.damping = s.scene->body(i).config().damping;
    material.contact_stiffness_n_per_m = s.scene->objectConfig(i).contact_stiffness_n_per_m;
    s.materials.push_back(material);
  }
  return s;
}

void reconfigureNode(FuzzedDataProvider& input, State& s) {
  DeformableCollisionConfig requested = s.node;
  requested.level = input.ConsumeIntegralInRange(-5, 300);
  requested.level_auto = input.ConsumeBool();
  requested.cycle_budget_ms = anyValue(input, 0.0, 10.0);
  // Kept within a few centimetres: a distance of metres makes every point pair a contact,
  // which is the user's to ask for but no fuzzer's to wait on.
  requested.contact_distance_m = anyValue(input, 1e-6, 0.05);
  requested.friction = anyValue(input, 0.0, 5.0);
  requested.__clamp__();
  if (!std::isfinite(requested.cycle_budget_ms) || !std::isfinite(requested.contact_distance_m) ||
      !std::isfinite(requested.friction) || requested.contact_distance_m > 0.05) {
    return;  // The server's clamp passes NaN on; rqt_reconfigure sends none.
  }
  const SceneConfig before = s.scene->config();
  if (nodeReconfigureProblem(requested, s.scene->maxLevel()).empty()) {
    applyToScene(*s.scene, requested, s.node);
    s.node = requested;
    check(s.scene->config().friction == requested.friction, "friction not taken");
    check(s.scene->config().contact_distance_m == requested.contact_distance_m,
          "contact distance not taken");
    check(requested.level_auto ||
              s.scene->level() == (requested.level < 0 ? s.scene->maxLevel() : requested.level),
          "level not taken");
  } else {
    check(s.scene->config().friction == before.friction &&
              s.scene->config().contact_distance_m == before.contact_distance_m,
          "a refused reconfiguration changed the scene");
  }
}

void reconfigureObject(FuzzedDataProvider& input, State& s) {
  const std::size_t index = input.ConsumeIntegralInRange<std::size_t>(0, s.materials.size() - 1);
  ObjectMaterialConfig requested = s.materials[index];
  requested.stiffness = anyValue(input, 0.0, 1.0);
  requested.damping = anyValue(input, 0.0, 1.0);
  requested.contact_stiffness_n_per_m = anyValue(input, 0.0, 1000.0);
  requested.__clamp__();
  if (!std::isfinite(requested.stiffness) || !std::isfinite(requested.damping) ||
      !std::isfinite(requested.contact_stiffness_n_per_m)) {
    return;
  }
  const ObjectKind kind = s.scene->objectConfig(index).kind;
  if (objectReconfigureProblem(requested, s.materials[index], kind).empty()) {
    applyMaterial(*s.scene, index, kind, requested);
    s.materials[index] = requested;
  }
}

void runCycle(State& s) {
  s.scene->cycle();
  for (std::size_t i = 0; i < s.scene->objectCount(); ++i) {
    for (const auto& p : s.scene->body(i).positions()) check(p.allFinite(), "a non-finite point");
  }
  for (const auto& c : s.scene->contacts()) {
    check(c.contact.position.allFinite() && std::isfinite(c.contact.depth_m),
          "a non-finite contact");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  // Made again for every input (a scene is not copied): each input is reproducible alone.
  State s = freshState();
  FuzzedDataProvider input(bytes, size);
  for (int op = 0; op < 16 && input.remaining_bytes() > 0; ++op) {
    switch (input.ConsumeIntegralInRange(0, 2)) {
      case 0:
        reconfigureNode(input, s);
        break;
      case 1:
        reconfigureObject(input, s);
        break;
      default:
        runCycle(s);
    }
  }
  return 0;
}
