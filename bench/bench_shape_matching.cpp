// One shape-matching step, and one fit to an observation (tracking), per point, on one core,
// for each deformation mode; the damped steps and the fits also with the portable code,
// which the CPU's vectors (AVX-512 or AVX2) give the same bits as.
// Run: make bench (or the binary with --benchmark_filter=...).
#include <benchmark/benchmark.h>

#include <limits>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"

namespace dc = deformable_collision;

namespace {

/// The box bent along x, so that the fit has something to deform.
std::vector<Eigen::Vector3d> bent(std::vector<Eigen::Vector3d> points) {
  for (auto& p : points) p.z() += 0.5 * p.x() * p.x();
  return points;
}

void shapeMatchingStep(benchmark::State& state, dc::DeformationMode mode, bool damped,
                       dc::VectorWidth vectors = dc::widestVectors()) {
  const auto points = static_cast<std::size_t>(state.range(0));
  dc::ShapeMatchingConfig config;
  config.mode = mode;
  config.clusters = static_cast<int>(state.range(1));
  config.damping = damped ? 0.05 : 0.0;
  dc::ShapeMatchingBody body(dc::sampleBox(points, {0.5, 0.2, 0.1}, 42), config, vectors);
  body.setPositions(bent(body.restPositions()));
  const Eigen::Vector3d gravity(0.0, 0.0, -9.81);
  for (auto _ : state) {
    body.step(0.01, gravity);
    benchmark::DoNotOptimize(body.positions().data());
  }
  state.counters["per_point"] = benchmark::Counter(
      static_cast<double>(points),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

/// One fit to the bent box whose every tenth point is unobserved (NaN), alternating with
/// the box a millimetre aside so that each fit starts from the other's state.
void shapeMatchingTrack(benchmark::State& state, dc::DeformationMode mode,
                        dc::VectorWidth vectors = dc::widestVectors()) {
  const auto points = static_cast<std::size_t>(state.range(0));
  dc::ShapeMatchingConfig config;
  config.mode = mode;
  config.clusters = static_cast<int>(state.range(1));
  dc::ShapeMatchingBody body(dc::sampleBox(points, {0.5, 0.2, 0.1}, 42), config, vectors);
  std::vector<Eigen::Vector3d> observations[2] = {bent(body.restPositions()), {}};
  for (std::size_t i = 0; i < points; i += 10) {
    observations[0][i].x() = std::numeric_limits<double>::quiet_NaN();
  }
  observations[1] = observations[0];
  for (auto& p : observations[1]) p.y() += 1e-3;
  std::size_t fits = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(body.track(observations[fits++ % 2]));
  }
  state.counters["per_point"] = benchmark::Counter(
      static_cast<double>(points),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
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
                  dc::VectorWidth::kPortable)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingStep, quadratic_damped_portable, dc::DeformationMode::kQuadratic,
                  true, dc::VectorWidth::kPortable)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingTrack, linear, dc::DeformationMode::kLinear)->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingTrack, quadratic, dc::DeformationMode::kQuadratic)->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingTrack, linear_portable, dc::DeformationMode::kLinear,
                  dc::VectorWidth::kPortable)
    ->Apply(arguments);
BENCHMARK_CAPTURE(shapeMatchingTrack, quadratic_portable, dc::DeformationMode::kQuadratic,
                  dc::VectorWidth::kPortable)
    ->Apply(arguments);

BENCHMARK_MAIN();
