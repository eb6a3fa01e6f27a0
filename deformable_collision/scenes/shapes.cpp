#include "deformable_collision/scenes/shapes.h"

#include <random>

namespace deformable_collision {
namespace {

/// Uniform in [-1, 1) from the top 53 bits, identical on every standard library.
double symmetricUnit(std::mt19937_64& engine) {
  return static_cast<double>(engine() >> 11) * 0x1.0p-52 - 1.0;
}

}  // namespace

std::vector<Eigen::Vector3d> sampleBox(std::size_t count, const Eigen::Vector3d& half_extents_m,
                                       std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::vector<Eigen::Vector3d> points(count);
  for (auto& p : points) {
    const Eigen::Vector3d u(symmetricUnit(engine), symmetricUnit(engine), symmetricUnit(engine));
    p = u.cwiseProduct(half_extents_m);
  }
  return points;
}

std::vector<Eigen::Vector3d> sampleEllipsoid(std::size_t count, const Eigen::Vector3d& radii_m,
                                             std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::vector<Eigen::Vector3d> points;
  points.reserve(count);
  while (points.size() < count) {
    const Eigen::Vector3d u(symmetricUnit(engine), symmetricUnit(engine), symmetricUnit(engine));
    if (u.squaredNorm() <= 1.0) points.push_back(u.cwiseProduct(radii_m));
  }
  return points;
}

std::vector<Eigen::Vector3d> gridLayers(int side, int layers, double spacing_m) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(side) * side * layers);
  const double half = 0.5 * (side - 1) * spacing_m;
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) {
      for (int k = 0; k < layers; ++k) {
        points.emplace_back(i * spacing_m - half, j * spacing_m - half, -k * spacing_m);
      }
    }
  }
  return points;
}

std::vector<Eigen::Vector3d> sampleNoisySurface(std::size_t count, const Eigen::Vector3d& radii_m,
                                                double noise_m, std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::vector<Eigen::Vector3d> points;
  points.reserve(count);
  while (points.size() < count) {
    // Directions uniform in the ball, projected onto the sphere; the centre's few are skipped.
    const Eigen::Vector3d u(symmetricUnit(engine), symmetricUnit(engine), symmetricUnit(engine));
    const double length = u.norm();
    if (length > 1.0 || length < 1e-3) continue;
    const Eigen::Vector3d noise(symmetricUnit(engine), symmetricUnit(engine),
                                symmetricUnit(engine));
    points.push_back((u / length).cwiseProduct(radii_m) + noise_m * noise);
  }
  return points;
}

}  // namespace deformable_collision
