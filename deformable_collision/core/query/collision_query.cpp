#include "deformable_collision/core/query/collision_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "deformable_collision/core/query/detail/collision_query_kernels.h"
#include "deformable_collision/core/query/detail/node_contact.h"

namespace deformable_collision {
namespace {

/// A leaf's points as coordinate arrays: its columns of the tree's leafPositions().
struct LeafPoints {
  std::uint32_t first_slot;
  std::uint32_t count;
  const double* x;
  const double* y;
  const double* z;
};

[[gnu::always_inline]] inline LeafPoints leafPoints(const SphereTree& tree, std::uint32_t leaf) {
  const std::uint32_t first = tree.leafSlotStarts()[leaf];
  const std::uint32_t count = tree.leafSlotStarts()[leaf + 1] - first;
  const auto& positions = tree.leafPositions();
  return {first, count, &positions(0, first), &positions(1, first), &positions(2, first)};
}

/// The closest point pair of two leaves as offsets into their points: the first point of a
/// at the least distance, and the first point of b at that distance from it.
struct ClosestPair {
  double squared_distance;
  std::uint32_t offset_a;
  std::uint32_t offset_b;
};

#if defined(__GNUC__) && defined(__x86_64__)
/// Whether a pair of the leaves' points is closer than `pair.squared_distance`, and then
/// the closest in `pair`: all pairs at once, eight of b's points per instruction.
[[gnu::always_inline]] inline bool closestPairAllAtOnce(const LeafPoints& a, const LeafPoints& b,
                                                        ClosestPair& pair,
                                                        QueryCounters& counters) {
  counters.point_tests += a.count * b.count;
  if (b.count <= 8) {
    return closestPairOfEightAvx512(a.x, a.y, a.z, a.count, b.x, b.y, b.z, b.count,
                                    pair.squared_distance, pair.squared_distance, pair.offset_a,
                                    pair.offset_b);
  }
  if (!nearestPairSquaredDistanceAvx512(a.x, a.y, a.z, a.count, b.x, b.y, b.z, b.count,
                                        pair.squared_distance, pair.squared_distance)) {
    return false;
  }
  firstPairAtAvx512(a.x, a.y, a.z, a.count, b.x, b.y, b.z, b.count, pair.squared_distance,
                    pair.offset_a, pair.offset_b);
  return true;
}
#endif

/// Offset of the first of b's points nearest to (x, y, z).
[[gnu::always_inline]] inline std::uint32_t firstNearest(const LeafPoints& b, double x, double y,
                                                         double z) {
  double nearest = std::numeric_limits<double>::infinity();
  std::uint32_t first = 0;
  for (std::uint32_t t = 0; t < b.count; ++t) {
    const double dx = x - b.x[t], dy = y - b.y[t], dz = z - b.z[t];
    const double distance_squared = dx * dx + dy * dy + dz * dz;
    if (distance_squared < nearest) {
      nearest = distance_squared;
      first = t;
    }
  }
  return first;
}

/// closestPairAllAtOnce without wide vectors: only the points of a within `reach_m` (b's
/// leaf radius plus the contact distance) of b's leaf centre are tested against all of b's.
[[gnu::always_inline]] inline bool closestPairNearSphere(const LeafPoints& a, const LeafPoints& b,
                                                         const Eigen::Vector3d& center_b,
                                                         double reach_m, ClosestPair& pair,
                                                         QueryCounters& counters) {
  counters.point_tests += a.count;
  for (std::uint32_t s = 0; s < a.count; ++s) {
    const Eigen::Vector3d point(a.x[s], a.y[s], a.z[s]);
    if ((point - center_b).squaredNorm() >= reach_m * reach_m) continue;
    counters.point_tests += b.count;
    const double nearest = nearestSquaredDistance(b.x, b.y, b.z, b.count, a.x[s], a.y[s], a.z[s]);
    if (nearest < pair.squared_distance) {
      pair.squared_distance = nearest;
      pair.offset_a = s;
    }
  }
  if (pair.offset_a == a.count) return false;
  pair.offset_b = firstNearest(b, a.x[pair.offset_a], a.y[pair.offset_a], a.z[pair.offset_a]);
  return true;
}

/// Records the contact of two leaves at their closest pair, closer than the contact distance.
[[gnu::always_inline]] inline void addLeafContact(const SphereTree& a, std::uint32_t leaf_a,
                                                  const LeafPoints& points_a, const SphereTree& b,
                                                  std::uint32_t leaf_b, const LeafPoints& points_b,
                                                  const ClosestPair& pair,
                                                  double contact_distance_m,
                                                  ContactSink& contacts) {
  SphereContact contact;
  contact.node_a = a.leafNode(leaf_a);
  contact.node_b = b.leafNode(leaf_b);
  contact.level = std::max(a.leafLevel(leaf_a), b.leafLevel(leaf_b));
  contact.point_a = a.pointIndices()[points_a.first_slot + pair.offset_a];
  contact.point_b = b.pointIndices()[points_b.first_slot + pair.offset_b];
  const std::uint32_t s = pair.offset_a;
  const std::uint32_t t = pair.offset_b;
  const Eigen::Vector3d x(points_a.x[s], points_a.y[s], points_a.z[s]);
  const Eigen::Vector3d y(points_b.x[t], points_b.y[t], points_b.z[t]);
  contact.position = 0.5 * (x + y);
  // The kernels sum the squared distance as Eigen's squaredNorm() does, so its root is
  // (x - y).norm() to the bit: one root for both the normal and the depth.
  const double distance_m = std::sqrt(pair.squared_distance);
  contact.normal =
      distance_m > 0.0 ? Eigen::Vector3d((x - y) / distance_m) : Eigen::Vector3d::UnitZ();
  contact.depth_m = contact_distance_m - distance_m;
  // Position and depth are those of a closest pair itself.
  contact.error_bound_m = 0.0;
  contacts.add(contact);
}

/// Adds the contact of the leaves at `leaf_a` and `leaf_b` in the trees' leaf orders if a
/// point pair is closer than the contact distance, at their closest pair. Both leaves must
/// be current.
template <VectorWidth Width>
[[gnu::always_inline]] inline void closestLeafPair(const SphereTree& a, std::uint32_t leaf_a,
                                                   const SphereTree& b, std::uint32_t leaf_b,
                                                   double contact_distance_m, ContactSink& contacts,
                                                   QueryCounters& counters) {
  ++counters.leaf_pairs_tested;
  const LeafPoints points_a = leafPoints(a, leaf_a);
  const LeafPoints points_b = leafPoints(b, leaf_b);
  ClosestPair pair{contact_distance_m * contact_distance_m, points_a.count, 0};
#if defined(__GNUC__) && defined(__x86_64__)
  if constexpr (Width == VectorWidth::kAvx512) {
    if (!closestPairAllAtOnce(points_a, points_b, pair, counters)) return;
  } else if (Width == VectorWidth::kAvx2 && points_b.count <= 8) {
    // Larger leaves (a tree of leaf_size > 8) take the portable test below.
    if (!closestPairOfEightAvx2(points_a.x, points_a.y, points_a.z, points_a.count, points_b.x,
                                points_b.y, points_b.z, points_b.count, pair.squared_distance,
                                pair.squared_distance, pair.offset_a, pair.offset_b,
                                counters.point_tests)) {
      return;
    }
  } else
#endif
  {
    const LeafSpheres& spheres_b = b.leafSpheres();
    const Eigen::Vector3d center_b(spheres_b.x[leaf_b], spheres_b.y[leaf_b], spheres_b.z[leaf_b]);
    const double reach_m = spheres_b.radius[leaf_b] + contact_distance_m;
    if (!closestPairNearSphere(points_a, points_b, center_b, reach_m, pair, counters)) return;
  }
  addLeafContact(a, leaf_a, points_a, b, leaf_b, points_b, pair, contact_distance_m, contacts);
}

[[gnu::always_inline]] inline Sphere leafSphere(const LeafSpheres& spheres, std::uint32_t leaf) {
  return {Eigen::Vector3d(spheres.x[leaf], spheres.y[leaf], spheres.z[leaf]), spheres.radius[leaf]};
}

/// Leaves under a node at which the descent to the leaves stops: their spheres are then
/// tested all against all, eight at a time, instead of pair by pair down the last levels.
constexpr std::uint32_t kBucketLeaves = SphereTree::kBucketLeaves;
static_assert(kBucketLeaves * kBucketLeaves <= 64, "a bucket pair's leaf pairs are one mask");

/// The leaf contacts of two nodes of at most kBucketLeaves leaves each, every leaf sphere
/// of one against every leaf sphere of the other. Both nodes' leaves must be current.
template <VectorWidth Width>
[[gnu::always_inline]] inline void collideBuckets(const SphereTree& a, const NodeState& bucket_a,
                                                  const SphereTree& b, const NodeState& bucket_b,
                                                  double contact_distance_m, const PairSlabs& slabs,
                                                  ContactSink& contacts, QueryCounters& counters) {
  counters.node_pairs_tested += bucket_a.leaf_count * bucket_b.leaf_count;
  const LeafSpheres& spheres_a = a.leafSpheres();
  const LeafSpheres& spheres_b = b.leafSpheres();
  const std::uint32_t first_a = bucket_a.first_leaf;
  const std::uint32_t first_b = bucket_b.first_leaf;
  // The pairs in reach, bit 8 k + j for leaf k of a and leaf j of b: one loop over them
  // all rather than one per leaf of a, whose ends a branch predictor cannot foresee.
  std::uint64_t within_reach = 0;
  for (std::uint32_t k = 0; k < bucket_a.leaf_count; ++k) {
    within_reach |=
        static_cast<std::uint64_t>(reachMask<Width>(
            spheres_a.x[first_a + k], spheres_a.y[first_a + k], spheres_a.z[first_a + k],
            spheres_a.radius[first_a + k] + contact_distance_m, &spheres_b.x[first_b],
            &spheres_b.y[first_b], &spheres_b.z[first_b], &spheres_b.radius[first_b],
            bucket_b.leaf_count))
        << (8 * k);
  }
  while (within_reach != 0) {
    const auto bit = static_cast<std::uint32_t>(__builtin_ctzll(within_reach));
    within_reach &= within_reach - 1;
    const std::uint32_t leaf_a = first_a + (bit >> 3);
    const std::uint32_t leaf_b = first_b + (bit & 7);
    if ((slabs.a || slabs.b) &&
        slabs.apart(a.leafNode(leaf_a), leafSphere(spheres_a, leaf_a), b.leafNode(leaf_b),
                    leafSphere(spheres_b, leaf_b), contact_distance_m)) {
      continue;
    }
    closestLeafPair<Width>(a, leaf_a, b, leaf_b, contact_distance_m, contacts, counters);
  }
}

/// collideBuckets compiled for each vector width, its kernels inlined into it.
#if defined(__GNUC__) && defined(__x86_64__)
__attribute__((target("avx512f"), flatten)) void collideBucketsAvx512(
    const SphereTree& a, const NodeState& bucket_a, const SphereTree& b, const NodeState& bucket_b,
    double contact_distance_m, const PairSlabs& slabs, ContactSink& contacts,
    QueryCounters& counters) {
  collideBuckets<VectorWidth::kAvx512>(a, bucket_a, b, bucket_b, contact_distance_m, slabs,
                                       contacts, counters);
}

__attribute__((target("avx2"), flatten)) void collideBucketsAvx2(
    const SphereTree& a, const NodeState& bucket_a, const SphereTree& b, const NodeState& bucket_b,
    double contact_distance_m, const PairSlabs& slabs, ContactSink& contacts,
    QueryCounters& counters) {
  collideBuckets<VectorWidth::kAvx2>(a, bucket_a, b, bucket_b, contact_distance_m, slabs, contacts,
                                     counters);
}
#endif

void collideBucketsPortable(const SphereTree& a, const NodeState& bucket_a, const SphereTree& b,
                            const NodeState& bucket_b, double contact_distance_m,
                            const PairSlabs& slabs, ContactSink& contacts,
                            QueryCounters& counters) {
  collideBuckets<VectorWidth::kPortable>(a, bucket_a, b, bucket_b, contact_distance_m, slabs,
                                         contacts, counters);
}

/// The leaf contacts of two sets of at most kBucketLeaves buckets each, every bucket of one
/// against every bucket of the other at once: all the buckets of a small object (one of at
/// most kBucketLeaves buckets) rather than pair by pair down the levels above them. A small
/// object in reach of another has most of its buckets in reach too (a pile), and costs at
/// most kBucketLeaves buckets however its contacts lie.
template <VectorWidth Width>
[[gnu::always_inline]] inline void collideBucketSets(
    SphereTree& a, const std::uint32_t* buckets_a, std::uint32_t count_a, SphereTree& b,
    const std::uint32_t* buckets_b, std::uint32_t count_b, double contact_distance_m,
    const PairSlabs& slabs, ContactSink& contacts, QueryCounters& counters) {
  double x[kBucketLeaves], y[kBucketLeaves], z[kBucketLeaves], radius[kBucketLeaves];
  for (std::uint32_t j = 0; j < count_b; ++j) {
    const Sphere& sphere = b.current(buckets_b[j], kBucketLeaves).sphere;
    x[j] = sphere.center.x();
    y[j] = sphere.center.y();
    z[j] = sphere.center.z();
    radius[j] = sphere.radius;
  }
  counters.node_pairs_tested += count_a * count_b;
  for (std::uint32_t k = 0; k < count_a; ++k) {
    const NodeState& bucket_a = a.current(buckets_a[k], kBucketLeaves);
    const Sphere& sphere = bucket_a.sphere;
    std::uint32_t within_reach =
        reachMask<Width>(sphere.center.x(), sphere.center.y(), sphere.center.z(),
                         sphere.radius + contact_distance_m, x, y, z, radius, count_b);
    while (within_reach != 0) {
      const auto j = static_cast<std::uint32_t>(__builtin_ctz(within_reach));
      within_reach &= within_reach - 1;
      const NodeState& bucket_b = b.current(buckets_b[j], kBucketLeaves);
      if ((slabs.a || slabs.b) &&
          slabs.apart(buckets_a[k], sphere, buckets_b[j], bucket_b.sphere, contact_distance_m)) {
        continue;
      }
      collideBuckets<Width>(a, bucket_a, b, bucket_b, contact_distance_m, slabs, contacts,
                            counters);
    }
  }
}

#if defined(__GNUC__) && defined(__x86_64__)
__attribute__((target("avx512f"), flatten)) void collideBucketSetsAvx512(
    SphereTree& a, const std::uint32_t* buckets_a, std::uint32_t count_a, SphereTree& b,
    const std::uint32_t* buckets_b, std::uint32_t count_b, double contact_distance_m,
    const PairSlabs& slabs, ContactSink& contacts, QueryCounters& counters) {
  collideBucketSets<VectorWidth::kAvx512>(a, buckets_a, count_a, b, buckets_b, count_b,
                                          contact_distance_m, slabs, contacts, counters);
}

__attribute__((target("avx2"), flatten)) void collideBucketSetsAvx2(
    SphereTree& a, const std::uint32_t* buckets_a, std::uint32_t count_a, SphereTree& b,
    const std::uint32_t* buckets_b, std::uint32_t count_b, double contact_distance_m,
    const PairSlabs& slabs, ContactSink& contacts, QueryCounters& counters) {
  collideBucketSets<VectorWidth::kAvx2>(a, buckets_a, count_a, b, buckets_b, count_b,
                                        contact_distance_m, slabs, contacts, counters);
}
#endif

void collideBucketSetsPortable(SphereTree& a, const std::uint32_t* buckets_a, std::uint32_t count_a,
                               SphereTree& b, const std::uint32_t* buckets_b, std::uint32_t count_b,
                               double contact_distance_m, const PairSlabs& slabs,
                               ContactSink& contacts, QueryCounters& counters) {
  collideBucketSets<VectorWidth::kPortable>(a, buckets_a, count_a, b, buckets_b, count_b,
                                            contact_distance_m, slabs, contacts, counters);
}

/// Whether two spheres come closer than the contact distance.
[[gnu::always_inline]] inline bool withinReach(const Sphere& a, const Sphere& b,
                                               double contact_distance_m) {
  const double reach = a.radius + b.radius + contact_distance_m;
  return (a.center - b.center).squaredNorm() < reach * reach;
}

/// How far two spheres, each grown by half the contact distance, overlap.
double overlap(const Sphere& a, const Sphere& b, double contact_distance_m) {
  return a.radius + b.radius + contact_distance_m - (a.center - b.center).norm();
}

inline std::uint32_t bucketCount(const SphereTree& tree) {
  return static_cast<std::uint32_t>(tree.buckets().size());
}

}  // namespace

/// One query's trees, level and reach, where its contacts and counts go, and the steps of
/// its descent. Its members are inlined into collide(), so it lives in registers.
struct HierarchyQuery::Descent {
  SphereTree& a;
  SphereTree& b;
  int level;
  double contact_distance_m;
  /// The slabs of static and kinematic objects, towards the leaves only (none above them).
  PairSlabs slabs;
  ContactSink& contacts;
  QueryCounters& counters;
  VectorWidth vectors;
  bool to_leaves;
  /// Towards the leaves, a node of kBucketLeaves leaves or fewer is measured with its
  /// leaves: its leaves are tested whenever it comes within reach of another.
  std::uint32_t leaf_limit;
  /// A small object is never descended: its buckets meet the other's as a set, the other
  /// object's buckets one at a time if it is not small too.
  bool small_a;
  bool small_b;

  /// Whether the descent ends at `node`; branch-free, as the outcome is a coin toss.
  [[gnu::always_inline]] bool terminal(const NodeState& node) const {
    return to_leaves ? node.leaf_count <= kBucketLeaves : endsDescentToLevel(node, level);
  }

  [[gnu::always_inline]] void leafContactsOfBucketSets(const std::uint32_t* buckets_a,
                                                       std::uint32_t count_a,
                                                       const std::uint32_t* buckets_b,
                                                       std::uint32_t count_b) const {
#if defined(__GNUC__) && defined(__x86_64__)
    if (vectors == VectorWidth::kAvx512) {
      collideBucketSetsAvx512(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                              slabs, contacts, counters);
      return;
    }
    if (vectors == VectorWidth::kAvx2) {
      collideBucketSetsAvx2(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m, slabs,
                            contacts, counters);
      return;
    }
#endif
    collideBucketSetsPortable(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                              slabs, contacts, counters);
  }

  [[gnu::always_inline]] void leafContactsOfBuckets(const NodeState& bucket_a,
                                                    const NodeState& bucket_b) const {
#if defined(__GNUC__) && defined(__x86_64__)
    if (vectors == VectorWidth::kAvx512) {
      collideBucketsAvx512(a, bucket_a, b, bucket_b, contact_distance_m, slabs, contacts, counters);
      return;
    }
    if (vectors == VectorWidth::kAvx2) {
      collideBucketsAvx2(a, bucket_a, b, bucket_b, contact_distance_m, slabs, contacts, counters);
      return;
    }
#endif
    collideBucketsPortable(a, bucket_a, b, bucket_b, contact_distance_m, slabs, contacts, counters);
  }

  /// The contact of two nodes above the leaves, with the pair's least overlap as its depth.
  [[gnu::always_inline]] void addNodeContact(const PendingPair& pair, const NodeState& na,
                                             const NodeState& nb) const {
    contacts.add(detail::nodeContact(pair.node_a, pair.node_b, std::max(na.level, nb.level),
                                     na.sphere, nb.sphere, pair.least_overlap_m,
                                     contact_distance_m));
  }

  /// The contacts of a pair within reach at which the descent ends on both sides.
  [[gnu::always_inline]] void collideWhereDescentEnds(const PendingPair& pair, const NodeState& na,
                                                      const NodeState& nb) const {
    if (small_a || small_b) {
      const std::uint32_t bucket_a = pair.node_a;
      const std::uint32_t bucket_b = pair.node_b;
      leafContactsOfBucketSets(
          small_a ? a.buckets().data() : &bucket_a, small_a ? bucketCount(a) : 1,
          small_b ? b.buckets().data() : &bucket_b, small_b ? bucketCount(b) : 1);
    } else if (to_leaves) {
      leafContactsOfBuckets(na, nb);
    } else {
      addNodeContact(pair, na, nb);
    }
  }

  /// Above the leaves, the least overlap of a pair's spheres and its ancestors' (see
  /// collide()); at the leaves the points give the depth.
  [[gnu::always_inline]] double leastOverlap(double ancestors_m, const Sphere& sa,
                                             const Sphere& sb) const {
    return to_leaves ? 0.0 : std::min(ancestors_m, overlap(sa, sb, contact_distance_m));
  }

  /// Whether `node` of `tree`, whose points are not measured yet, is ruled out against
  /// `other` by its bound alone: measuring a bucket reads all its points, scattered in the
  /// body's order, and many buckets a descent meets are out of reach.
  [[gnu::always_inline]] bool outOfReachUnmeasured(SphereTree& tree, std::uint32_t node,
                                                   const Sphere& other) const {
    return tree.measuresPoints(node, leaf_limit) &&
           !withinReach(tree.boundWithoutPoints(node), other, contact_distance_m);
  }

  /// Stacks the children of a's node (if `split_a`, else of b's) that come within reach of
  /// the other node, and returns the new stack height. Children go last first, so that
  /// contacts come in depth-first order; the overlap a pair carries (a square root) is
  /// computed only for those within reach. The stack grows only in the first queries.
  [[gnu::always_inline]] std::size_t stackChildrenInReach(std::vector<PendingPair>& stack,
                                                          std::size_t stacked,
                                                          const PendingPair& pair,
                                                          const NodeState& na, const NodeState& nb,
                                                          bool split_a) const {
    const NodeState& split = split_a ? na : nb;
    if (stack.size() < stacked + split.child_count) {
      stack.resize(std::max(2 * stack.size(), stacked + split.child_count));
    }
    counters.node_pairs_tested += split.child_count;
    if (split_a) {
      for (std::uint32_t c = na.first_child + na.child_count; c-- > na.first_child;) {
        if (outOfReachUnmeasured(a, c, nb.sphere)) continue;
        const Sphere& child = a.current(c, leaf_limit).sphere;
        if (!withinReach(child, nb.sphere, contact_distance_m) ||
            slabs.apart(c, child, pair.node_b, nb.sphere, contact_distance_m)) {
          continue;
        }
        stack[stacked++] = {c, pair.node_b, leastOverlap(pair.least_overlap_m, child, nb.sphere)};
        a.prefetchChildren(c);
      }
    } else {
      for (std::uint32_t c = nb.first_child + nb.child_count; c-- > nb.first_child;) {
        if (outOfReachUnmeasured(b, c, na.sphere)) continue;
        const Sphere& child = b.current(c, leaf_limit).sphere;
        if (!withinReach(na.sphere, child, contact_distance_m) ||
            slabs.apart(pair.node_a, na.sphere, c, child, contact_distance_m)) {
          continue;
        }
        stack[stacked++] = {pair.node_a, c, leastOverlap(pair.least_overlap_m, na.sphere, child)};
        b.prefetchChildren(c);
      }
    }
    return stacked;
  }
};

HierarchyQuery::HierarchyQuery(VectorWidth vectors)
    : vectors_(std::min(vectors, widestVectors())) {}

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             std::vector<SphereContact>& contacts, QueryCounters& counters,
                             const PairSlabs& slabs) {
  struct Appender final : ContactSink {
    explicit Appender(std::vector<SphereContact>& contacts) : contacts(contacts) {}
    void add(const SphereContact& contact) override { contacts.push_back(contact); }
    std::vector<SphereContact>& contacts;
  } appender(contacts);
  collide(a, b, level, contact_distance_m, appender, counters, slabs);
}

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             ContactSink& contacts, QueryCounters& counters,
                             const PairSlabs& slabs) {
  const bool to_leaves = level >= std::max(a.maxLevel(), b.maxLevel());
  const Descent descent{a,
                        b,
                        level,
                        contact_distance_m,
                        to_leaves ? slabs : PairSlabs{},
                        contacts,
                        counters,
                        vectors_,
                        to_leaves,
                        to_leaves ? kBucketLeaves : 0,
                        to_leaves && a.buckets().size() <= kBucketLeaves,
                        to_leaves && b.buckets().size() <= kBucketLeaves};
  const std::uint32_t leaf_limit = descent.leaf_limit;
  // Pairs are tested before they are stacked, so the stack holds only pairs within reach.
  ++counters.node_pairs_tested;
  const Sphere& root_a = a.current(0, leaf_limit).sphere;
  const Sphere& root_b = b.current(0, leaf_limit).sphere;
  if (!withinReach(root_a, root_b, contact_distance_m) ||
      descent.slabs.apart(0, root_a, 0, root_b, contact_distance_m)) {
    return;
  }
  if (descent.small_a && descent.small_b) {
    descent.leafContactsOfBucketSets(a.buckets().data(), bucketCount(a), b.buckets().data(),
                                     bucketCount(b));
    return;
  }
  // Above the leaves a pair carries the least overlap of its own and its ancestors'
  // spheres: all of them bound its points, so their overlap is at most that. A contact's
  // depth is then one that the response can clear without the pair's ancestors leaving
  // reach first, which would end the contact above where it rests.
  if (stack_.empty()) stack_.resize(1);
  stack_[0] = {0, 0, to_leaves ? 0.0 : overlap(a.sphere(0), b.sphere(0), contact_distance_m)};
  std::size_t stacked = 1;
  while (stacked > 0) {
    // A copy: the children stacked next may be written over its slot.
    const PendingPair pair = stack_[--stacked];
    const NodeState& na = a.current(pair.node_a, leaf_limit);
    const NodeState& nb = b.current(pair.node_b, leaf_limit);
    const bool stop_a = descent.small_a || descent.terminal(na);
    const bool stop_b = descent.small_b || descent.terminal(nb);
    if (stop_a && stop_b) {
      descent.collideWhereDescentEnds(pair, na, nb);
      continue;
    }
    // Descend the node that is not done, the larger one if both may go on.
    const bool split_a = !stop_a && (stop_b || na.sphere.radius >= nb.sphere.radius);
    stacked = descent.stackChildrenInReach(stack_, stacked, pair, na, nb, split_a);
  }
}

}  // namespace deformable_collision
