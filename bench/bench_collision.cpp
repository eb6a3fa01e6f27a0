// S1: the collision stage of two quadratic objects touching at a patch, per step, on the
// same deforming points in the same run, by
//   deformation_update - our spheres from the shape-matching matrices, lazily (the paper)
//   exact_refit        - our smallest enclosing sphere of the points of each visited node
//   full_refit         - our every node refitted bottom-up, then the same query
// and by the peers of s1_methods.h (FCL, Bullet, PCL). Every method finds the point pairs
// closer than the contact distance; the run fails if any finds other pairs than ours.
// Usage: bench_collision [points_in_all=160000] [steps=20] [results_dir] [contact_distance_m=0.005]
// Prints the table, then what our query tested per step and how full ball a's leaves are.
// With results_dir (not empty), appends to results_dir/s1.csv and results_dir/s1_pairs.csv,
// each row with its contact distance. The default 5 mm is a near miss (a few point pairs per
// step at 160k points); 0.05 is the dense case, thousands of pairs touching, where every
// method's time goes into testing points of leaves in reach against each other.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "bench/bench_common.h"
#include "bench/s1_bodies.h"
#include "bench/s1_methods.h"
#include "deformable_collision/core/query/collision_query.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

/// Our sphere trees over both bodies, queried to the leaves. Counts the spheres computed.
class SphereTreeMethod : public db::S1Method {
 public:
  SphereTreeMethod(const char* name, const dc::ShapeMatchingBody& a, const dc::ShapeMatchingBody& b,
                   dc::SphereUpdate update, const dc::SphereTreeConfig& config,
                   double contact_distance_m)
      : name_(name),
        update_(update),
        a_(a, config),
        b_(b, config),
        contact_distance_m_(contact_distance_m) {}

  const char* name() const override { return name_; }

  std::size_t step() override {
    contacts_.clear();
    a_.beginCycle(update_);
    b_.beginCycle(update_);
    query_.collide(a_, b_, kLeaves, contact_distance_m_, contacts_, counters_);
    leaf_contacts_ += contacts_.size();
    return a_.counters().spheres_updated + b_.counters().spheres_updated;
  }

  /// What the queries of `steps` steps tested, per step, and the leaves they tested: where
  /// the time goes, against the point pairs found.
  void printWork(int steps) const {
    std::uint32_t fewest = ~0u, most = 0;
    const auto& starts = a_.leafSlotStarts();
    for (std::size_t k = 0; k + 1 < starts.size(); ++k) {
      fewest = std::min(fewest, starts[k + 1] - starts[k]);
      most = std::max(most, starts[k + 1] - starts[k]);
    }
    std::printf(
        "\n%s's query per step: %.0f node pairs, %.0f leaf pairs tested (%.1f point tests "
        "each), %.0f of them closer than the contact distance; ball a's %zu leaves hold %u to "
        "%u points (%.1f on average)\n",
        name_, double(counters_.node_pairs_tested) / steps,
        double(counters_.leaf_pairs_tested) / steps,
        double(counters_.point_tests) /
            double(std::max<std::size_t>(1, counters_.leaf_pairs_tested)),
        double(leaf_contacts_) / steps, starts.size() - 1, fewest, most,
        double(starts.back()) / double(starts.size() - 1));
  }

  /// The point pairs of the contacts' leaves; a point shared by overlapping clusters sits
  /// in several leaves, hence sortedUnique.
  std::vector<db::PointPair> pointPairs() const override {
    std::vector<db::PointPair> pairs;
    const auto& pa = a_.body().positions();
    const auto& pb = b_.body().positions();
    for (const dc::SphereContact& c : contacts_) {
      const dc::SphereNode& na = a_.node(c.node_a);
      const dc::SphereNode& nb = b_.node(c.node_b);
      for (std::uint32_t s = na.first_point; s < na.first_point + na.point_count; ++s) {
        for (std::uint32_t t = nb.first_point; t < nb.first_point + nb.point_count; ++t) {
          const std::uint32_t i = a_.pointIndices()[s];
          const std::uint32_t j = b_.pointIndices()[t];
          if (db::closerThan(pa[i], pb[j], contact_distance_m_)) pairs.emplace_back(i, j);
        }
      }
    }
    return db::sortedUnique(std::move(pairs));
  }

 private:
  static constexpr int kLeaves = 1000;  // deeper than any tree: the query tests points

  const char* name_;
  dc::SphereUpdate update_;
  dc::SphereTree a_, b_;
  double contact_distance_m_;
  dc::HierarchyQuery query_;
  dc::QueryCounters counters_;
  std::size_t leaf_contacts_ = 0;
  std::vector<dc::SphereContact> contacts_;
};

struct Totals {
  double ms = 0.0;
  std::size_t updated = 0;
  std::size_t pairs = 0;
};

/// Full refit's place in makeMethods: the ratio column's denominator.
constexpr std::size_t kFullRefit = 2;

/// Ours first (the reference every other method's pairs must equal), then the peers.
std::vector<std::unique_ptr<db::S1Method>> makeMethods(const dc::ShapeMatchingBody& a,
                                                       const dc::ShapeMatchingBody& b,
                                                       double contact_distance_m) {
  const dc::SphereTreeConfig tree_config{2, 8};
  std::vector<std::unique_ptr<db::S1Method>> methods;
  methods.push_back(std::make_unique<SphereTreeMethod>(
      "deformation_update", a, b, dc::SphereUpdate::kDeformation, tree_config, contact_distance_m));
  methods.push_back(std::make_unique<SphereTreeMethod>(
      "exact_refit", a, b, dc::SphereUpdate::kExactRefit, tree_config, contact_distance_m));
  methods.push_back(std::make_unique<SphereTreeMethod>(
      "full_refit", a, b, dc::SphereUpdate::kBottomUpRefit, tree_config, contact_distance_m));
  for (auto& peer : db::makePeers(a.positions(), b.positions(), contact_distance_m)) {
    methods.push_back(std::move(peer));
  }
  return methods;
}

/// Steps both bodies and times every method on each step; false (said on stderr) as soon as
/// a method finds other pairs than the first.
bool runSteps(int steps, dc::ShapeMatchingBody& a, dc::ShapeMatchingBody& b,
              std::vector<std::unique_ptr<db::S1Method>>& methods, std::vector<Totals>& totals) {
  for (int s = 0; s < steps; ++s) {
    a.step(0.01, Eigen::Vector3d::Zero());
    b.step(0.01, Eigen::Vector3d::Zero());
    std::vector<db::PointPair> reference;
    for (std::size_t m = 0; m < methods.size(); ++m) {
      const auto start = db::Clock::now();
      totals[m].updated += methods[m]->step();
      totals[m].ms += db::millisecondsSince(start);
      const std::vector<db::PointPair> pairs = methods[m]->pointPairs();
      totals[m].pairs += pairs.size();
      if (m == 0) {
        reference = pairs;
      } else if (pairs != reference) {
        std::fprintf(stderr,
                     "bench_collision: step %d: %s found %zu point pairs, %s %zu (or other ones)\n",
                     s, methods[m]->name(), pairs.size(), methods[0]->name(), reference.size());
        return false;
      }
    }
  }
  return true;
}

/// The table on stdout and, with a results directory, its rows in s1.csv and s1_pairs.csv.
void report(const std::vector<std::unique_ptr<db::S1Method>>& methods,
            const std::vector<Totals>& totals, std::size_t each, int steps,
            double contact_distance_m, const std::string& results_dir) {
  std::printf(
      "S1: two quadratic balls of %zu points each (%zu in all), %d steps, contact distance "
      "%.3f m; every method found the same %.1f point pairs per step\n\n",
      each, 2 * each, steps, contact_distance_m, double(totals[0].pairs) / steps);
  std::printf(
      "| method | collision ms/step | / full refit | volumes updated/step |\n|---|---|---|---|\n");
  const double full_refit_ms = totals[kFullRefit].ms / steps;
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::printf("| %s | %.3f | %.4f | %.0f |\n", methods[m]->name(), totals[m].ms / steps,
                totals[m].ms / steps / full_refit_ms, double(totals[m].updated) / steps);
  }
  // makeMethods puts ours first.
  static_cast<const SphereTreeMethod&>(*methods.front()).printWork(steps);
  if (results_dir.empty()) return;
  db::CsvAppender csv(
      results_dir + "/s1.csv",
      "points,contact_distance_m,method,spheres_updated,collision_ms,ratio_to_full_refit");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::fprintf(csv.file(), "%zu,%.4f,%s,%.0f,%.5f,%.5f\n", 2 * each, contact_distance_m,
                 methods[m]->name(), double(totals[m].updated) / steps, totals[m].ms / steps,
                 totals[m].ms / steps / full_refit_ms);
  }
  db::CsvAppender pairs(results_dir + "/s1_pairs.csv",
                        "points,contact_distance_m,steps,methods,point_pairs_per_step");
  std::fprintf(pairs.file(), "%zu,%.4f,%d,%zu,%.2f\n", 2 * each, contact_distance_m, steps,
               methods.size(), double(totals[0].pairs) / steps);
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t points = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 160000;
  const int steps = argc > 2 ? std::atoi(argv[2]) : 20;
  const std::string results_dir = argc > 3 ? argv[3] : "";
  const double contact_distance_m = argc > 4 ? std::atof(argv[4]) : 0.005;
  const std::size_t each = points / 2;

  // Two balls of radius 0.5 m pressed 2 cm into each other, both released from a bend.
  db::S1Bodies bodies = db::makeS1Bodies(each, 0.98);
  dc::ShapeMatchingBody& a = bodies.a;
  dc::ShapeMatchingBody& b = bodies.b;

  std::vector<std::unique_ptr<db::S1Method>> methods = makeMethods(a, b, contact_distance_m);
  std::vector<Totals> totals(methods.size());
  if (!runSteps(steps, a, b, methods, totals)) return 1;
  report(methods, totals, each, steps, contact_distance_m, results_dir);
  return 0;
}
