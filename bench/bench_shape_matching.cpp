// One shape-matching step per point, on one core, for each deformation mode; the damped
// ones also with the portable code where the CPU has wide vectors (the same bits either way).
// Run: make bench (or the binary with --benchmark_filter=...).
#include <benchmark/benchmark.h>

#include "deformable_collision/core/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"

namespace dc = deformable_collision;

namespace {

void shapeMatchingStep(benchmark::State& state, dc::DeformationMode mode, bool damped,
                       bool wide_vectors = dc::wideVectorsAvailable()) {
  const auto points = static_cast<std::size_t>(state.range(0));
  dc::ShapeMatchingConfig config;
  config.mode = mode;
  config.clusters = static_cast<int>(state.range(1));
  config.damping = damped ? 0.05 : 0.0;
  dc::ShapeMatchingBody body(dc::sampleBox(points, {0.5, 0.2, 0.1}, 42), config, wide_vectors);
  std::vector<Eigen::Vector3d> bent = body.restPositions();
  for (auto& p : bent) p.z() += 0.5 * p.x() * p.x();
  body.setPositions(bent);
  const Eigen::Vector3d gravity(0.0, 0.0, -9.81);
  for (auto _ : state) {
    body.step(0.01, gravity);
    benchmark::DoNotOptimize(body.positions().data());
  }
  state.counters["per_point"] = benchmark::Counter(
      static_cast<double>(points), benchmark::Counter::kIsIterationInvariantRate |
                                       benchmark::Counter::kInvert);
}

void arguments(benchmark::internal::Benchmark* b) {
  b->Args({100000, 1})->Args({100000, 4})->Unit(benchmark::kMillisecond);
}

}  // namespace

BENCHMARK_CAPTURE(shapeMatchingStep, rigid, dc::DeformationMode::kRigid, false)->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, linear, dc::DeformationMode::kLinear, false)->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, quadratic, dc::DeformationMode::kQuadratic, false)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, linear_damped, dc::DeformationMode::kLinear, true)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, quadratic_damped, dc::DeformationMode::kQuadratic, true)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, linear_damped_portable, dc::DeformationMode::kLinear, true,
                  false)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, quadratic_damped_portable, dc::DeformationMode::kQuadratic,
                  true, false)
    ->Apply(arguments);

BENCHMARK_MAIN();
