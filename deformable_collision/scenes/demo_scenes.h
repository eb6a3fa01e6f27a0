#pragma once

#include <memory>
#include <optional>
#include <string>

#include "deformable_collision/core/common/enum_names.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// Built-in synthetic scenes, deterministic (fixed seeds), after the paper's section 7.
enum class DemoScene {
  kTwoObjects,    ///< S1: two soft balls thrown at each other, no gravity.
  kPile,          ///< S2: 300 (or more) soft objects falling into a box and onto each other.
  kThreeObjects,  ///< S3: a soft ball and a soft bar dropped on a floor.
  kGripper,       ///< A soft ball on a floor, squeezed by the two rigid jaws of a gripper.
};

inline constexpr EnumNames<DemoScene, 4> kDemoSceneNames{
    {{DemoScene::kTwoObjects, "two_objects"},
     {DemoScene::kPile, "pile"},
     {DemoScene::kThreeObjects, "three_objects"},
     {DemoScene::kGripper, "gripper"}}};

/// The scene named `name` (kDemoSceneNames); std::nullopt otherwise.
inline std::optional<DemoScene> parseDemoScene(const std::string& name) {
  return parseEnum(kDemoSceneNames, name);
}
inline const char* toString(DemoScene scene) { return enumName(kDemoSceneNames, scene); }

/// Points in the scene's soft objects when none are asked for: S1 16k, S2 131k, S3 19k in
/// all three objects, gripper 10k.
std::size_t defaultPointCount(DemoScene scene);

/// Builds `scene` with about `points` points in its soft objects (0: the default count),
/// on `config`. The scene sets gravity and, unless `config` asks for more, a contact
/// distance of about its point spacing at the default count: point clouds are porous to
/// each other at any shorter distance. `pile_objects`: the pile's soft objects (0: 300, S2);
/// more widen its box, and its default points grow with them.
/// @throw std::invalid_argument if points is too small for the scene's objects, or for
/// pile_objects other than 0 on another scene or over 10000.
std::unique_ptr<Scene> makeDemoScene(DemoScene scene, std::size_t points = 0,
                                     SceneConfig config = SceneConfig{},
                                     std::size_t pile_objects = 0);

/// Where kinematic object `object` of a built-in scene is at `time_s` (a pose of its rest
/// shape); std::nullopt if the scene has no such kinematic object.
std::optional<Eigen::Isometry3d> demoKinematicPose(DemoScene scene, const std::string& object,
                                                   double time_s);

/// Moves the kinematic objects of a built-in scene to where they are at `time_s` (the
/// gripper's jaws); nothing for the others.
void driveDemoScene(DemoScene scene, Scene& built, double time_s);

/// The mean speed of the dynamic objects' points, m/s (whether a scene has come to rest);
/// 0 if it has none.
double meanDynamicPointSpeed(const Scene& scene);

}  // namespace deformable_collision
