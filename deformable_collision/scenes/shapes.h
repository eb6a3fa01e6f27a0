#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// Deterministic synthetic point sets, shared by the demo, the benchmarks and the tests.
/// The same seed gives the same points on every platform (std::mt19937_64 and a
/// hand-written uniform mapping, not the implementation-defined distributions).

/// `count` points uniformly inside an axis-aligned box centred at the origin.
std::vector<Eigen::Vector3d> sampleBox(std::size_t count, const Eigen::Vector3d& half_extents_m,
                                       std::uint64_t seed);

/// `count` points uniformly inside an axis-aligned ellipsoid centred at the origin.
std::vector<Eigen::Vector3d> sampleEllipsoid(std::size_t count, const Eigen::Vector3d& radii_m,
                                             std::uint64_t seed);

/// A regular grid of `side` x `side` points `spacing_m` apart in x and y, in `layers` layers
/// as far apart below z = 0 (a floor's top at z = 0), centred on the z axis.
std::vector<Eigen::Vector3d> gridLayers(int side, int layers, double spacing_m);

/// `count` points on the surface of an axis-aligned ellipsoid centred at the origin, each moved
/// by up to `noise_m` along each axis: a closed surface as a scanner sees it.
std::vector<Eigen::Vector3d> sampleNoisySurface(std::size_t count, const Eigen::Vector3d& radii_m,
                                                double noise_m, std::uint64_t seed);

/// A box of nx x ny x nz points `spacing_m` apart along x, y and z, centred at the origin.
std::vector<Eigen::Vector3d> gridBox(int nx, int ny, int nz, double spacing_m);

/// A shape lying along x bent into a U in the xy-plane: its middle around a half circle of
/// centre-line radius `radius_m` (about x = 0), its two ends straight arms along -x, one
/// above the other; y across the shape runs along the bend's outward normal.
std::vector<Eigen::Vector3d> bentIntoU(const std::vector<Eigen::Vector3d>& points, double radius_m);

}  // namespace deformable_collision
