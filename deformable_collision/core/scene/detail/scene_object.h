// Internal to the core: an object of a Scene, with what the broad phase, the query and the
// response keep of it. Not installed.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "deformable_collision/core/hierarchy/node_slabs.h"
#include "deformable_collision/core/query/self_collision_query.h"
#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/registration/near_points_filter.h"
#include "deformable_collision/core/response/detail/contact_memory.h"
#include "deformable_collision/core/response/detail/dent_scratch.h"
#include "deformable_collision/core/response/detail/fixed_planes.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace detail {

/// An object of a Scene: its configuration, body and hierarchy, and what the broad phase
/// and the response keep of it between and within cycles.
struct SceneObject {
  SceneObject(const ObjectConfig& object_config, std::vector<Eigen::Vector3d> rest_points,
              const SphereTreeConfig& tree_config);
  // The tree, the slabs and the planes point into the object itself.
  SceneObject(const SceneObject&) = delete;
  SceneObject& operator=(const SceneObject&) = delete;

  bool dynamic() const { return config.kind == ObjectKind::kDynamic; }

  ObjectConfig config;
  ShapeMatchingBody body;
  SphereTree tree;
  bool stale = false;  ///< Moved since its tree's spheres were last invalidated.
  /// Scene-wide number of the last restart of its tree (Scene::restartTree), new for every
  /// object made; numbers only grow, so an object numbered after a detection changed since.
  std::uint64_t revision = 0;
  /// Process-wide number of its rest shape, new for every object made: a tracked fit
  /// (TrackedFit::rest_shape) is taken only by the rest shape it was fitted to.
  std::uint64_t rest_shape = 0;
  /// Box around the object's points, grown by half the contact distance, for the broad
  /// phase: around the root sphere, or, for a static object, around points_box.
  Eigen::AlignedBox3d sweep_box;
  Eigen::AlignedBox3d points_box;             ///< Static objects: their points' box, set when made.
  std::vector<Eigen::Vector3d> posed_points;  ///< Kinematic objects: the rest shape posed.

  std::optional<FixedPlanes> planes;  ///< Objects the response never moves.
  /// Static and kinematic objects, whose nodes' points move only rigidly: the slabs of
  /// their points now, and a kinematic object's of its rest shape, which each pose moves.
  NodeSlabs slabs;
  NodeSlabs rest_slabs;
  DentScratch dents;  ///< Dynamic objects.
  /// Objects with self_collision: the rest spheres their self-contacts are told by.
  std::optional<RestSpheres> rest_spheres;
  ContactMemory contact_memory;
  /// Tracked objects fitted to unordered clouds: made on the first such cloud.
  std::optional<CloudRegistration> registration;
  /// What its registration leaves out: the others' points near it (Scene::pointsNearObject).
  NearPointsFilter near_points;
  /// The last registered cloud's estimate of the model's error: how far its contacts and
  /// indentations may be off the real object's (zero for an object never registered).
  SurfaceError registration_error;

  /// Dynamic objects: their centre of mass before this cycle's step, where a new contact's
  /// side is seen from (a long step may carry the centre past a thin floor). Taken from the
  /// clusters' centres: the points' mean read every point of every object each cycle.
  Eigen::Vector3d center_before_step = Eigen::Vector3d::Zero();
  /// Contacts between this object and a fixed one, counted in hops over touching objects
  /// (0: fixed itself); unsupported objects have the largest value.
  std::uint32_t support_depth = 0;
  // The whole object's move in this response, summed over its pairs.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_change = Eigen::Vector3d::Zero();
  /// Objects in contact: the body's mean velocity as the response found it (zero for objects
  /// the response never moves). Nothing changes it before applyObjectResponse, and the pairs
  /// and the velocity passes read it many times, each read a sum over the clusters.
  Eigen::Vector3d mean_velocity = Eigen::Vector3d::Zero();
  /// The response (Scene's cycle count) mean_velocity was read for: once per object, however
  /// many pairs it is in.
  std::uint64_t mean_velocity_cycle = 0;
  /// Dynamic objects: the momentum the pairs gave it where it acted as fixed (shock
  /// propagation), which its velocity never took; its supports carry it (contact forces).
  Eigen::Vector3d carried_impulse = Eigen::Vector3d::Zero();
  /// Dynamic objects: the size of the momentum its supports gave it, over all of them, and
  /// how many they are: how the carried momentum is shared among them.
  double support_impulse = 0.0;
  std::uint32_t supports = 0;
  /// Objects in contact: mean velocity once velocity_change is applied.
  Eigen::Vector3d velocity_after = Eigen::Vector3d::Zero();
};

}  // namespace detail
}  // namespace deformable_collision
