// Internal to the core: an object of a Scene and its parts, shared by the files that
// implement the Scene (broad phase, response, dents, fixed planes). Not a public header.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "deformable_collision/core/node_slabs.h"
#include "deformable_collision/core/scene.h"

namespace deformable_collision {
namespace scene_internal {

/// The rest plane of every node of an object the response never moves (static or
/// kinematic). A node's own points may be too few to span a plane (a leaf of a two-layer
/// floor is a small cube), so it takes the normal of its nearest ancestor that is clearly
/// planar, or the root's. The plane is anchored at the node's sphere centre; its surfaces
/// are where the object reaches from there in line with the node, through gaps no wider
/// than the contact distance, within that ancestor: a point deep in a thick floor is as
/// deep as the floor's top above it, not as the small node it touches.
struct FixedPlanes {
  void compute(const ShapeMatchingBody& body, const SphereTree& tree, double gap_m);

  std::vector<Eigen::Vector3d> normals;  ///< Per node, in the rest shape.
  /// Per node: how far the object reaches from its sphere's centre along the normal and
  /// against it.
  std::vector<double> extent_along;
  std::vector<double> extent_against;
};

/// A change of every point's velocity by `velocity + spin x (x - center)`.
struct RigidVelocityChange {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d spin = Eigen::Vector3d::Zero();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};

/// The dents of a dynamic object: each contact node's push, kept until the object's move
/// over all its pairs is known, and the per-point sums they turn into.
struct DentScratch {
  static constexpr std::uint32_t kNoDepth = std::numeric_limits<std::uint32_t>::max();
  /// A contact node's dent by one partner.
  struct PendingDent {
    std::uint32_t node = 0;
    Eigen::Vector3d away = Eigen::Vector3d::UnitZ();  ///< Direction this object is pushed.
    std::uint32_t partner = 0;                         ///< The object it touches.
    /// Its contacts' depths in depths, a list from first_depth to last_depth.
    std::uint32_t first_depth = kNoDepth;
    std::uint32_t last_depth = kNoDepth;
    /// Each point goes to its contacts' surfaces (DentDepth::surface_m), not the whole node
    /// by its deepest point's depth.
    bool to_surface = false;
  };
  struct DentDepth {
    double depth_unmoved_m = 0.0;  ///< How far the node must go if the object did not move.
    /// For a dent to_surface: where along `away` its points are cleared to, unmoved.
    double surface_m = 0.0;
    std::uint32_t next = kNoDepth;
  };

  /// Sized once, so that no cycle allocates, even the first that dents every point.
  void reserve(std::size_t point_count, std::size_t node_count);
  /// Notes a contact's dent of `node`, pushed along `away` by `partner` in the pair resolved
  /// as `pair_serial`; with `surface_m`, each of the node's points only as far as it lies
  /// short of that level along `away` (every contact of a pair dents alike).
  void add(std::uint32_t node, const Eigen::Vector3d& away, double depth_unmoved_m,
           std::uint32_t partner, std::uint64_t pair_serial,
           std::optional<double> surface_m = std::nullopt);
  /// Turns the sums into one mean displacement per dented point (in displacements) and
  /// clears them.
  void averageDisplacements();
  /// Makes the dented points' velocity changes (in displacements) leave the object's momentum
  /// and angular momentum as they were, but for slowing its spin: returns the rigid change
  /// every point gives up for them (no point's faster than the fastest of them, its points
  /// lying within `reach_m` of the centre of mass) and adds it back to the dented points'.
  RigidVelocityChange balanceVelocityChanges(const std::vector<Eigen::Vector3d>& positions,
                                             const RigidMotion& motion, double point_mass_kg,
                                             double reach_m);

  std::vector<PendingDent> pending;
  std::vector<DentDepth> depths;
  /// Per node: its dent in `pending`, valid for the pair resolved as dent_pair_of_node.
  std::vector<std::uint32_t> dent_of_node;
  std::vector<std::uint64_t> dent_pair_of_node;
  // Changes summed per point, averaged when applied.
  std::vector<Eigen::Vector3d> displacement_sums;
  std::vector<Eigen::Vector3d> velocity_change_sums;
  std::vector<std::uint32_t> displacement_counts;
  std::vector<std::uint32_t> displaced_points;
  std::vector<PointDisplacement> displacements;
};

/// The side each partner touched this object from, kept while the contact lasts: an object
/// pushed past the middle of a thin wall must still be pushed back, not through.
struct ContactMemory {
  struct ContactSide {
    std::uint32_t partner = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Away from the partner.
    std::uint64_t cycle = 0;                             ///< Last cycle in contact.
  };

  /// The side last seen for `partner`, or nullptr.
  ContactSide* find(std::uint32_t partner);
  void remember(std::uint32_t partner, const Eigen::Vector3d& normal, std::uint64_t cycle);
  /// Forgets the partners not in contact in the cycle before `cycle`.
  void forgetBefore(std::uint64_t cycle);

  std::vector<ContactSide> sides;
};

}  // namespace scene_internal

struct Scene::Object {
  Object(const ObjectConfig& object_config, std::vector<Eigen::Vector3d> rest_points,
         const SphereTreeConfig& tree_config);

  bool dynamic() const { return config.kind == ObjectKind::kDynamic; }

  /// Dents the pending nodes by what their contacts need beyond the object's move, once
  /// every pair has added to that move.
  void applyPendingDents(const std::vector<std::unique_ptr<Object>>& objects);

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
  /// phase: around the root sphere, or, for a static object, its points' own box once.
  Eigen::AlignedBox3d sweep_box;
  std::vector<Eigen::Vector3d> posed_points;  ///< Kinematic objects: the rest shape posed.

  scene_internal::FixedPlanes planes;  ///< Objects the response never moves.
  /// Static and kinematic objects, whose nodes' points move only rigidly: the slabs of
  /// their points now, and a kinematic object's of its rest shape, which each pose moves.
  NodeSlabs slabs;
  NodeSlabs rest_slabs;
  scene_internal::DentScratch dents;   ///< Dynamic objects.
  scene_internal::ContactMemory contact_memory;
  /// Tracked objects fitted to unordered clouds: made on the first such cloud.
  std::optional<CloudRegistration> registration;

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
  /// Objects in contact: mean velocity once velocity_change is applied.
  Eigen::Vector3d velocity_after = Eigen::Vector3d::Zero();
};

/// The object pair being resolved and what its steps find out.
struct Scene::ResolvingPair {
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
};

}  // namespace deformable_collision
