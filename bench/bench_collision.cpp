// Collision stage of two quadratic objects touching at a patch, per step, with three ways
// of getting the spheres, all on the same deforming points in the same run:
//   deformation  - spheres from the shape-matching matrices, lazily (the paper's update)
//   exact_refit  - smallest enclosing sphere of the current points of each visited node
//   bottom_up    - every node refitted bottom-up, then the same query
// Usage: bench_collision [points_per_object=80000] [steps=20]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "deformable_collision/core/collision_query.h"
#include "deformable_collision/core/shapes.h"

namespace dc = deformable_collision;

namespace {

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

struct MethodTotals {
  double update_ms = 0.0;  // bottom-up: the refit alone
  double stage_ms = 0.0;   // update + query to the leaves
  std::size_t spheres_updated = 0;
  std::size_t max_spheres_updated = 0;
  std::size_t contacts = 0;
};

std::vector<Eigen::Vector3d> shifted(std::vector<Eigen::Vector3d> points, const Eigen::Vector3d& by) {
  for (auto& p : points) p += by;
  return points;
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t points = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 80000;
  const int steps = argc > 2 ? std::atoi(argv[2]) : 20;
  const double contact_distance_m = 0.005;

  dc::ShapeMatchingConfig config;
  config.mode = dc::DeformationMode::kQuadratic;
  config.clusters = 4;
  config.stiffness = 0.3;
  // Two balls of radius 0.5 m pressed 2 cm into each other, both released from a bend.
  dc::ShapeMatchingBody a(dc::sampleEllipsoid(points, {0.5, 0.5, 0.5}, 1), config);
  dc::ShapeMatchingBody b(shifted(dc::sampleEllipsoid(points, {0.5, 0.5, 0.5}, 2), {0.98, 0, 0}),
                          config);
  for (dc::ShapeMatchingBody* body : {&a, &b}) {
    auto bent = body->restPositions();
    const double center_x = body == &a ? 0.0 : 0.98;
    for (auto& p : bent) p.z() += 0.05 * (p.y() * p.y() - (p.x() - center_x) * (p.x() - center_x));
    body->setPositions(bent);
  }
  const dc::SphereTreeConfig tree_config{2, 8};
  dc::SphereTree deformation_a(a, tree_config), deformation_b(b, tree_config);
  dc::SphereTree exact_a(a, tree_config), exact_b(b, tree_config);
  dc::SphereTree bottom_up_a(a, tree_config), bottom_up_b(b, tree_config);
  dc::HierarchyQuery query;
  std::vector<dc::SphereContact> contacts;
  contacts.reserve(1 << 16);

  const auto run = [&](dc::SphereTree& ta, dc::SphereTree& tb, dc::SphereUpdate method,
                       MethodTotals& totals) {
    contacts.clear();
    dc::QueryCounters counters;
    const auto start = Clock::now();
    ta.beginCycle(method);
    tb.beginCycle(method);
    totals.update_ms += method == dc::SphereUpdate::kBottomUpRefit ? millisecondsSince(start) : 0.0;
    query.collide(ta, tb, 1000, contact_distance_m, contacts, counters);
    totals.stage_ms += millisecondsSince(start);
    const std::size_t updated = ta.counters().spheres_updated + tb.counters().spheres_updated;
    totals.spheres_updated += updated;
    totals.max_spheres_updated = std::max(totals.max_spheres_updated, updated);
    totals.contacts += contacts.size();
  };

  MethodTotals deformation, exact, bottom_up;
  for (int s = 0; s < steps; ++s) {
    a.step(0.01, Eigen::Vector3d::Zero());
    b.step(0.01, Eigen::Vector3d::Zero());
    run(deformation_a, deformation_b, dc::SphereUpdate::kDeformation, deformation);
    run(exact_a, exact_b, dc::SphereUpdate::kExactRefit, exact);
    run(bottom_up_a, bottom_up_b, dc::SphereUpdate::kBottomUpRefit, bottom_up);
  }

  const std::size_t nodes = deformation_a.nodeCount() + deformation_b.nodeCount();
  std::printf("two quadratic objects of %zu points (%zu nodes in both trees), %d steps, "
              "contact distance %.3f m\n\n",
              points, nodes, steps, contact_distance_m);
  std::printf("| method | stage ms/step | of bottom-up refit | spheres updated/step | max | "
              "leaf contacts/step |\n|---|---|---|---|---|---|\n");
  const auto row = [&](const char* name, const MethodTotals& t) {
    std::printf("| %s | %.3f | %.3f | %.0f | %zu | %.0f |\n", name, t.stage_ms / steps,
                t.stage_ms / bottom_up.update_ms, double(t.spheres_updated) / steps,
                t.max_spheres_updated, double(t.contacts) / steps);
  };
  row("deformation", deformation);
  row("exact_refit", exact);
  row("bottom_up", bottom_up);
  std::printf("\nbottom-up refit alone: %.3f ms/step\n", bottom_up.update_ms / steps);
  std::printf("deformation stage / bottom-up refit: %.3f (target <= 0.10)\n",
              deformation.stage_ms / bottom_up.update_ms);
  std::printf("spheres updated, deformation / exact refit: %.3f (target <= 1.05)\n",
              double(deformation.spheres_updated) / double(exact.spheres_updated));
  return 0;
}
