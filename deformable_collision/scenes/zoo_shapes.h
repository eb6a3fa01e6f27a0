#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// The registration zoo's objects, unlike each other on purpose: a rounded box, a smooth
/// convex fruit, a long curved tube, a thin plate with sharp edges, and a figure with
/// protrusions and concave joints.
enum class ZooShape { kSponge, kFruit, kBanana, kPlate, kToy };

inline constexpr std::array<ZooShape, 5> kZooShapes = {
    ZooShape::kSponge, ZooShape::kFruit, ZooShape::kBanana, ZooShape::kPlate, ZooShape::kToy};

const char* zooShapeName(ZooShape shape);

/// Samples spread uniformly at random over a closed surface, with its outward unit normals.
struct ZooSurface {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;
  double spacing_m = 0.0;  ///< sqrt(surface area / points): the samples' typical spacing.
};

/// `count` samples of `shape`, centred on their mean, its long axis along x and z up; 10 to
/// 25 cm long. The same seed gives the same samples on every platform.
/// @throw std::invalid_argument if `count` < 100.
ZooSurface zooShapeSurface(ZooShape shape, std::size_t count, std::uint64_t seed);

}  // namespace deformable_collision
