#pragma once

#include <cstddef>
#include <optional>
#include <string_view>
#include <vector>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/Distance.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/GetDistance.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/core/lod/level_costs.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// An object as the services know it: its configured name and, once a cloud gave it a
/// shape, its index in the scene.
struct NamedObject {
  std::string_view name;
  std::optional<std::size_t> scene_index;
};

/// The answers of `~set_level`, `~get_contacts` and `~get_distance`, apart from the node so that
/// tests and fuzzers can put any request to them. A bad request gets success = false and a message
/// that says what is wrong; it changes nothing.

/// SetLevel's level for "auto": the level of each cycle picked to fit the cycle budget.
constexpr int kAutoLevel = -3;

/// Sets the scene's running level to the requested one in [0, maxLevel()] or to FINEST
/// (-1, which stays the finest as deeper objects come), which leaves budget mode;
/// kAutoLevel (-3) enters budget mode with `cycle_budget_ms` (the node's, std::nullopt if
/// it has none: then the request fails); RUNNING (-2) only answers.
void answerSetLevel(Scene& scene, const SetLevel::Request& request, SetLevel::Response& response,
                    std::optional<double> cycle_budget_ms = std::nullopt);

/// Contacts of the named objects (empty name: any) on the current state, at the requested
/// level (FINEST, -1: the leaves; RUNNING, -2: the running one) or, with `budget_ms` > 0, at
/// the level `detection_costs` expect within it (LevelCosts::levelWithin; the message says
/// how it was taken); the running level is left alone. `detection_costs` are the scene's
/// (Scene::detectionCosts), or given ones in tests. `scratch` holds the contacts between
/// calls so that repeated queries reuse its memory. The caller sets the header.
void answerGetContacts(Scene& scene, const LevelCosts& detection_costs,
                       const std::vector<NamedObject>& objects, const GetContacts::Request& request,
                       std::vector<SceneContact>& scratch, GetContacts::Response& response);

/// The closest points of the two named objects (both required, distinct) on the current
/// state at the requested level (FINEST: exact; RUNNING: the running one), within
/// `max_distance_m` (Scene::closestPoints); found = false beyond it, or for an object that
/// has had no cloud yet. The running level is left alone. The caller sets the header.
void answerGetDistance(Scene& scene, const std::vector<NamedObject>& objects,
                       const GetDistance::Request& request, GetDistance::Response& response);

/// The closest points of two objects of the scene at a level in [0, maxLevel()] within
/// `max_distance_m` (Scene::closestPoints) as a message; found = false beyond it.
void fillDistance(Scene& scene, std::size_t object_a, std::size_t object_b, int level,
                  double max_distance_m, Distance& message);

/// Writes `contacts` (found at `level`) as a message, with the objects' names.
void fillContactArray(const Scene& scene, const std::vector<SceneContact>& contacts, int level,
                      ContactArray& message);

}  // namespace deformable_collision
