#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// How densely a surface is sampled: every point of the surface lies within `spacing_m` of a
/// sample, and a shape that would take more than `max_points` samples is refused before any
/// is made.
struct SurfaceSampling {
  double spacing_m = 0.005;
  std::size_t max_points = 1000000;
};

/// A triangle mesh in metres: each triangle holds three indices into `vertices`.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

// Each function below samples the surface only, never the inside: a shape's inside cannot
// touch anything before its surface does. Samples are deterministic (no randomness), in the
// shape's own frame, and lie on the surface to rounding.

/// The surface of a box of edge lengths `size_m` centred at the origin, axis-aligned: the
/// points of a lattice with steps of at most spacing_m along each axis that lie on its faces,
/// each once.
/// @throw std::invalid_argument if spacing_m or a size is not finite and > 0.
/// @throw std::length_error if it would take more than max_points points.
std::vector<Eigen::Vector3d> sampleBoxSurface(const Eigen::Vector3d& size_m,
                                              const SurfaceSampling& sampling);

/// The surface of a cylinder along z, centred at the origin (URDF's convention): rings at
/// most spacing_m apart along its side, each with points at most spacing_m apart, and
/// concentric rings on both caps.
/// @throw std::invalid_argument if spacing_m, the radius or the length is not finite and > 0.
/// @throw std::length_error if it would take more than max_points points.
std::vector<Eigen::Vector3d> sampleCylinderSurface(double radius_m, double length_m,
                                                   const SurfaceSampling& sampling);

/// The surface of a sphere centred at the origin: latitude rings at most spacing_m apart
/// along a meridian, each with points at most spacing_m apart, and both poles.
/// @throw std::invalid_argument if spacing_m or the radius is not finite and > 0.
/// @throw std::length_error if it would take more than max_points points.
std::vector<Eigen::Vector3d> sampleSphereSurface(double radius_m, const SurfaceSampling& sampling);

/// The surface of a triangle mesh: each triangle in rows parallel to its longest edge, at most
/// sqrt(3)/2 spacing_m apart, each row with points at most spacing_m apart, from the longest
/// edge to the opposite corner; thin and large triangles alike. Points that several triangles
/// make alike (shared corners) are kept once, in the order first made.
/// @throw std::invalid_argument if spacing_m is not finite and > 0, the mesh has no triangle,
/// a vertex is not finite or an index is out of range.
/// @throw std::length_error if it would take more than max_points points.
std::vector<Eigen::Vector3d> sampleMeshSurface(const TriangleMesh& mesh,
                                               const SurfaceSampling& sampling);

}  // namespace deformable_collision
