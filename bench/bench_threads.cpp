// A cycle's stages against the threads it runs on (SceneConfig::threads): S2 (the pile) at
// its finest level, S1 (two objects) and S3 (three objects). Each scene is made and settled
// once per thread count; then blocks of cycles are timed in turn on each count, so that the
// host's speed, which drifts by tens of percent over a run, weighs on every count alike,
// and each stage's median over the blocks is kept:
//   bench_threads results_dir [settle=150] [blocks=30] [cycles_per_block=10]
// -> threads.csv: scene, threads, median block mean ms of shape matching, detection,
// response and the whole cycle. The states are the same on every count
// (test_scene_threads).
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

constexpr std::array<int, 3> kThreadCounts = {1, 2, 4};

/// Per block, the mean ms of shape matching, detection, response and the whole cycle.
using BlockMeans = std::array<double, 4>;

BlockMeans timeBlock(dc::Scene& scene, int cycles) {
  BlockMeans m{};
  for (int c = 0; c < cycles; ++c) {
    const auto start = db::Clock::now();
    scene.cycle();
    const dc::CycleStats& s = scene.stats();
    m[3] += db::millisecondsSince(start) / cycles;
    m[0] += s.shape_matching_ms / cycles;
    m[1] += s.detection_ms / cycles;
    m[2] += s.response_ms / cycles;
  }
  return m;
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void measure(dc::DemoScene kind, int settle, int blocks, int cycles, std::FILE* csv) {
  std::vector<std::unique_ptr<dc::Scene>> scenes;
  for (const int threads : kThreadCounts) {
    dc::SceneConfig config;
    config.threads = threads;
    scenes.push_back(dc::makeDemoScene(kind, 0, config));
    for (int c = 0; c < settle; ++c) scenes.back()->cycle();
  }
  std::vector<std::vector<BlockMeans>> timed(scenes.size());
  for (int block = 0; block < blocks; ++block) {
    for (std::size_t s = 0; s < scenes.size(); ++s) {
      timed[s].push_back(timeBlock(*scenes[s], cycles));
    }
  }
  for (std::size_t s = 0; s < scenes.size(); ++s) {
    BlockMeans m{};
    for (std::size_t stage = 0; stage < m.size(); ++stage) {
      std::vector<double> values;
      for (const BlockMeans& b : timed[s]) values.push_back(b[stage]);
      m[stage] = median(values);
    }
    std::fprintf(csv, "%s,%d,%.5f,%.5f,%.5f,%.5f\n", dc::toString(kind), kThreadCounts[s], m[0],
                 m[1], m[2], m[3]);
    std::printf(
        "%s, %d threads: shape matching %.3f, detection %.3f, response %.3f, whole %.3f ms\n",
        dc::toString(kind), kThreadCounts[s], m[0], m[1], m[2], m[3]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: bench_threads results_dir [settle=150] [blocks=30] "
                 "[cycles_per_block=10]\n");
    return 2;
  }
  const int settle = argc > 2 ? std::atoi(argv[2]) : 150;
  const int blocks = argc > 3 ? std::atoi(argv[3]) : 30;
  const int cycles = argc > 4 ? std::atoi(argv[4]) : 10;
  if (settle < 0 || blocks < 1 || cycles < 1) {
    std::fprintf(stderr, "bench_threads: settle >= 0, blocks >= 1 and cycles_per_block >= 1\n");
    return 2;
  }
  db::CsvAppender csv(std::string(argv[1]) + "/threads.csv",
                      "scene,threads,shape_matching_ms,detection_ms,response_ms,whole_ms");
  for (const dc::DemoScene kind :
       {dc::DemoScene::kPile, dc::DemoScene::kTwoObjects, dc::DemoScene::kThreeObjects}) {
    measure(kind, settle, blocks, cycles, csv.file());
  }
  return 0;
}
