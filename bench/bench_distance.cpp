// ~get_distance's query on S1's two deforming balls held apart: per step, the closest points
// of the two point sets by
//   ours_finest   - HierarchyDistance to the leaves (exact), spheres from the deformation
//   ours_level_N  - the same three levels above the leaves: a lower bound and its error
//   fcl_obbrss    - FCL's distance() on a BVHModel<OBBRSS> of each cloud (a degenerate
//                   triangle per point: FCL's distance takes only triangle models), refitted
//                   top-down each step (FCL 0.7's bottom-up OBBRSS refit does not enclose)
// on the same points, the result checked against FCL's: the run fails on a difference.
// Usage: bench_distance [points_in_all=160000] [steps=20] [results_dir] [gap_m=0.02]
// With results_dir (not empty), appends to results_dir/distance.csv.
#include <fcl/fcl.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "bench/s1_bodies.h"
#include "deformable_collision/core/query/distance_query.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

using FclModel = fcl::BVHModel<fcl::OBBRSSd>;
/// ours_level_N's levels above the finest.
constexpr int kLevelsAboveLeaves = 3;

/// FCL's model of one body's points, a degenerate triangle per point.
class FclCloud {
 public:
  explicit FclCloud(const std::vector<Eigen::Vector3d>& points)
      : points_(points), model_(std::make_shared<FclModel>()) {
    std::vector<fcl::Triangle> triangles(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) triangles[i] = fcl::Triangle(i, i, i);
    model_->beginModel();
    model_->addSubModel(points, triangles);
    model_->endModel();
    object_ = std::make_unique<fcl::CollisionObjectd>(model_);
  }

  /// Brings the model up to the body's current points.
  fcl::CollisionObjectd& refit() {
    model_->beginUpdateModel();
    model_->updateSubModel(points_);
    model_->endUpdateModel(true, false);
    object_->computeAABB();
    return *object_;
  }

 private:
  const std::vector<Eigen::Vector3d>& points_;
  std::shared_ptr<FclModel> model_;
  std::unique_ptr<fcl::CollisionObjectd> object_;
};

struct Totals {
  double ms = 0.0;
  double refit_ms = 0.0;    ///< Of ms: bringing the structure up to the points.
  double distance_m = 0.0;  ///< Summed over the steps.
  double error_bound_m = 0.0;
  std::size_t node_pairs = 0;
};

/// Our query on fresh spheres of both trees, timed with the cycle's beginCycle().
dc::ClosestPoints ours(dc::SphereTree& a, dc::SphereTree& b, int level,
                       dc::HierarchyDistance& distance, Totals& totals) {
  dc::QueryCounters counters;
  const auto start = db::Clock::now();
  a.beginCycle();
  b.beginCycle();
  const auto closest = distance.closest(a, b, level, 1.0, counters);
  totals.ms += db::millisecondsSince(start);
  totals.node_pairs += counters.node_pairs_tested;
  if (!closest) {
    std::fprintf(stderr, "bench_distance: nothing within 1 m\n");
    std::exit(1);
  }
  totals.distance_m += closest->distance_m;
  totals.error_bound_m += closest->error_bound_m;
  return *closest;
}

double fclDistance(FclCloud& a, FclCloud& b, Totals& totals) {
  const auto start = db::Clock::now();
  fcl::CollisionObjectd& object_a = a.refit();
  fcl::CollisionObjectd& object_b = b.refit();
  totals.refit_ms += db::millisecondsSince(start);
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd result;
  fcl::distance(&object_a, &object_b, request, result);
  totals.ms += db::millisecondsSince(start);
  totals.distance_m += result.min_distance;
  return result.min_distance;
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t points = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 160000;
  const int steps = argc > 2 ? std::atoi(argv[2]) : 20;
  const std::string results_dir = argc > 3 ? argv[3] : "";
  const double gap_m = argc > 4 ? std::atof(argv[4]) : 0.02;
  db::S1Bodies bodies = db::makeS1Bodies(points / 2, 1.0 + gap_m);
  dc::SphereTree tree_a(bodies.a, {2, 8}), tree_b(bodies.b, {2, 8});
  FclCloud fcl_a(bodies.a.positions()), fcl_b(bodies.b.positions());
  dc::HierarchyDistance distance;
  const int finest = std::max(tree_a.maxLevel(), tree_b.maxLevel());
  const int coarse_level = finest - kLevelsAboveLeaves;
  Totals finest_totals, coarse_totals, fcl_totals;
  double largest_difference_m = 0.0;
  for (int s = 0; s < steps; ++s) {
    bodies.a.step(0.01, Eigen::Vector3d::Zero());
    bodies.b.step(0.01, Eigen::Vector3d::Zero());
    const double exact = ours(tree_a, tree_b, finest, distance, finest_totals).distance_m;
    const dc::ClosestPoints coarse = ours(tree_a, tree_b, coarse_level, distance, coarse_totals);
    const double peer = fclDistance(fcl_a, fcl_b, fcl_totals);
    largest_difference_m = std::max(largest_difference_m, std::abs(exact - peer));
    if (std::abs(exact - peer) > 1e-9 || coarse.distance_m > exact + 1e-12 ||
        coarse.distance_m + coarse.error_bound_m < exact - 1e-12) {
      std::fprintf(
          stderr, "bench_distance: step %d: ours %.12f m, FCL %.12f m, level %d [%.6f, %.6f]\n", s,
          exact, peer, coarse_level, coarse.distance_m, coarse.distance_m + coarse.error_bound_m);
      return 1;
    }
  }
  std::printf(
      "S1 held apart: two quadratic balls of %zu points each, gap %.3f m, %d steps; ours and "
      "FCL's distances differ by at most %.2e m\n\n| method | ms/query | of it refit | "
      "distance m | error bound m | node pairs |\n|---|---|---|---|---|---|\n",
      points / 2, gap_m, steps, largest_difference_m);
  const auto row = [&](const std::string& name, const Totals& t) {
    std::printf("| %s | %.4f | %.4f | %.6f | %.6f | %.0f |\n", name.c_str(), t.ms / steps,
                t.refit_ms / steps, t.distance_m / steps, t.error_bound_m / steps,
                double(t.node_pairs) / steps);
  };
  const std::string coarse_name = "ours_level_" + std::to_string(coarse_level);
  row("ours_finest", finest_totals);
  row(coarse_name, coarse_totals);
  row("fcl_obbrss", fcl_totals);
  if (results_dir.empty()) return 0;
  db::CsvAppender csv(results_dir + "/distance.csv",
                      "points,gap_m,method,ms_per_query,refit_ms,distance_m,error_bound_m,"
                      "node_pairs");
  for (const auto& [name, t] : {std::pair<std::string, const Totals&>{"ours_finest", finest_totals},
                                {coarse_name, coarse_totals},
                                {"fcl_obbrss", fcl_totals}}) {
    std::fprintf(csv.file(), "%zu,%.4f,%s,%.5f,%.5f,%.9f,%.9f,%.0f\n", points, gap_m, name.c_str(),
                 t.ms / steps, t.refit_ms / steps, t.distance_m / steps, t.error_bound_m / steps,
                 double(t.node_pairs) / steps);
  }
  return 0;
}
