// Internal to the core: the object pair the response is resolving.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "deformable_collision/core/response/contact_response.h"
#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {

/// The object pair being resolved and what its steps find out.
struct ContactResponse::ResolvingPair {
  Object& a;
  Object& b;
  std::uint32_t index_a;
  std::uint32_t index_b;
  std::size_t run_begin;  ///< The pair's contacts: contacts_[run_begin, run_end).
  std::size_t run_end;
  bool one_side_fixed;  ///< One object is dynamic, the other never moves.
  bool leaves;          ///< One query found all the contacts, at the leaves or above them.
  /// The objects' moves by the pairs resolved before this one.
  Eigen::Vector3d translation_before_a;
  Eigen::Vector3d translation_before_b;
  Eigen::Vector3d side_of_a = Eigen::Vector3d::Zero();  ///< From b towards a, not unit.
  /// Between two dynamic objects: the normal of every push, from b to a.
  Eigen::Vector3d dynamic_normal = Eigen::Vector3d::Zero();
  /// The whole objects' moves for this pair.
  Eigen::Vector3d move_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d move_b = Eigen::Vector3d::Zero();
  /// The pushes' normals weighted by their depths: the pair's normal, not unit.
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  bool held = false;  ///< The two were in contact in the last cycle.
  /// Between dynamic objects: a push along the pair's normal would drive a (b, against the
  /// normal) into a fixed object that pushed it off in this response.
  bool a_against_fixed = false;
  bool b_against_fixed = false;
  std::uint32_t run = 0;  ///< Its contact run.
  ContactResponse::PairScratch* scratch = nullptr;
  std::uint64_t serial = 0;                         ///< Keys its dents.
  ContactResponse::PairOutcome* outcome = nullptr;  ///< Where its exchange and move go.
};

struct ContactResponse::FixedSurface {
  Eigen::Vector3d away;         ///< The node's plane normal, towards the dynamic object.
  Eigen::Vector3d plane_point;  ///< The node's sphere centre.
  double reach = 0.0;           ///< How far the object's surface lies from it along away.
};

/// The fixed object's touched nodes seen along `away` (from the fixed object towards the
/// dynamic one): the highest of their surfaces, and the region across `away` that their
/// spheres cover, where a point of the dynamic object lies in line with them.
struct ContactResponse::TouchedSurface {
  Eigen::Vector3d away;
  Eigen::Vector3d across_u;
  Eigen::Vector3d across_v;
  Eigen::AlignedBox2d in_line;
  double level = -std::numeric_limits<double>::infinity();

  bool inLine(const Eigen::Vector3d& point) const {
    return in_line.contains(Eigen::Vector2d(point.dot(across_u), point.dot(across_v)));
  }
};

}  // namespace deformable_collision
