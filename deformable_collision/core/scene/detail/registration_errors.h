// Internal to the core: each contact's registration_error_m, from its objects' registrations.
#pragma once

#include <memory>
#include <vector>

#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace detail {

struct SceneObject;

/// Sets registration_error_m of `contacts` (each pair's together, as a Scene lists them):
/// per pair, the larger of its two objects' SurfaceError on the side of each camera that the
/// pair faces. Touches nothing when no object was ever registered: their contacts were made
/// with 0. Allocation-free.
void assignRegistrationErrors(const std::vector<std::unique_ptr<SceneObject>>& objects,
                              std::vector<SceneContact>& contacts);

}  // namespace detail
}  // namespace deformable_collision
