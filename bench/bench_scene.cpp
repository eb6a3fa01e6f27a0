// The cycle of built-in scenes stage by stage, on one core (the paper's section 7):
//   S2 (pile: 300 soft objects, 131k points) at every level, after the pile has formed;
//   S3 (three objects, 19k points) at the finest level.
// Usage: bench_scene [settle_cycles=150] [measured_cycles=20]
#include <cstdio>
#include <cstdlib>

#include "deformable_collision/core/demo_scenes.h"

namespace dc = deformable_collision;

namespace {

struct Figures {
  double shape_matching_ms = 0, detection_ms = 0, response_ms = 0, contacts = 0;
};

Figures run(dc::DemoScene kind, int level, int settle, int measured) {
  dc::SceneConfig config;
  config.level = level;
  auto scene = dc::makeDemoScene(kind, 0, config);
  for (int c = 0; c < settle; ++c) scene->cycle();
  Figures f;
  for (int c = 0; c < measured; ++c) {
    scene->cycle();
    const auto& s = scene->stats();
    f.shape_matching_ms += s.shape_matching_ms / measured;
    f.detection_ms += s.detection_ms / measured;
    f.response_ms += s.response_ms / measured;
    f.contacts += double(s.contacts) / measured;
  }
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  const int settle = argc > 1 ? std::atoi(argv[1]) : 150;
  const int measured = argc > 2 ? std::atoi(argv[2]) : 20;
  const int finest = dc::makeDemoScene(dc::DemoScene::kPile)->maxLevel();
  std::printf("S2 pile, %d settling cycles, mean of %d\n\n", settle, measured);
  std::printf("| level | contacts | detection ms | response ms | total ms |\n|---|---|---|---|---|\n");
  for (int level = 1; level <= finest; ++level) {
    const Figures f = run(dc::DemoScene::kPile, level, settle, measured);
    std::printf("| %d | %.0f | %.2f | %.2f | %.2f |\n", level, f.contacts, f.detection_ms,
                f.response_ms, f.detection_ms + f.response_ms);
  }
  const Figures s3 = run(dc::DemoScene::kThreeObjects, -1, settle, measured);
  std::printf("\nS3 three objects, finest level: shape matching %.3f ms, detection %.3f ms, "
              "response %.3f ms, cycle %.3f ms, %.0f contacts\n",
              s3.shape_matching_ms, s3.detection_ms, s3.response_ms,
              s3.shape_matching_ms + s3.detection_ms + s3.response_ms, s3.contacts);
  return 0;
}
