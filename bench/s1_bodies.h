// S1's two deforming bodies, shared by bench_collision (contacts) and bench_distance.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision::bench {

struct S1Bodies {
  ShapeMatchingBody a;
  ShapeMatchingBody b;
};

/// Bends a ball about its centre line x = center_x, so that shape matching has work to do.
inline void bend(ShapeMatchingBody& body, double center_x) {
  auto bent = body.restPositions();
  for (auto& p : bent) p.z() += 0.05 * (p.y() * p.y() - (p.x() - center_x) * (p.x() - center_x));
  body.setPositions(bent);
}

/// Two quadratic balls of radius 0.5 m and `each` points (4 clusters, stiffness 0.3), b's
/// centre `separation_m` from a's along x, both released from a bend. S1 presses them 2 cm
/// into each other (0.98 m).
inline S1Bodies makeS1Bodies(std::size_t each, double separation_m) {
  ShapeMatchingConfig config;
  config.mode = DeformationMode::kQuadratic;
  config.clusters = 4;
  config.stiffness = 0.3;
  std::vector<Eigen::Vector3d> rest_b = sampleEllipsoid(each, {0.5, 0.5, 0.5}, 2);
  for (auto& p : rest_b) p.x() += separation_m;
  S1Bodies bodies{ShapeMatchingBody(sampleEllipsoid(each, {0.5, 0.5, 0.5}, 1), config),
                  ShapeMatchingBody(rest_b, config)};
  bend(bodies.a, 0.0);
  bend(bodies.b, separation_m);
  return bodies;
}

}  // namespace deformable_collision::bench
