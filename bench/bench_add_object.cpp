// The cost of making an object (Scene::addObject: clusters, rest moments, tree, exact radii)
// and of the first cycle after it, against its points, and for a static object what it
// leaves to its first contacts (every node's slab and fixed plane, measured when a contact
// first reaches the node):
//   bench_add_object SHAPE KIND POINTS results_dir [repeats=1] [clusters=1]
// SHAPE: thin_grid (two layers 1 cm apart, 1 cm spacing), thick_grid (16 such layers),
// random_box (uniform in a 16 cm thick box, a point per cm^3), scanned_surface (a closed
// ellipsoid surface, a point per cm^2, 1 mm of noise). KIND: static or dynamic (linear).
// The least of `repeats` runs -> add_object.csv.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "deformable_collision/core/hierarchy/node_slabs.h"
#include "deformable_collision/core/response/detail/fixed_planes.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

constexpr double kSpacingM = 0.01;

std::vector<Eigen::Vector3d> shapePoints(const std::string& shape, std::size_t points) {
  const auto side = [&](int layers) {
    return static_cast<int>(std::lround(std::sqrt(double(points) / layers)));
  };
  if (shape == "thin_grid") return dc::gridLayers(side(2), 2, kSpacingM);
  if (shape == "thick_grid") return dc::gridLayers(side(16), 16, kSpacingM);
  if (shape == "random_box") {
    const double half = 0.5 * side(16) * kSpacingM;
    return dc::sampleBox(points, {half, half, 0.08}, 5);
  }
  if (shape == "scanned_surface") {
    // An ellipsoid of radii r (1, 0.8, 0.6) has about 0.78 of the area 4 pi r^2.
    const double r = std::sqrt(double(points) * kSpacingM * kSpacingM / (4 * M_PI * 0.78));
    return dc::sampleNoisySurface(points, {r, 0.8 * r, 0.6 * r}, 0.001, 9);
  }
  std::fprintf(stderr, "bench_add_object: unknown shape %s\n", shape.c_str());
  std::exit(2);
}

dc::ObjectConfig objectConfig(const std::string& kind, int clusters) {
  dc::ObjectConfig config;
  config.name = "object";
  config.shape.clusters = clusters;
  if (kind == "static") {
    config.kind = dc::ObjectKind::kStatic;
    config.shape.mode = dc::DeformationMode::kRigid;
  } else if (kind != "dynamic") {
    std::fprintf(stderr, "bench_add_object: unknown kind %s\n", kind.c_str());
    std::exit(2);
  }
  return config;
}

struct Timing {
  double add_ms = std::numeric_limits<double>::infinity();
  double first_cycle_ms = std::numeric_limits<double>::infinity();
  /// Static objects: every node's slab and plane, which contacts measure node by node.
  double every_node_ms = std::numeric_limits<double>::infinity();
};

/// What the first contacts of a static object measure, for all its nodes at once.
double everyNodeMs(const dc::Scene& scene, double gap_m) {
  const auto start = db::Clock::now();
  dc::NodeSlabs slabs;
  slabs.compute(scene.tree(0), scene.body(0).positions());
  dc::detail::FixedPlanes planes(scene.body(0), scene.tree(0), gap_m);
  for (std::uint32_t n = 0; n < scene.tree(0).nodeCount(); ++n) planes.plane(n);
  return db::millisecondsSince(start);
}

/// The object made in a new scene, then one cycle; the least times of `repeats` runs.
Timing measure(const std::vector<Eigen::Vector3d>& points, const dc::ObjectConfig& config,
               int repeats) {
  dc::SceneConfig scene_config;
  scene_config.contact_distance_m = kSpacingM;
  Timing best;
  for (int r = 0; r < repeats; ++r) {
    dc::Scene scene(scene_config);
    auto start = db::Clock::now();
    scene.addObject(config, points);
    best.add_ms = std::min(best.add_ms, db::millisecondsSince(start));
    start = db::Clock::now();
    scene.cycle();
    best.first_cycle_ms = std::min(best.first_cycle_ms, db::millisecondsSince(start));
    if (config.kind == dc::ObjectKind::kStatic) {
      best.every_node_ms = std::min(best.every_node_ms, everyNodeMs(scene, kSpacingM));
    }
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr,
                 "usage: bench_add_object SHAPE KIND POINTS results_dir [repeats=1] "
                 "[clusters=1]\n");
    return 2;
  }
  const std::string shape = argv[1], kind = argv[2];
  const std::vector<Eigen::Vector3d> points = shapePoints(shape, std::stoul(argv[3]));
  const int repeats = argc > 5 ? std::max(1, std::atoi(argv[5])) : 1;
  const int clusters = argc > 6 ? std::max(1, std::atoi(argv[6])) : 1;
  const Timing t = measure(points, objectConfig(kind, clusters), repeats);
  const double us_per_point = 1000.0 * t.add_ms / double(points.size());
  db::CsvAppender csv(std::string(argv[4]) + "/add_object.csv",
                      "shape,kind,points,add_ms,us_per_point,first_cycle_ms,every_node_ms");
  const bool deferred = std::isfinite(t.every_node_ms);
  std::fprintf(csv.file(), "%s,%s,%zu,%.3f,%.4f,%.3f,", shape.c_str(), kind.c_str(), points.size(),
               t.add_ms, us_per_point, t.first_cycle_ms);
  if (deferred) std::fprintf(csv.file(), "%.3f", t.every_node_ms);
  std::fprintf(csv.file(), "\n");
  std::printf(
      "add_object %s %s: %zu points, made in %.3f ms (%.4f us a point), first cycle %.3f ms",
      shape.c_str(), kind.c_str(), points.size(), t.add_ms, us_per_point, t.first_cycle_ms);
  if (deferred) std::printf(", every node's slab and plane %.3f ms", t.every_node_ms);
  std::printf("\n");
  return 0;
}
