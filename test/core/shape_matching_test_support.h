#pragma once
// What the ShapeMatchingBody tests share: point maps, centroids, configurations, a fixed
// rotation, and measures of how far the points are from their goals and rest shapes.

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {
namespace test {

using Points = std::vector<Eigen::Vector3d>;
using PointMap = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

inline Points mapped(const Points& points, const PointMap& map) {
  Points out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(map(p));
  return out;
}

inline Eigen::Vector3d centroid(const Points& points) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) sum += p;
  return sum / static_cast<double>(points.size());
}

inline ShapeMatchingConfig configFor(DeformationMode mode, int clusters) {
  ShapeMatchingConfig c;
  c.mode = mode;
  c.clusters = clusters;
  return c;
}

/// Largest |g_i - x_i| minus the cluster's bound, over all clusters: <= 0 when sound.
inline double worstBoundExcess(const ShapeMatchingBody& body) {
  double worst = -1.0;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto& deformation = body.deformation(k);
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Vector3d goal =
          deformation.transform * quadraticFeatures(cluster.rest_offsets[j]) +
          deformation.translation;
      const double gap = (goal - body.positions()[cluster.points[j]]).norm();
      worst = std::max(worst, gap - deformation.goal_deviation_bound_m);
    }
  }
  return worst;
}

/// RMS distance of the points from their clusters' rigidly moved rest positions.
inline double shapeError(const ShapeMatchingBody& body) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto& deformation = body.deformation(k);
    const Eigen::Matrix3d r = deformation.rotation.toRotationMatrix();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      sum += (body.positions()[cluster.points[j]] -
              (r * cluster.rest_offsets[j] + deformation.center_of_mass))
                 .squaredNorm();
      ++count;
    }
  }
  return std::sqrt(sum / count);
}

/// A turn about a skew axis, applied to the rest shapes of many tests.
inline const Eigen::Matrix3d kRotation =
    Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).matrix();

}  // namespace test
}  // namespace deformable_collision
