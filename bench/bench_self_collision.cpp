// S4: a soft strip folded onto itself (self_collision). Per size: the self-query's time, node
// pairs and point pairs tested and self-contacts, against PCL's kd-tree with the same rest
// rule; then the price of self_collision where nothing folds, the whole cycle of the strip
// lying on a floor with it on against off.
//   bench_self_collision points clusters results_dir [repeats=10]
// -> self_collision.csv. Times are the least of `repeats` queries (a shared machine's noise
// only adds); the flat cycles the median of blocks of 10, self_collision off and on in turn.
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "bench/bench_common.h"
#include "deformable_collision/core/query/self_collision_query.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;
using Points = std::vector<Eigen::Vector3d>;

namespace {

constexpr double kLengthM = 0.4;  ///< The strip is 40 x 10 cm, two layers thick.

/// A strip of about `points` points, four times as long as wide, in two layers; its point
/// spacing in `spacing_m`.
Points strip(std::size_t points, double& spacing_m) {
  const int across = std::max(2, static_cast<int>(std::lround(std::sqrt(points / 8.0))));
  const int along = 4 * across;
  spacing_m = kLengthM / (along - 1);
  return dc::gridBox(along, across, 2, spacing_m);
}

struct FoldFigures {
  double query_ms = std::numeric_limits<double>::infinity();
  dc::QueryCounters counters;
  std::size_t contacts = 0;
  std::size_t missed = 0;  ///< Peer pairs under no contact's leaves: must be 0.
  double peer_ms = std::numeric_limits<double>::infinity();
  std::size_t peer_pairs = 0;
};

class Collector final : public dc::ContactSink {
 public:
  void add(const dc::SphereContact& contact) override { contacts.push_back(contact); }
  std::vector<dc::SphereContact> contacts;
};

/// The pairs closer than `contact_m` and farther than `rest_m` at rest, from a kd-tree over
/// the points (float search, radius grown by a micrometre, the exact distance decides).
std::vector<std::pair<std::uint32_t, std::uint32_t>> kdTreePairs(const Points& x,
                                                                 const Points& rest,
                                                                 double contact_m, double rest_m) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) (*cloud)[i].getVector3fMap() = x[i].cast<float>();
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setSortedResults(false);
  tree.setInputCloud(cloud);
  std::vector<int> found;
  std::vector<float> squared;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (std::uint32_t i = 0; i < x.size(); ++i) {
    tree.radiusSearch((*cloud)[i], static_cast<float>(contact_m + 1e-6), found, squared);
    for (const int j : found) {
      const auto q = static_cast<std::uint32_t>(j);
      if (q > i && (x[i] - x[q]).squaredNorm() < contact_m * contact_m &&
          (rest[i] - rest[q]).squaredNorm() > rest_m * rest_m) {
        pairs.emplace_back(i, q);
      }
    }
  }
  return pairs;
}

/// Peer pairs whose points' leaves no contact joins.
std::size_t missedPairs(const dc::SphereTree& tree, const std::vector<dc::SphereContact>& contacts,
                        const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs) {
  std::vector<std::uint32_t> leaf_of(tree.body().pointCount());
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const dc::SphereNode& node = tree.node(n);
    if (!node.isLeaf()) continue;
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      leaf_of[tree.pointIndices()[s]] = n;
    }
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> joined;
  for (const auto& c : contacts)
    joined.insert({std::min(c.node_a, c.node_b), std::max(c.node_a, c.node_b)});
  std::size_t missed = 0;
  for (const auto& [p, q] : pairs) {
    const std::uint32_t a = leaf_of[p], b = leaf_of[q];
    missed += joined.count({std::min(a, b), std::max(a, b)}) == 0;
  }
  return missed;
}

FoldFigures folded(const Points& rest, int clusters, double contact_m, double rest_m, int repeats) {
  dc::ShapeMatchingConfig config;
  config.clusters = clusters;
  dc::ShapeMatchingBody body(rest, config);
  // The arms' inner faces half a contact distance apart.
  body.setPositions(dc::bentIntoU(rest, 0.5 * (contact_m + 0.5 * contact_m)));
  dc::SphereTree tree(body, {});
  const dc::RestSpheres rest_spheres(tree);
  dc::SelfCollisionQuery query;
  FoldFigures f;
  Collector sink;
  for (int r = 0; r < repeats; ++r) {
    sink.contacts.clear();
    f.counters = {};
    const auto start = db::Clock::now();
    tree.beginCycle();
    query.collide(tree, rest_spheres, -1, contact_m, rest_m, sink, f.counters);
    f.query_ms = std::min(f.query_ms, db::millisecondsSince(start));
  }
  f.contacts = sink.contacts.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (int r = 0; r < 3; ++r) {
    const auto start = db::Clock::now();
    pairs = kdTreePairs(body.positions(), rest, contact_m, rest_m);
    f.peer_ms = std::min(f.peer_ms, db::millisecondsSince(start));
  }
  f.peer_pairs = pairs.size();
  f.missed = missedPairs(tree, sink.contacts, pairs);
  return f;
}

/// The strip lying on a static floor, settled.
std::unique_ptr<dc::Scene> flatStrip(const Points& rest, int clusters, double contact_m,
                                     bool self_collision) {
  dc::SceneConfig config;
  config.contact_distance_m = contact_m;
  auto scene = std::make_unique<dc::Scene>(config);
  dc::ObjectConfig floor;
  floor.name = "floor";
  floor.kind = dc::ObjectKind::kStatic;
  Points floor_points = dc::gridBox(60, 20, 1, 0.01);
  for (auto& p : floor_points) p.z() -= 0.5 * contact_m + 0.002;
  scene->addObject(floor, floor_points);
  dc::ObjectConfig s;
  s.name = "strip";
  s.shape.clusters = clusters;
  s.self_collision = self_collision;
  Points lifted = rest;
  for (auto& p : lifted) p.z() += contact_m;
  scene->addObject(s, lifted);
  for (int c = 0; c < 50; ++c) scene->cycle();
  return scene;
}

/// The flat strip's whole cycle with self_collision off and on: blocks of 10 cycles of
/// each in turn, the median block of each, so that the host's drift falls on both alike.
std::pair<double, double> flatCyclesMs(const Points& rest, int clusters, double contact_m) {
  constexpr int kBlocks = 21;
  const std::unique_ptr<dc::Scene> scenes[2] = {flatStrip(rest, clusters, contact_m, false),
                                                flatStrip(rest, clusters, contact_m, true)};
  std::vector<double> blocks[2];
  for (int b = 0; b < kBlocks; ++b) {
    for (int k = 0; k < 2; ++k) {
      const auto start = db::Clock::now();
      for (int c = 0; c < 10; ++c) scenes[k]->cycle();
      blocks[k].push_back(db::millisecondsSince(start) / 10);
    }
  }
  for (auto& times : blocks)
    std::nth_element(times.begin(), times.begin() + kBlocks / 2, times.end());
  return {blocks[0][kBlocks / 2], blocks[1][kBlocks / 2]};
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_self_collision points clusters results_dir [repeats=10]\n");
    return 2;
  }
  const std::size_t points = std::strtoul(argv[1], nullptr, 10);
  const int clusters = std::atoi(argv[2]);
  const std::string results = argv[3];
  const int repeats = argc > 4 ? std::atoi(argv[4]) : 10;
  double spacing_m = 0.0;
  const Points rest = strip(points, spacing_m);
  // A contact distance of the point spacing, the rest distance at its default.
  const double contact_m = spacing_m;
  const double rest_m = dc::kSelfRestContactDistances * contact_m;
  const FoldFigures f = folded(rest, clusters, contact_m, rest_m, repeats);
  const auto [off_ms, on_ms] = flatCyclesMs(rest, clusters, contact_m);
  db::CsvAppender csv(results + "/self_collision.csv",
                      "points,clusters,contact_distance_m,self_query_ms,node_pairs,point_tests,"
                      "self_contacts,missed,kdtree_ms,kdtree_pairs,flat_cycle_off_ms,"
                      "flat_cycle_on_ms");
  std::fprintf(csv.file(), "%zu,%d,%.6f,%.4f,%zu,%zu,%zu,%zu,%.3f,%zu,%.4f,%.4f\n", rest.size(),
               clusters, contact_m, f.query_ms, f.counters.node_pairs_tested,
               f.counters.point_tests, f.contacts, f.missed, f.peer_ms, f.peer_pairs, off_ms,
               on_ms);
  std::printf(
      "S4 %zu points, %d clusters: self-query %.3f ms, %zu node pairs, %zu self-contacts (%zu "
      "missed); "
      "kd-tree %.2f ms, %zu pairs; flat strip cycle %.3f ms off, %.3f ms on\n",
      rest.size(), clusters, f.query_ms, f.counters.node_pairs_tested, f.contacts, f.missed,
      f.peer_ms, f.peer_pairs, off_ms, on_ms);
  return f.missed == 0 ? 0 : 1;
}
