// The core on a built-in scene: objects, points, level of detail, time per stage and
// contacts, over a fixed simulated time, and a hash of the trajectory.
// Usage: core_demo [scene=three_objects] [cycles=300] [level=-1 (finest)] [points=0 (the
//        scene's default)] [contact_distance_m=0 (the scene's default, the least allowed)]
//        [threads=1 (SceneConfig::threads: the hashes are the same on any count)]
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "deformable_collision/scenes/byte_digest.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace dc = deformable_collision;

namespace {

using TrajectoryHash = dc::ByteDigest;

void addContacts(const std::vector<dc::SceneContact>& contacts, TrajectoryHash& hash) {
  for (const auto& c : contacts) {
    hash.add(c.object_a);
    hash.add(c.object_b);
    hash.add(c.contact.node_a);
    hash.add(c.contact.node_b);
    hash.add(c.contact.depth_m);
    hash.add(c.contact.position.x());
    hash.add(c.contact.position.y());
    hash.add(c.contact.position.z());
  }
}

/// The objects (the first 8), their points and the level of detail.
void printScene(const std::string& name, int cycles, const dc::Scene& scene) {
  std::size_t points = 0;
  std::printf("deformable_collision demo: scene %s, %d cycles of %.3f s\n", name.c_str(), cycles,
              scene.config().dt_s);
  std::printf("%-14s %-10s %-10s %8s %8s\n", "object", "kind", "mode", "points", "clusters");
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    const auto& object = scene.objectConfig(o);
    points += scene.body(o).pointCount();
    if (o < 8) {
      std::printf("%-14s %-10s %-10s %8zu %8zu\n", object.name.c_str(), dc::toString(object.kind),
                  dc::toString(scene.body(o).config().mode), scene.body(o).pointCount(),
                  scene.body(o).clusterCount());
    }
  }
  if (scene.objectCount() > 8) std::printf("... %zu objects in all\n", scene.objectCount());
  std::printf("points %zu, level %d of %d, contact distance %.3f m\n\n", points, scene.level(),
              scene.maxLevel(), scene.config().contact_distance_m);
}

/// Runs the scene, printing about six cycles and the means; returns the hash of every
/// cycle's contacts.
std::uint64_t runCycles(dc::DemoScene kind, int cycles, dc::Scene& scene) {
  double shape_matching = 0.0, detection = 0.0, response = 0.0;
  std::size_t contacts = 0;
  TrajectoryHash contact_hash;
  std::printf("%8s %10s %10s %10s %9s %12s\n", "cycle", "shape ms", "detect ms", "respond ms",
              "contacts", "spheres");
  for (int cycle = 0; cycle < cycles; ++cycle) {
    dc::driveDemoScene(kind, scene, cycle * scene.config().dt_s);
    scene.cycle();
    const auto& s = scene.stats();
    shape_matching += s.shape_matching_ms;
    detection += s.detection_ms;
    response += s.response_ms;
    contacts += s.contacts;
    addContacts(scene.contacts(), contact_hash);
    if (cycle % (cycles / 6 > 0 ? cycles / 6 : 1) == 0 || cycle == cycles - 1) {
      std::printf("%8d %10.3f %10.3f %10.3f %9zu %12zu\n", cycle, s.shape_matching_ms,
                  s.detection_ms, s.response_ms, s.contacts, s.spheres_updated);
    }
  }
  std::printf(
      "\nmean per cycle: shape matching %.3f ms, detection %.3f ms, response %.3f ms, "
      "%.0f contacts\n",
      shape_matching / cycles, detection / cycles, response / cycles, double(contacts) / cycles);
  return contact_hash.value();
}

std::uint64_t finalStateHash(const dc::Scene& scene) {
  TrajectoryHash state_hash;
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    state_hash.addVectors(scene.body(o).positions());
    state_hash.addVectors(scene.body(o).velocities());
  }
  return state_hash.value();
}

}  // namespace

int main(int argc, char** argv) {
  const std::string name = argc > 1 ? argv[1] : "three_objects";
  const auto kind = dc::parseDemoScene(name);
  if (!kind) {
    std::fprintf(stderr, "unknown scene '%s': %s\n", name.c_str(),
                 dc::enumNameList(dc::kDemoSceneNames).c_str());
    return 2;
  }
  const int cycles = argc > 2 ? std::atoi(argv[2]) : 300;
  dc::SceneConfig config;
  config.level = argc > 3 ? std::atoi(argv[3]) : -1;
  const long points = argc > 4 ? std::atol(argv[4]) : 0;
  if (points < 0) {
    std::fprintf(stderr, "points %ld must be >= 0 (0: the scene's default)\n", points);
    return 2;
  }
  if (argc > 5) config.contact_distance_m = std::atof(argv[5]);
  if (argc > 6) config.threads = std::atoi(argv[6]);
  std::unique_ptr<dc::Scene> scene;
  try {
    scene = dc::makeDemoScene(*kind, std::size_t(points), config);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "core_demo: %s\n", error.what());
    return 2;
  }
  printScene(name, cycles, *scene);
  const std::uint64_t contacts = runCycles(*kind, cycles, *scene);
  std::printf("mean point speed of the dynamic objects after the last cycle: %.4f m/s\n",
              dc::meanDynamicPointSpeed(*scene));
  std::printf("trajectory hash: contacts %016" PRIx64 ", final state %016" PRIx64 "\n", contacts,
              finalStateHash(*scene));
  return 0;
}
