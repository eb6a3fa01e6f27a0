#pragma once

#include <cstddef>
#include <string>

#include "deformable_collision/DeformableCollisionConfig.h"
#include "deformable_collision/ObjectMaterialConfig.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// What a reconfiguration does to the scene, apart from the servers (NodeReconfigure), so
/// that tests and the fuzzer can put any to it.

/// Why a reconfiguration of the node cannot be taken on a scene of `max_level`, or empty:
/// a fixed level beyond the deepest tree, or level_auto without a budget. The servers clamp
/// each value to the .cfg's range first.
std::string nodeReconfigureProblem(const DeformableCollisionConfig& requested, int max_level);

/// Why a reconfiguration of an object of `kind` cannot be taken, or empty: stiffness and
/// damping are a dynamic object's, contact stiffness a tracked one's; the others must keep
/// their values (`current`).
std::string objectReconfigureProblem(const ObjectMaterialConfig& requested,
                                     const ObjectMaterialConfig& current, ObjectKind kind);

/// Takes a checked reconfiguration into the scene: the level (only if it, level_auto or the
/// budget changed from `current`), the contact distance (if it changed) and the friction.
/// @throw std::invalid_argument or std::out_of_range for one that fails its check.
void applyToScene(Scene& scene, const DeformableCollisionConfig& requested,
                  const DeformableCollisionConfig& current);

/// Takes a checked material into object `index` of the scene, of `kind`: a dynamic one's
/// stiffness and damping, a tracked one's contact stiffness; nothing for the others.
void applyMaterial(Scene& scene, std::size_t index, ObjectKind kind,
                   const ObjectMaterialConfig& material);

}  // namespace deformable_collision
