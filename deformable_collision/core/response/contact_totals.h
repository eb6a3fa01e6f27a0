#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_collision {

struct SceneContact;

/// What a controller reads of one touching object pair in one cycle.
struct PairSummary {
  std::uint32_t object_a = 0;
  std::uint32_t object_b = 0;
  std::size_t contacts = 0;
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();  ///< Mean of the contacts' positions.
  /// Unit, from b to a: the contacts' normals weighted by depth (the first contact's if
  /// they cancel).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double largest_depth_m = 0.0;
  Eigen::Vector3d force_n = Eigen::Vector3d::Zero();  ///< Total on a.
  /// How far force_n can be from the finest level's total: the contacts' shares of the
  /// indentation's error (0 for a pair with a dynamic object, whose total every level shares).
  double force_error_n = 0.0;
  /// The ellipse the contact positions spread over in the plane across `normal`: pi times
  /// twice each standard deviation (a disc or an ellipse of contacts gives its own area, a
  /// square 5% more). 0 for a single contact; the finest level's is the truest.
  double area_m2 = 0.0;
  double registration_error_m = 0.0;  ///< The largest of the contacts'.
};

/// One summary per object pair, in the order the pairs come in `contacts` (each pair's
/// contacts together, as a Scene lists them), into `summaries`.
void summarizePairs(const std::vector<SceneContact>& contacts, std::vector<PairSummary>& summaries);

/// Force and torque, in the frame they were asked in.
struct Wrench {
  Eigen::Vector3d force_n = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_nm = Eigen::Vector3d::Zero();
};

/// What a force-torque sensor at `frame` (its pose in the scene frame) reads of the contact
/// forces on `object`: their sum, and their moments about the frame's origin, both in the
/// frame's axes.
Wrench wrenchOn(const std::vector<SceneContact>& contacts, std::uint32_t object,
                const Eigen::Isometry3d& frame);

}  // namespace deformable_collision
