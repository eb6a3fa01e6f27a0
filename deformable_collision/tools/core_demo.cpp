// The core on a built-in scene, until the nodelet exists: objects, points, level of detail,
// time per stage and contacts, over a fixed simulated time.
// Usage: core_demo [scene=three_objects] [cycles=300] [level=-1 (finest)]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "deformable_collision/core/demo_scenes.h"

namespace dc = deformable_collision;

int main(int argc, char** argv) {
  const std::string name = argc > 1 ? argv[1] : "three_objects";
  const auto kind = dc::parseDemoScene(name);
  if (!kind) {
    std::fprintf(stderr, "unknown scene '%s': two_objects, pile, three_objects or gripper\n",
                 name.c_str());
    return 2;
  }
  const int cycles = argc > 2 ? std::atoi(argv[2]) : 300;
  dc::SceneConfig config;
  config.level = argc > 3 ? std::atoi(argv[3]) : -1;
  auto scene = dc::makeDemoScene(*kind, 0, config);

  std::size_t points = 0;
  std::printf("deformable_collision demo: scene %s, %d cycles of %.3f s\n", name.c_str(), cycles,
              scene->config().dt_s);
  std::printf("%-14s %-10s %-10s %8s %8s\n", "object", "kind", "mode", "points", "clusters");
  for (std::size_t o = 0; o < scene->objectCount(); ++o) {
    const auto& object = scene->objectConfig(o);
    points += scene->body(o).pointCount();
    if (o < 8) {
      std::printf("%-14s %-10s %-10s %8zu %8zu\n", object.name.c_str(), dc::toString(object.kind),
                  dc::toString(scene->body(o).config().mode), scene->body(o).pointCount(),
                  scene->body(o).clusterCount());
    }
  }
  if (scene->objectCount() > 8) std::printf("... %zu objects in all\n", scene->objectCount());
  std::printf("points %zu, level %d of %d, contact distance %.3f m\n\n", points, scene->level(),
              scene->maxLevel(), scene->config().contact_distance_m);

  double shape_matching = 0.0, detection = 0.0, response = 0.0;
  std::size_t contacts = 0;
  std::printf("%8s %10s %10s %10s %9s %12s\n", "cycle", "shape ms", "detect ms", "respond ms",
              "contacts", "spheres");
  for (int cycle = 0; cycle < cycles; ++cycle) {
    dc::driveDemoScene(*kind, *scene, cycle * scene->config().dt_s);
    scene->cycle();
    const auto& s = scene->stats();
    shape_matching += s.shape_matching_ms;
    detection += s.detection_ms;
    response += s.response_ms;
    contacts += s.contacts;
    if (cycle % (cycles / 6 > 0 ? cycles / 6 : 1) == 0 || cycle == cycles - 1) {
      std::printf("%8d %10.3f %10.3f %10.3f %9zu %12zu\n", cycle, s.shape_matching_ms,
                  s.detection_ms, s.response_ms, s.contacts, s.spheres_updated);
    }
  }
  std::printf("\nmean per cycle: shape matching %.3f ms, detection %.3f ms, response %.3f ms, "
              "%.0f contacts\n",
              shape_matching / cycles, detection / cycles, response / cycles,
              double(contacts) / cycles);
  return 0;
}
