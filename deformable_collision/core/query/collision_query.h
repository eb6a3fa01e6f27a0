#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "deformable_collision/core/common/wide_vectors.h"
#include "deformable_collision/core/hierarchy/node_slabs.h"
#include "deformable_collision/core/hierarchy/sphere_tree.h"

namespace deformable_collision {

/// A contact between node `node_a` of object a and node `node_b` of object b.
struct SphereContact {
  static constexpr std::uint32_t kNoPoint = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t node_a = 0;
  std::uint32_t node_b = 0;
  std::uint16_t level = 0;  ///< The deeper of the two nodes' levels.
  /// Midway between the two surfaces (spheres, or the closest point pair at the leaves).
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Unit, from b to a.
  /// Overlap in metres with every sphere and point grown by contact_distance / 2;
  /// > 0 for every reported contact.
  double depth_m = 0.0;
  /// How far the contact can be from the truth of its two nodes' points, in metres: for
  /// every closest pair (x, y) of node_a's and node_b's points (their least distance D),
  /// |position - (x + y) / 2| <= error_bound_m and |depth_m - (contact distance - D)| <=
  /// error_bound_m. Above the leaves it follows from the spheres alone (every point lies in
  /// its node's sphere, docs/design.md, "Error bound of a contact"), a few radii at most;
  /// at the leaves it is 0: position is the midpoint of a closest pair and depth_m the
  /// contact distance minus its length, both exact.
  double error_bound_m = 0.0;
  std::uint32_t point_a = kNoPoint;  ///< Closest pair, at the leaf level only.
  std::uint32_t point_b = kNoPoint;
};

/// Takes a query's contacts one at a time, so that a caller can keep them in its own layout
/// (a scene tags each with its two objects) without copying them afterwards.
class ContactSink {
 public:
  /// One more contact, composed by the query before it is handed over: a default record
  /// filled in place would be cleared first, a store loop slower than the contact itself.
  virtual void add(const SphereContact& contact) = 0;

 protected:
  ~ContactSink() = default;
};

struct QueryCounters {
  std::size_t node_pairs_tested = 0;
  std::size_t leaf_pairs_tested = 0;  ///< Leaf pairs whose points were tested.
  std::size_t point_tests = 0;        ///< Point-sphere and point-point distance tests.
};

/// The slabs of the query's static and kinematic objects (NodeSlabs), or null: towards the
/// leaves they rule out node and leaf pairs whose spheres come within reach but whose points
/// cannot.
struct PairSlabs {
  NodeSlabs* a = nullptr;
  NodeSlabs* b = nullptr;

  /// Whether a slab proves node_a's points and node_b's at least `distance_m` apart.
  bool apart(std::uint32_t node_a, const Sphere& sphere_a, std::uint32_t node_b,
             const Sphere& sphere_b, double distance_m) const {
    return (a && a->apart(node_a, sphere_b, distance_m)) ||
           (b && b->apart(node_b, sphere_a, distance_m));
  }
};

/// Descends two sphere trees where their spheres come within the contact distance.
/// Holds its traversal stack so that repeated queries allocate nothing.
class HierarchyQuery {
 public:
  /// Tests leaves and points with vectors of up to `vectors` (the CPU's widest if it has
  /// not those): four or eight at once, finding the same contacts, bit for bit.
  explicit HierarchyQuery(VectorWidth vectors = widestVectors());

  /// Appends to `contacts` the node pairs of trees `a` and `b` at `level` (0: the roots;
  /// a node that is a leaf above `level` stands for itself) whose spheres come closer
  /// than `contact_distance_m`; such a contact's depth is the least overlap of its spheres
  /// and its ancestors' (grown by half the contact distance each). With `level` >= both
  /// trees' maxLevel() the query runs to the leaves and tests points: a leaf pair is a
  /// contact if and only if one of its point pairs is closer than `contact_distance_m`, so
  /// the contacts cover exactly the point pairs that brute force finds; there, nodes of up
  /// to eight leaves (buckets) test their leaves' spheres all against all rather than
  /// descending pair by pair; an object of up to eight buckets is not descended: its buckets
  /// are tested all at once against the other's (all of them if it is small too, else each
  /// bucket the descent reaches). Spheres are computed lazily (SphereTree::sphere); a bucket
  /// not yet measured is first tested with its bound (SphereTree::boundWithoutPoints), and
  /// its points are read only if that comes within reach. `slabs`, when given, must be
  /// those of the trees' current points; they prune only the descent to the leaves, whose
  /// contacts are the same with them or without.
  void collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
               ContactSink& contacts, QueryCounters& counters, const PairSlabs& slabs = {});
  /// collide() appending to a vector.
  void collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
               std::vector<SphereContact>& contacts, QueryCounters& counters,
               const PairSlabs& slabs = {});

 private:
  /// A node pair within reach, waiting to be visited.
  struct PendingPair {
    std::uint32_t node_a = 0;
    std::uint32_t node_b = 0;
    double least_overlap_m = 0.0;  ///< Above the leaves: see collide().
  };
  /// One query's state and the steps of its descent (collision_query.cpp).
  struct Descent;

  VectorWidth vectors_ = VectorWidth::kPortable;
  std::vector<PendingPair> stack_;
};

}  // namespace deformable_collision
