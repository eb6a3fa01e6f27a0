#include "deformable_collision/ros/contact_service.h"

#include <cmath>
#include <sstream>
#include <string>

#include "deformable_collision/ros/message_vectors.h"

namespace deformable_collision {
namespace {

/// Finds a named object; the empty name is "any" (std::nullopt, with a shape).
/// False, with `problem` said, if no object has that name.
bool resolveObject(const std::vector<NamedObject>& objects, const std::string& name,
                   std::optional<std::size_t>& index, bool& has_shape, std::string& problem) {
  index.reset();
  has_shape = true;
  if (name.empty()) return true;
  for (const NamedObject& object : objects) {
    if (object.name != name) continue;
    index = object.scene_index;
    has_shape = object.scene_index.has_value();
    return true;
  }
  std::ostringstream known;
  for (std::size_t i = 0; i < objects.size(); ++i) known << (i ? ", " : "") << objects[i].name;
  problem = "unknown object '" + name + "'; the objects are: " + known.str();
  return false;
}

static_assert(int{SetLevel::Request::FINEST} == int{GetContacts::Request::FINEST} &&
                  int{SetLevel::Request::RUNNING} == int{GetContacts::Request::RUNNING} &&
                  int{GetDistance::Request::FINEST} == int{GetContacts::Request::FINEST} &&
                  int{GetDistance::Request::RUNNING} == int{GetContacts::Request::RUNNING},
              "the services name levels alike");

/// A level a request may name apart from RUNNING: FINEST or one in [0, max_level].
bool isRequestableLevel(int level, int max_level) {
  return level == GetContacts::Request::FINEST || (level >= 0 && level <= max_level);
}

std::string levelOutOfRange(int level, int max_level) {
  return "level " + std::to_string(level) + " is outside [0, " + std::to_string(max_level) + "] (" +
         std::to_string(max_level) + ": the leaves; -1: the finest; -2: the running one)";
}

/// What the level taken for a budget means, after "N contacts at level L".
std::string budgetNote(const LevelCosts::LevelForBudget& pick, double budget_ms) {
  std::ostringstream note;
  switch (pick.basis) {
    case LevelCosts::Basis::kWithinBudget:
      note << ", the finest expected within " << budget_ms << " ms of detection ("
           << *pick.estimate_ms << " ms)";
      break;
    case LevelCosts::Basis::kCheapest:
      note << ": no level is expected within " << budget_ms
           << " ms of detection; this one is the cheapest measured (" << *pick.estimate_ms
           << " ms)";
      break;
    case LevelCosts::Basis::kNoneMeasured:
      note << ": no level's detection has been measured yet (no cycle has run), so the "
              "coarsest";
      break;
  }
  return note.str();
}

}  // namespace

void answerSetLevel(Scene& scene, const SetLevel::Request& request, SetLevel::Response& response,
                    std::optional<double> cycle_budget_ms) {
  response.success = false;
  // Without a budget in the config, -3 is out of range like any other level.
  const bool to_auto = request.level == kAutoLevel && cycle_budget_ms;
  if (scene.objectCount() == 0) {
    response.message =
        "no object has a rest shape yet, so there are no levels: publish clouds first";
  } else if (!to_auto && request.level != SetLevel::Request::RUNNING &&
             !isRequestableLevel(request.level, scene.maxLevel())) {
    response.message = levelOutOfRange(request.level, scene.maxLevel()) +
                       (cycle_budget_ms ? "; -3: auto"
                                        : "; -3 (auto) needs level: auto and cycle_budget_ms in "
                                          "the config");
  } else {
    if (to_auto) {
      scene.setCycleBudget(cycle_budget_ms);
    } else if (request.level != SetLevel::Request::RUNNING) {
      scene.setLevel(request.level);
    }
    response.success = true;
    response.message = "level " + std::to_string(scene.level()) + " of [0, " +
                       std::to_string(scene.maxLevel()) + "]";
    if (const std::optional<double> budget = scene.cycleBudget()) {
      std::ostringstream fit;
      fit << ", picked each cycle to fit " << *budget << " ms";
      response.message += fit.str();
    }
  }
  response.max_level = static_cast<std::uint8_t>(scene.maxLevel());
  response.level = static_cast<std::uint8_t>(scene.level());
}

void answerGetContacts(Scene& scene, const LevelCosts& detection_costs,
                       const std::vector<NamedObject>& objects, const GetContacts::Request& request,
                       std::vector<SceneContact>& scratch, GetContacts::Response& response) {
  response.success = false;
  response.contacts.contacts.clear();
  std::optional<std::size_t> a, b;
  bool a_has_shape = true, b_has_shape = true;
  if (!resolveObject(objects, request.object_a, a, a_has_shape, response.message) ||
      !resolveObject(objects, request.object_b, b, b_has_shape, response.message)) {
    return;
  }
  if (!(request.budget_ms >= 0.0) || !std::isfinite(request.budget_ms)) {
    std::ostringstream problem;
    problem << "budget_ms = " << request.budget_ms
            << " must be finite and >= 0 (0: no budget, the level asked for)";
    response.message = problem.str();
    return;
  }
  const int max_level = scene.maxLevel();
  int level = request.level;
  std::string budget_note;
  if (request.budget_ms > 0.0) {
    const LevelCosts::LevelForBudget pick =
        detection_costs.levelWithin(request.budget_ms, max_level);
    level = pick.level;
    budget_note = budgetNote(pick, request.budget_ms);
  } else if (level == GetContacts::Request::RUNNING) {
    level = scene.level();
  } else if (level == GetContacts::Request::FINEST) {
    level = max_level;
  } else if (!isRequestableLevel(level, max_level)) {
    response.message = levelOutOfRange(level, max_level);
    return;
  }
  response.success = true;
  response.level = static_cast<std::uint8_t>(level);
  response.contacts.level = static_cast<std::uint8_t>(level);
  if (!a_has_shape || !b_has_shape) {
    response.message = "object '" + (a_has_shape ? request.object_b : request.object_a) +
                       "' has had no valid cloud yet: no contacts";
    return;
  }
  scene.contactsAt(level, a, b, scratch);
  fillContactArray(scene, scratch, level, response.contacts);
  response.message =
      std::to_string(scratch.size()) + " contacts at level " + std::to_string(level) + budget_note;
}

namespace {

/// The two objects of a distance request, both named and distinct; false, with the
/// problem said, otherwise.
bool resolveDistancePair(const std::vector<NamedObject>& objects,
                         const GetDistance::Request& request, std::optional<std::size_t>& a,
                         std::optional<std::size_t>& b, std::string& problem) {
  if (request.object_a.empty() || request.object_b.empty()) {
    problem = "object_a and object_b must both be named";
    return false;
  }
  if (request.object_a == request.object_b) {
    problem = "object_a and object_b are both '" + request.object_a + "'";
    return false;
  }
  bool a_has_shape = true, b_has_shape = true;
  return resolveObject(objects, request.object_a, a, a_has_shape, problem) &&
         resolveObject(objects, request.object_b, b, b_has_shape, problem);
}

/// The request's level: RUNNING and FINEST resolved; std::nullopt, with the problem said,
/// outside [0, max_level].
std::optional<int> resolveDistanceLevel(const Scene& scene, int level, std::string& problem) {
  const int max_level = scene.maxLevel();
  if (level == GetDistance::Request::RUNNING) return scene.level();
  if (level == GetDistance::Request::FINEST) return max_level;
  if (isRequestableLevel(level, max_level)) return level;
  problem = levelOutOfRange(level, max_level);
  return std::nullopt;
}

}  // namespace

void answerGetDistance(Scene& scene, const std::vector<NamedObject>& objects,
                       const GetDistance::Request& request, GetDistance::Response& response) {
  response = GetDistance::Response();
  std::optional<std::size_t> a, b;
  if (!resolveDistancePair(objects, request, a, b, response.message)) return;
  if (!(request.max_distance_m >= 0.0) || !std::isfinite(request.max_distance_m)) {
    std::ostringstream problem;
    problem << "max_distance_m = " << request.max_distance_m << " must be finite and >= 0";
    response.message = problem.str();
    return;
  }
  const std::optional<int> level = resolveDistanceLevel(scene, request.level, response.message);
  if (!level) return;
  response.success = true;
  if (!a || !b) {
    response.distance.object_a = request.object_a;
    response.distance.object_b = request.object_b;
    response.distance.level = static_cast<std::uint8_t>(*level);
    response.message = "object '" + (a ? request.object_b : request.object_a) +
                       "' has had no valid cloud yet: no distance";
    return;
  }
  fillDistance(scene, *a, *b, *level, request.max_distance_m, response.distance);
  std::ostringstream message;
  if (response.distance.found) {
    message << response.distance.distance_m << " m at level " << *level
            << (response.distance.error_bound_m == 0.0 ? " (exact)" : " (a lower bound)");
  } else {
    message << "farther apart than " << request.max_distance_m << " m at level " << *level;
  }
  response.message = message.str();
}

void fillDistance(Scene& scene, std::size_t object_a, std::size_t object_b, int level,
                  double max_distance_m, Distance& message) {
  message.object_a = scene.objectConfig(object_a).name;
  message.object_b = scene.objectConfig(object_b).name;
  message.level = static_cast<std::uint8_t>(level);
  const std::optional<ClosestPoints> closest =
      scene.closestPoints(object_a, object_b, level, max_distance_m);
  message.found = closest.has_value();
  // A message filled again (~distances) keeps nothing of the last pair found.
  const ClosestPoints found = closest.value_or(ClosestPoints{});
  message.distance_m = found.distance_m;
  message.error_bound_m = found.error_bound_m;
  message.point_a = toPointMessage(found.point_a);
  message.point_b = toPointMessage(found.point_b);
  message.normal = toVectorMessage(found.normal);
}

void fillContactArray(const Scene& scene, const std::vector<SceneContact>& contacts, int level,
                      ContactArray& message) {
  message.level = static_cast<std::uint8_t>(level);
  message.contacts.resize(contacts.size());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    const SceneContact& from = contacts[k];
    Contact& to = message.contacts[k];
    to.object_a = scene.objectConfig(from.object_a).name;
    to.object_b = scene.objectConfig(from.object_b).name;
    to.sphere_a = from.contact.node_a;
    to.sphere_b = from.contact.node_b;
    to.level = static_cast<std::uint8_t>(from.contact.level);
    to.position = toPointMessage(from.contact.position);
    to.normal = toVectorMessage(from.contact.normal);
    to.depth = from.contact.depth_m;
    to.error_bound_m = from.contact.error_bound_m;
    to.force_n = toVectorMessage(from.force_n);
    to.force_error_n = from.force_error_n;
    to.registration_error_m = from.registration_error_m;
  }
}

}  // namespace deformable_collision
