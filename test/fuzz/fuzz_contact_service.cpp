// libFuzzer target: the answers of ~set_level, ~get_contacts and ~get_distance to any
// sequence of requests, on the squeezed gripper scene (every kind of object, contacts at every
// level) plus a configured object that has had no cloud. Every input starts from the same state.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

#include "deformable_collision/ros/contact_service.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace {

using namespace deformable_collision;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Fixture {
  std::unique_ptr<Scene> scene;
  std::vector<NamedObject> objects;
  std::vector<SceneContact> scratch;
  int initial_level = 0;  ///< As configured: -1 is the finest.
};

Fixture& fixture() {
  static Fixture built = [] {
    Fixture f;
    f.scene = makeDemoScene(DemoScene::kGripper, 2000);
    for (int step = 0; step < 150; ++step) {
      driveDemoScene(DemoScene::kGripper, *f.scene, step * f.scene->config().dt_s);
      f.scene->cycle();
    }
    for (std::size_t i = 0; i < f.scene->objectCount(); ++i) {
      f.objects.push_back({f.scene->objectConfig(i).name, i});
    }
    f.objects.push_back({"late", std::nullopt});
    f.initial_level = f.scene->config().level;
    return f;
  }();
  return built;
}

void check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_contact_service: %s\n", what);
    std::abort();
  }
}

std::string objectName(FuzzedDataProvider& input, const Fixture& f) {
  switch (input.ConsumeIntegralInRange(0, 3)) {
    case 0:
      return "";
    case 1:
      return input.ConsumeRandomLengthString(16);
    default:
      return std::string(
          f.objects[input.ConsumeIntegralInRange<std::size_t>(0, f.objects.size() - 1)].name);
  }
}

bool known(const Fixture& f, const std::string& name) {
  if (name.empty()) return true;
  for (const NamedObject& object : f.objects) {
    if (object.name == name) return true;
  }
  return false;
}

std::int16_t requestedLevel(FuzzedDataProvider& input) {
  return input.ConsumeBool() ? input.ConsumeIntegralInRange<std::int16_t>(-3, 20)
                             : input.ConsumeIntegral<std::int16_t>();
}

/// No budget (0) half the time; else one in [0, 10] ms, an edge or any double.
double requestedBudget(FuzzedDataProvider& input) {
  if (!input.ConsumeBool()) return 0.0;
  switch (input.ConsumeIntegralInRange(0, 2)) {
    case 0:
      return input.ConsumeFloatingPointInRange(0.0, 10.0);
    case 1:
      return input.PickValueInArray({kNaN, kInf, -kInf, -0.0, -1.0, 1e-300});
    default:
      return input.ConsumeFloatingPoint<double>();
  }
}

/// The level a request names on `scene` (FINEST, RUNNING or itself); -3 if out of range.
int namedLevel(const Scene& scene, int requested) {
  if (requested == GetContacts::Request::RUNNING) return scene.level();
  if (requested == GetContacts::Request::FINEST) return scene.maxLevel();
  return requested >= 0 && requested <= scene.maxLevel() ? requested : -3;
}

void setLevel(FuzzedDataProvider& input, Fixture& f) {
  SetLevel::Request request;
  request.level = requestedLevel(input);
  const int before = f.scene->level();
  const int expected = namedLevel(*f.scene, request.level);
  SetLevel::Response response;
  answerSetLevel(*f.scene, request, response);
  check(response.success == (expected >= 0), "set_level accepted wrongly");
  check(f.scene->level() == (response.success ? expected : before), "wrong level in force");
  check(request.level != SetLevel::Request::FINEST || f.scene->config().level == -1,
        "set_level FINEST did not keep to the finest");
  check(response.level == f.scene->level() && response.max_level == f.scene->maxLevel(),
        "set_level reports a level not in force");
  check(!response.message.empty(), "set_level said nothing");
}

/// Returns the request, for getDistance().
GetContacts::Request getContacts(FuzzedDataProvider& input, Fixture& f) {
  GetContacts::Request request;
  request.object_a = objectName(input, f);
  request.object_b = objectName(input, f);
  request.level = requestedLevel(input);
  // Drawn after the level: the kept regression input ends before it, and an exhausted input
  // draws 0 (no budget), so it still asks what it asked before budget_ms came.
  request.budget_ms = requestedBudget(input);
  const bool budget_valid = request.budget_ms >= 0.0 && std::isfinite(request.budget_ms);
  const int running = f.scene->level();
  const int level =
      budget_valid && request.budget_ms > 0.0
          ? f.scene->detectionCosts().levelWithin(request.budget_ms, f.scene->maxLevel()).level
          : namedLevel(*f.scene, request.level);
  GetContacts::Response response;
  answerGetContacts(*f.scene, f.scene->detectionCosts(), f.objects, request, f.scratch, response);
  const bool valid =
      known(f, request.object_a) && known(f, request.object_b) && budget_valid && level >= 0;
  check(response.success == valid, "get_contacts accepted wrongly");
  check(f.scene->level() == running, "get_contacts changed the running level");
  check(!response.message.empty(), "get_contacts said nothing");
  if (!response.success) {
    check(response.contacts.contacts.empty(), "a refused query returned contacts");
    return request;
  }
  check(response.level == level && response.contacts.level == level, "contacts of another level");
  for (const Contact& contact : response.contacts.contacts) {
    check(request.object_a.empty() || contact.object_a == request.object_a ||
              contact.object_b == request.object_a,
          "a contact without object_a");
    check(request.object_b.empty() || contact.object_a == request.object_b ||
              contact.object_b == request.object_b,
          "a contact without object_b");
    check(contact.level <= level, "a contact below the level asked for");
    const double length =
        std::sqrt(contact.normal.x * contact.normal.x + contact.normal.y * contact.normal.y +
                  contact.normal.z * contact.normal.z);
    check(std::abs(length - 1.0) < 1e-9, "a normal that is not unit length");
    check(std::isfinite(contact.depth) && std::isfinite(contact.position.x) &&
              std::isfinite(contact.position.y) && std::isfinite(contact.position.z),
          "a non-finite contact");
    check(std::isfinite(contact.error_bound_m) && contact.error_bound_m >= 0.0,
          "an error bound that is not finite and >= 0");
  }
  return request;
}

/// ~get_distance between the objects and at the level a contact request named, within a
/// drawn maximum: drawn last, so that inputs kept from before it still ask what they asked.
void getDistance(FuzzedDataProvider& input, Fixture& f, const GetContacts::Request& contacts) {
  GetDistance::Request request;
  request.object_a = contacts.object_a;
  request.object_b = contacts.object_b;
  request.level = contacts.level;
  request.max_distance_m = requestedBudget(input);
  const int running = f.scene->level();
  const int level = namedLevel(*f.scene, request.level);
  GetDistance::Response response;
  answerGetDistance(*f.scene, f.objects, request, response);
  const bool valid = !request.object_a.empty() && !request.object_b.empty() &&
                     request.object_a != request.object_b && known(f, request.object_a) &&
                     known(f, request.object_b) && request.max_distance_m >= 0.0 &&
                     std::isfinite(request.max_distance_m) && level >= 0;
  check(response.success == valid, "get_distance accepted wrongly");
  check(f.scene->level() == running, "get_distance changed the running level");
  check(!response.message.empty(), "get_distance said nothing");
  if (!response.distance.found) return;
  check(response.success && response.distance.level == level, "a distance of another level");
  check(std::isfinite(response.distance.distance_m) && response.distance.distance_m >= 0.0 &&
            response.distance.distance_m <= request.max_distance_m,
        "a distance that is not finite, >= 0 and within the maximum");
  check(std::isfinite(response.distance.error_bound_m) && response.distance.error_bound_m >= 0.0,
        "a distance's error bound that is not finite and >= 0");
  const double length = std::sqrt(response.distance.normal.x * response.distance.normal.x +
                                  response.distance.normal.y * response.distance.normal.y +
                                  response.distance.normal.z * response.distance.normal.z);
  check(std::abs(length - 1.0) < 1e-9, "a distance normal that is not unit length");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  Fixture& f = fixture();
  f.scene->setLevel(f.initial_level);
  FuzzedDataProvider input(bytes, size);
  while (input.remaining_bytes() > 0) {
    if (input.ConsumeBool()) {
      setLevel(input, f);
    } else {
      getDistance(input, f, getContacts(input, f));
    }
  }
  return 0;
}
