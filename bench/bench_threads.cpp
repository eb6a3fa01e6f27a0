// A cycle's stages against the threads it runs on (SceneConfig::threads): S2 (the pile) at
// its finest level, S1 (two objects) and S3 (three objects), each settled on its own
// threads, then timed; of 3 such runs, the one of the least mean whole cycle:
//   bench_threads results_dir [settle=150] [cycles=100]
// -> threads.csv: scene, threads, mean ms of shape matching, detection, response and the
// whole cycle. The states are the same on every count (test_scene_threads).
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "bench/bench_common.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

struct StageMeans {
  double shape_matching_ms = 0, detection_ms = 0, response_ms = 0, whole_ms = 0;
};

StageMeans measure(dc::DemoScene kind, int threads, int settle, int cycles) {
  dc::SceneConfig config;
  config.threads = threads;
  std::unique_ptr<dc::Scene> scene = dc::makeDemoScene(kind, 0, config);
  for (int c = 0; c < settle; ++c) scene->cycle();
  StageMeans m;
  for (int c = 0; c < cycles; ++c) {
    const auto start = db::Clock::now();
    scene->cycle();
    m.whole_ms += db::millisecondsSince(start) / cycles;
    const dc::CycleStats& s = scene->stats();
    m.shape_matching_ms += s.shape_matching_ms / cycles;
    m.detection_ms += s.detection_ms / cycles;
    m.response_ms += s.response_ms / cycles;
  }
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_threads results_dir [settle=150] [cycles=100]\n");
    return 2;
  }
  const int settle = argc > 2 ? std::atoi(argv[2]) : 150;
  const int cycles = argc > 3 ? std::atoi(argv[3]) : 100;
  db::CsvAppender csv(std::string(argv[1]) + "/threads.csv",
                      "scene,threads,shape_matching_ms,detection_ms,response_ms,whole_ms");
  for (const dc::DemoScene kind :
       {dc::DemoScene::kPile, dc::DemoScene::kTwoObjects, dc::DemoScene::kThreeObjects}) {
    for (const int threads : {1, 2, 4}) {
      StageMeans m = measure(kind, threads, settle, cycles);
      for (int run = 1; run < 3; ++run) {
        const StageMeans again = measure(kind, threads, settle, cycles);
        if (again.whole_ms < m.whole_ms) m = again;
      }
      std::fprintf(csv.file(), "%s,%d,%.5f,%.5f,%.5f,%.5f\n", dc::toString(kind), threads,
                   m.shape_matching_ms, m.detection_ms, m.response_ms, m.whole_ms);
      std::printf(
          "%s, %d threads: shape matching %.3f, detection %.3f, response %.3f, whole %.3f ms\n",
          dc::toString(kind), threads, m.shape_matching_ms, m.detection_ms, m.response_ms,
          m.whole_ms);
    }
  }
  return 0;
}
