#include "deformable_collision/scenes/shapes.h"

#include <cmath>
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

std::vector<Eigen::Vector3d> gridBox(int nx, int ny, int nz, double spacing_m) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(nx) * ny * nz);
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        points.emplace_back((i - 0.5 * (nx - 1)) * spacing_m, (j - 0.5 * (ny - 1)) * spacing_m,
                            (k - 0.5 * (nz - 1)) * spacing_m);
      }
    }
  }
  return points;
}

std::vector<Eigen::Vector3d> bentIntoU(const std::vector<Eigen::Vector3d>& points,
                                       double radius_m) {
  const double half_arc_m = 0.5 * 3.14159265358979323846 * radius_m;
  std::vector<Eigen::Vector3d> bent;
  bent.reserve(points.size());
  for (const Eigen::Vector3d& p : points) {
    const double u = p.x();
    Eigen::Vector2d centre, outward;
    if (u < -half_arc_m) {
      centre = {u + half_arc_m, -radius_m};
      outward = {0.0, -1.0};
    } else if (u > half_arc_m) {
      centre = {half_arc_m - u, radius_m};
      outward = {0.0, 1.0};
    } else {
      outward = {std::cos(u / radius_m), std::sin(u / radius_m)};
      centre = radius_m * outward;
    }
    // Across the shape, y runs along the outward normal: a bend, not a tear.
    const Eigen::Vector2d in_plane = centre + p.y() * outward;
    bent.emplace_back(in_plane.x(), in_plane.y(), p.z());
  }
  return bent;
}

}  // namespace deformable_collision
