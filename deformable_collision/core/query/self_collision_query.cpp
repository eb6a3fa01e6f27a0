#include "deformable_collision/core/query/self_collision_query.h"

#include <algorithm>
#include <cmath>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/query/detail/leaf_pair_kernels.h"
#include "deformable_collision/core/query/detail/node_contact.h"

namespace deformable_collision {

RestSpheres::RestSpheres(const SphereTree& tree) : slot_points_(3, tree.pointIndices().size()) {
  for (std::size_t s = 0; s < tree.pointIndices().size(); ++s) {
    slot_points_.col(s) = tree.body().restPositions()[tree.pointIndices()[s]];
  }
  spheres_.reserve(tree.nodeCount());
  cluster_extents_.reserve(tree.nodeCount());
  for (std::uint32_t i = 0; i < tree.nodeCount(); ++i) {
    const SphereNode& node = tree.node(i);
    // A cluster's nodes are centred on its rest centre of mass; an object root over several
    // clusters is not (erratum 1 of docs/design.md).
    const Eigen::Vector3d origin = node.cluster < 0
                                       ? Eigen::Vector3d::Zero()
                                       : tree.body().cluster(node.cluster).rest_center_of_mass;
    spheres_.push_back({node.rest_center + origin, node.rest_radius_m});
    cluster_extents_.push_back(node.rest_center.norm() + node.rest_radius_m);
  }
}

namespace {

/// Relative margin of the rest and stretch tests, far above their rounding.
constexpr double kMargin = 1e-9;

/// Nodes of at most this many leaves have their leaf pairs tested directly.
constexpr std::uint32_t kBucketLeaves = SphereTree::kBucketLeaves;

/// A sphere at most this many times its rest radius (plus the contact distance) is used as the
/// tree gives it; a wider one is replaced by the sphere around the box of its points.
constexpr double kLooseSphere = 2.0;

/// Whether two spheres come closer than the contact distance.
bool withinReach(const Sphere& a, const Sphere& b, double contact_distance_m) {
  const double reach = a.radius + b.radius + contact_distance_m;
  return (a.center - b.center).squaredNorm() < reach * reach;
}

/// The closest qualifying point pair of a leaf pair so far, as slots of pointIndices().
struct ClosestSlots {
  double squared_distance_m2;
  std::uint32_t slot_a = 0;
  std::uint32_t slot_b = 0;
  bool found = false;
};

/// Squared distance of the points at slots s and t, summed as the wide kernels sum it, so
/// that both tests find the same bits.
double squaredDistance(const SlotPositions& points, std::uint32_t s, std::uint32_t t) {
  const double dx = points(0, s) - points(0, t);
  const double dy = points(1, s) - points(1, t);
  const double dz = points(2, s) - points(2, t);
  return dx * dx + dy * dy + dz * dz;
}

/// A lower bound of the least singular value of a 3x3 matrix: the product of the three is
/// |det|, and the other two are at most the largest. Exact for a rotation and tight for a
/// nearly uniform stretch; rounding is covered by a relative margin far above it.
double leastSingularValueBound(const Eigen::Matrix3d& matrix) {
  const double largest = spectralNorm(matrix);
  if (!(largest > 0.0)) return 0.0;
  return std::abs(matrix.determinant()) / (largest * largest) * (1.0 - kMargin);
}

/// The leaves under a node of at most kBucketLeaves leaves, with the spheres the query
/// uses for them as coordinate arrays.
struct SmallNodeLeaves {
  std::uint32_t count = 0;
  std::uint32_t node[kBucketLeaves];
  double x[kBucketLeaves], y[kBucketLeaves], z[kBucketLeaves], radius[kBucketLeaves];
  /// Each leaf's box around its current points, its least and greatest coordinates.
  const double* low[kBucketLeaves];
  const double* high[kBucketLeaves];
};
static_assert(kBucketLeaves * kBucketLeaves <= 64, "two small nodes' leaf pairs are one mask");

/// Whether two boxes, given by their least and greatest coordinates, lie at least the
/// contact distance apart. Summed as the point tests sum a squared distance, each term at
/// most theirs, so that no pair of the points inside can pass the point test.
bool boxesApart(const double* low_a, const double* high_a, const double* low_b,
                const double* high_b, double contact_distance_m) {
  double gap[3];
  for (int i = 0; i < 3; ++i) gap[i] = std::max({0.0, low_a[i] - high_b[i], low_b[i] - high_a[i]});
  return gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2] >=
         contact_distance_m * contact_distance_m;
}

/// Of a node's leaf pairs with itself, each pair once and each leaf with itself: bit 8 k + l
/// for l >= k.
constexpr std::uint64_t kSameNodePairs = 0x80C0E0F0F8FCFEFFull;

#if defined(__GNUC__) && defined(__x86_64__)
/// reachingPairs, four of b's leaf spheres per instruction.
__attribute__((target("avx2"))) std::uint64_t reachingPairsAvx2(const SmallNodeLeaves& a,
                                                                const SmallNodeLeaves& b,
                                                                double contact_distance_m) {
  std::uint64_t pairs = 0;
  for (std::uint32_t k = 0; k < a.count; ++k) {
    pairs |= static_cast<std::uint64_t>(reachMaskAvx2(a.x[k], a.y[k], a.z[k],
                                                      a.radius[k] + contact_distance_m, b.x, b.y,
                                                      b.z, b.radius, b.count))
             << (8 * k);
  }
  return pairs;
}
#endif

/// The leaf pairs of two small nodes whose spheres come within the contact distance: bit
/// 8 k + l for a's leaf k and b's leaf l. Every width finds the same bits.
std::uint64_t reachingPairs(const SmallNodeLeaves& a, const SmallNodeLeaves& b,
                            double contact_distance_m, VectorWidth width) {
#if defined(__GNUC__) && defined(__x86_64__)
  if (width != VectorWidth::kPortable) return reachingPairsAvx2(a, b, contact_distance_m);
#endif
  std::uint64_t pairs = 0;
  for (std::uint32_t k = 0; k < a.count; ++k) {
    for (std::uint32_t l = 0; l < b.count; ++l) {
      const double dx = a.x[k] - b.x[l], dy = a.y[k] - b.y[l], dz = a.z[k] - b.z[l];
      const double reach_m = b.radius[l] + (a.radius[k] + contact_distance_m);
      pairs |= static_cast<std::uint64_t>(dx * dx + dy * dy + dz * dz < reach_m * reach_m)
               << (8 * k + l);
    }
  }
  return pairs;
}

#if defined(__GNUC__) && defined(__x86_64__)
/// The closest pair of leaf a's points and leaf b's (at most eight) closer than `closest`
/// says and, unless `distant`, farther than sqrt(apart_squared) at rest: the same pair, to
/// the bit, as the point-by-point test. Compiled for AVX2 apart, so that the kernels inline.
__attribute__((target("avx2"))) bool closestPairAvx2(const SlotPositions& positions,
                                                     const SlotPositions& rest, const NodeState& a,
                                                     const NodeState& b, bool distant,
                                                     double apart_squared, ClosestSlots& closest,
                                                     std::size_t& point_tests) {
  const std::uint32_t s = a.first_point;
  const std::uint32_t t = b.first_point;
  const double* const xa[3] = {&positions(0, s), &positions(1, s), &positions(2, s)};
  const double* const xb[3] = {&positions(0, t), &positions(1, t), &positions(2, t)};
  double squared_m2 = 0.0;
  std::uint32_t offset_a = 0;
  std::uint32_t offset_b = 0;
  bool found = false;
  if (distant) {
    found = closestPairOfEightAvx2(xa[0], xa[1], xa[2], a.point_count, xb[0], xb[1], xb[2],
                                   b.point_count, closest.squared_distance_m2, squared_m2, offset_a,
                                   offset_b, point_tests);
  } else {
    const double* const ra[3] = {&rest(0, s), &rest(1, s), &rest(2, s)};
    const double* const rb[3] = {&rest(0, t), &rest(1, t), &rest(2, t)};
    found = closestPairApartAtRestOfEightAvx2(xa, ra, a.point_count, xb, rb, b.point_count,
                                              apart_squared, closest.squared_distance_m2,
                                              squared_m2, offset_a, offset_b, point_tests);
  }
  if (found) closest = {squared_m2, s + offset_a, t + offset_b, true};
  return found;
}
#endif

}  // namespace

struct SelfCollisionQuery::Descent {
  SphereTree& tree;
  const RestSpheres& rest;
  int level;
  bool to_leaves;
  double contact_distance_m;
  double rest_distance_m;
  ContactSink& contacts;
  QueryCounters& counters;
  std::vector<PendingPair>& stack;
  const std::vector<ClusterStretch>& stretches;
  std::vector<QuerySphere>& query_spheres;
  std::vector<NodeBox>& node_boxes;
  std::uint64_t query_serial;
  VectorWidth width;

  /// Whether the fits of nodes a's and b's clusters keep every pair of their points farther
  /// than the rest distance apart at rest from coming within the contact distance: tried
  /// with the stretch of either's cluster.
  bool keptApartByClusters(std::uint32_t a, std::uint32_t b) const {
    const SphereNode& na = tree.node(a);
    const SphereNode& nb = tree.node(b);
    if (na.cluster < 0 || nb.cluster < 0) return false;
    if (na.cluster == nb.cluster) {
      return stretches[na.cluster].may_keep_apart && keptApartInCluster(a, b, na.cluster);
    }
    return (stretches[na.cluster].may_keep_apart &&
            keptApartAcross(a, na.cluster, b, nb.cluster)) ||
           (stretches[nb.cluster].may_keep_apart && keptApartAcross(b, nb.cluster, a, na.cluster));
  }

  /// One cluster's fit f: |f(u) - f(v)| >= stretch |u - v| (ClusterStretch) for u and v of
  /// the two nodes, with e from their rest spheres (centred coordinates).
  bool keptApartInCluster(std::uint32_t a, std::uint32_t b, std::int32_t cluster) const {
    const ClusterStretch& k = stretches[cluster];
    const double extent_m = std::max(rest.clusterExtent(a), rest.clusterExtent(b));
    const double stretch = k.least_stretch - 2.0 * extent_m * k.quadratic_norms;
    return stretch * rest_distance_m - 2.0 * k.deviation_m >= contact_distance_m * (1.0 + kMargin);
  }

  /// Node a of cluster k against node b of cluster l: x_a - x_b = (f_k(u) - f_k(v)) + (f_k(v) -
  /// f_l(v)) + the deviations, for rest points u of a and v of b. The first is bounded by
  /// k's stretch over both nodes, the second by how far the two fits part over b's rest
  /// sphere: at its centre, plus its radius times the difference of the linear parts
  /// (Frobenius, above the spectral norm) and the quadratic parts' slopes.
  bool keptApartAcross(std::uint32_t a, std::int32_t k, std::uint32_t b, std::int32_t l) const {
    const ClusterStretch& sk = stretches[k];
    const ClusterStretch& sl = stretches[l];
    const Sphere& ra = rest[a];
    const Sphere& rb = rest[b];
    const double b_from_k_m = (rb.center - sk.rest_center_m).norm() + rb.radius;
    const double b_from_l_m = (rb.center - sl.rest_center_m).norm() + rb.radius;
    const double extent_m = std::max((ra.center - sk.rest_center_m).norm() + ra.radius, b_from_k_m);
    const double stretch = sk.least_stretch - 2.0 * extent_m * sk.quadratic_norms;
    const Eigen::Vector3d fit_k = fitAt(k, rb.center);
    const Eigen::Vector3d fit_l = fitAt(l, rb.center);
    const double slope = (sk.linear - sl.linear).norm() + 2.0 * b_from_k_m * sk.quadratic_norms +
                         2.0 * b_from_l_m * sl.quadratic_norms;
    // The fits are evaluated far from the origin too: their rounding, relative to their size.
    const double parting_m =
        (fit_k - fit_l).norm() + slope * rb.radius + kMargin * (fit_k.norm() + fit_l.norm());
    return stretch * rest_distance_m - parting_m - sk.deviation_m - sl.deviation_m >=
           contact_distance_m * (1.0 + kMargin);
  }

  /// Cluster k's fit at rest point `rest_m` (in the object's frame).
  Eigen::Vector3d fitAt(std::int32_t k, const Eigen::Vector3d& rest_m) const {
    const ClusterDeformation& deformation = tree.body().deformation(k);
    const Eigen::Vector3d q = rest_m - stretches[k].rest_center_m;
    Eigen::Matrix<double, 9, 1> features;
    features << q.x(), q.y(), q.z(), q.x() * q.x(), q.y() * q.y(), q.z() * q.z(), q.x() * q.y(),
        q.y() * q.z(), q.z() * q.x();
    return deformation.transform * features + deformation.translation;
  }

  /// How nodes a and b (a itself if a == b) lie at rest: whether some point of a and some
  /// point of b may lie more than the rest distance apart (only then can the pair hold a
  /// self-contact), and whether every pair does. The relative margins keep both tests on
  /// the safe side of their rounding.
  struct AtRest {
    bool may_hold_distant;
    bool all_distant;
  };
  AtRest atRest(std::uint32_t a, std::uint32_t b) const {
    const Sphere& ra = rest[a];
    const Sphere& rb = rest[b];
    if (a == b) return {2.0 * ra.radius * (1.0 + kMargin) > rest_distance_m, false};
    const double between_m = (ra.center - rb.center).norm();
    return {(between_m + ra.radius + rb.radius) * (1.0 + kMargin) > rest_distance_m,
            between_m - ra.radius - rb.radius > rest_distance_m * (1.0 + kMargin)};
  }

  /// The node's sphere from the tree, or, where its cluster's fit is poor (a fold inside the
  /// cluster: the sphere far wider than at rest), the one through the corners of its points'
  /// box. A loose sphere would keep every node of a folded cluster in reach of every other.
  /// Chosen once a query: a descent asks for the same nodes' spheres many times.
  const Sphere& sphere(std::uint32_t node) {
    QuerySphere& chosen = query_spheres[node];
    if (chosen.query != query_serial) chosen = {chooseSphere(node), query_serial};
    return chosen.sphere;
  }

  Sphere chooseSphere(std::uint32_t node) {
    const NodeState& state = tree.current(node);
    const Sphere fitted = state.sphere;
    if (fitted.radius <= kLooseSphere * rest[node].radius + contact_distance_m) return fitted;
    const Sphere measured = aroundBox(nodeBox(node));
    return measured.radius < fitted.radius ? measured : fitted;
  }

  /// The sphere through the box's corners.
  static Sphere aroundBox(const NodeBox& box) {
    const Eigen::Vector3d low(box.low[0], box.low[1], box.low[2]);
    const Eigen::Vector3d high(box.high[0], box.high[1], box.high[2]);
    const Eigen::Vector3d center = 0.5 * (low + high);
    const double radius_m = 0.5 * (high - low).norm();
    return {center, radius_m + kMargin * (radius_m + center.cwiseAbs().maxCoeff())};
  }

  bool terminal(const NodeState& node) const {
    return to_leaves ? node.isLeaf() : endsDescentToLevel(node, level);
  }

  /// Stacks the pair if it may hold a self-contact: in reach now, and apart at rest.
  void push(std::uint32_t a, std::uint32_t b) {
    ++counters.node_pairs_tested;
    if (a != b && (!withinReach(sphere(a), sphere(b), contact_distance_m) || knownApart(a, b))) {
      return;
    }
    const AtRest at_rest = atRest(a, b);
    if (at_rest.may_hold_distant && !keptApartByClusters(a, b)) {
      stack.push_back({a, b, at_rest.all_distant});
    }
  }

  /// A node against itself: its children against each other and each against itself.
  void visitNode(std::uint32_t index) {
    const NodeState& node = tree.current(index);
    if (to_leaves && node.leaf_count <= kBucketLeaves) {
      SmallNodeLeaves leaves;
      gatherLeaves(node, leaves);
      collideLeaves(leaves, leaves, true);
      return;
    }
    if (node.isLeaf()) {
      testLeaves(node, node, false);
      return;
    }
    const std::uint32_t first = node.first_child;
    const std::uint32_t end = first + node.child_count;
    for (std::uint32_t k = end; k-- > first;) {
      for (std::uint32_t l = end; l-- > k;) push(k, l);
    }
  }

  void visitPair(const PendingPair& pair) {
    const NodeState& na = tree.current(pair.node_a);
    const NodeState& nb = tree.current(pair.node_b);
    const bool distant = pair.all_distant;
    const bool stop_a = terminal(na);
    const bool stop_b = terminal(nb);
    if (to_leaves && na.leaf_count <= kBucketLeaves && nb.leaf_count <= kBucketLeaves) {
      SmallNodeLeaves leaves_a;
      SmallNodeLeaves leaves_b;
      gatherLeaves(na, leaves_a);
      gatherLeaves(nb, leaves_b);
      collideLeaves(leaves_a, leaves_b, false);
      return;
    }
    if (stop_a && stop_b && distant && !to_leaves) {
      const Sphere& sa = sphere(pair.node_a);
      const Sphere& sb = sphere(pair.node_b);
      const double overlap_m =
          sa.radius + sb.radius + contact_distance_m - (sa.center - sb.center).norm();
      contacts.add(detail::nodeContact(pair.node_a, pair.node_b, std::max(na.level, nb.level), sa,
                                       sb, overlap_m, contact_distance_m));
      return;
    }
    if (na.isLeaf() && nb.isLeaf()) {
      testLeaves(na, nb, distant);
      return;
    }
    // A pair not proven apart at rest goes below the level, where its nodes can be.
    const bool can_a = !na.isLeaf() && !(distant && stop_a);
    const bool can_b = !nb.isLeaf() && !(distant && stop_b);
    const bool split_a = can_a && (!can_b || na.sphere.radius >= nb.sphere.radius);
    const NodeState& split = split_a ? na : nb;
    for (std::uint32_t c = split.first_child + split.child_count; c-- > split.first_child;) {
      if (split_a) {
        push(c, pair.node_b);
      } else {
        push(pair.node_a, c);
      }
    }
  }

  void gatherLeaves(const NodeState& state, SmallNodeLeaves& leaves) {
    leaves.count = state.leaf_count;
    for (std::uint32_t k = 0; k < state.leaf_count; ++k) {
      const std::uint32_t leaf = tree.leafNode(state.first_leaf + k);
      const Sphere& s = sphere(leaf);
      leaves.node[k] = leaf;
      leaves.x[k] = s.center.x();
      leaves.y[k] = s.center.y();
      leaves.z[k] = s.center.z();
      leaves.radius[k] = s.radius;
      const NodeBox& box = nodeBox(leaf);
      leaves.low[k] = box.low;
      leaves.high[k] = box.high;
    }
  }

  /// Whether both nodes' boxes were measured in this query (folded nodes) and lie the
  /// contact distance apart. No box is measured for it: that reads all points below.
  bool knownApart(std::uint32_t a, std::uint32_t b) const {
    const NodeBox& u = node_boxes[a];
    const NodeBox& v = node_boxes[b];
    return u.query == query_serial && v.query == query_serial &&
           boxesApart(u.low, u.high, v.low, v.high, contact_distance_m);
  }

  /// The box around the node's current points, measured once a query: a leaf's from its
  /// points, a node's as its children's together (exactly the box of its points), so that
  /// a folded branch's points are read once, not once per level.
  const NodeBox& nodeBox(std::uint32_t node) {
    NodeBox& box = node_boxes[node];
    if (box.query == query_serial) return box;
    const NodeState& state = tree.current(node);
    if (state.isLeaf()) {
      boxAroundPoints(state, box);
    } else {
      box = nodeBox(state.first_child);
      for (std::uint32_t c = state.first_child + 1; c < state.first_child + state.child_count;
           ++c) {
        const NodeBox& child = nodeBox(c);
        for (int i = 0; i < 3; ++i) {
          box.low[i] = std::min(box.low[i], child.low[i]);
          box.high[i] = std::max(box.high[i], child.high[i]);
        }
      }
    }
    box.query = query_serial;
    return box;
  }

  void boxAroundPoints(const NodeState& leaf, NodeBox& box) const {
    const SlotPositions& positions = tree.leafPositions();
    const std::uint32_t end = leaf.first_point + leaf.point_count;
    for (int i = 0; i < 3; ++i) {
      box.low[i] = box.high[i] = positions(i, leaf.first_point);
      for (std::uint32_t s = leaf.first_point + 1; s < end; ++s) {
        box.low[i] = std::min(box.low[i], positions(i, s));
        box.high[i] = std::max(box.high[i], positions(i, s));
      }
    }
  }

  /// Every leaf of a against every leaf of b (each pair once, and each leaf with itself, if
  /// `same`): the leaf pairs of two small nodes, tested without the levels between them and
  /// their leaves, whose pairs would mostly be in reach and be descended anyway.
  void collideLeaves(const SmallNodeLeaves& a, const SmallNodeLeaves& b, bool same) {
    counters.node_pairs_tested += same ? a.count * (a.count + 1) / 2 : a.count * b.count;
    std::uint64_t pairs = reachingPairs(a, b, contact_distance_m, width);
    if (same) pairs &= kSameNodePairs;
    while (pairs != 0) {
      const auto bit = static_cast<std::uint32_t>(__builtin_ctzll(pairs));
      pairs &= pairs - 1;
      const std::uint32_t k = bit >> 3;
      const std::uint32_t l = bit & 7;
      if (boxesApart(a.low[k], a.high[k], b.low[l], b.high[l], contact_distance_m)) continue;
      leafPair(a.node[k], b.node[l]);
    }
  }

  /// A leaf pair in reach (a leaf with itself if a == b), tested if it may hold a
  /// self-contact by its rest shape and, in one cluster, by that cluster's fit. Two clusters'
  /// fits are not tried again: the small nodes above failed that test, and it costs about
  /// what testing the leaves' points does.
  void leafPair(std::uint32_t a, std::uint32_t b) {
    const AtRest at_rest = atRest(a, b);
    if (!at_rest.may_hold_distant) return;
    const std::int32_t cluster = tree.node(a).cluster;
    if (cluster >= 0 && cluster == tree.node(b).cluster && stretches[cluster].may_keep_apart &&
        keptApartInCluster(a, b, cluster)) {
      return;
    }
    testLeaves(tree.current(a), tree.current(b), at_rest.all_distant);
  }

  /// The closest pair of a's and b's points (each pair once if a is b) that is closer than
  /// the contact distance and, unless `distant`, farther than the rest distance at rest.
  void testLeaves(const NodeState& a, const NodeState& b, bool distant) {
    ++counters.leaf_pairs_tested;
    ClosestSlots closest{contact_distance_m * contact_distance_m};
#if defined(__GNUC__) && defined(__x86_64__)
    if (&a != &b && width != VectorWidth::kPortable && b.point_count <= 8) {
      if (closestPairAvx2(tree.leafPositions(), rest.slotPoints(), a, b, distant,
                          rest_distance_m * rest_distance_m, closest, counters.point_tests)) {
        addLeafContact(a, b, closest);
      }
      return;
    }
#endif
    closestPairPointByPoint(a, b, distant, closest);
    if (closest.found) addLeafContact(a, b, closest);
  }

  void closestPairPointByPoint(const NodeState& a, const NodeState& b, bool distant,
                               ClosestSlots& closest) {
    const SlotPositions& positions = tree.leafPositions();
    const SlotPositions& rest_points = rest.slotPoints();
    const double rest_squared_m2 = rest_distance_m * rest_distance_m;
    const bool same = &a == &b;
    // Only a's points within reach of b's sphere can have a partner in b.
    const double reach_m = b.sphere.radius + contact_distance_m;
    for (std::uint32_t s = a.first_point; s < a.first_point + a.point_count; ++s) {
      ++counters.point_tests;
      if (!same && (positions.col(s) - b.sphere.center).squaredNorm() >= reach_m * reach_m) {
        continue;
      }
      for (std::uint32_t t = same ? s + 1 : b.first_point; t < b.first_point + b.point_count; ++t) {
        ++counters.point_tests;
        const double squared_m2 = squaredDistance(positions, s, t);
        if (squared_m2 >= closest.squared_distance_m2) continue;
        if (!distant && squaredDistance(rest_points, s, t) <= rest_squared_m2) {
          continue;
        }
        closest = {squared_m2, s, t, true};
      }
    }
  }

  void addLeafContact(const NodeState& a, const NodeState& b, const ClosestSlots& closest) {
    const auto& positions = tree.leafPositions();
    const Eigen::Vector3d x = positions.col(closest.slot_a);
    const Eigen::Vector3d y = positions.col(closest.slot_b);
    SphereContact contact;
    contact.node_a = tree.leafNode(a.first_leaf);
    contact.node_b = tree.leafNode(b.first_leaf);
    contact.level = std::max(a.level, b.level);
    contact.point_a = tree.pointIndices()[closest.slot_a];
    contact.point_b = tree.pointIndices()[closest.slot_b];
    contact.position = 0.5 * (x + y);
    const double distance_m = std::sqrt(closest.squared_distance_m2);
    contact.normal = directionFrom(y, x);
    contact.depth_m = contact_distance_m - distance_m;
    contact.error_bound_m = 0.0;
    contacts.add(contact);
  }
};

void SelfCollisionQuery::collide(SphereTree& tree, const RestSpheres& rest, int level,
                                 double contact_distance_m, double rest_distance_m,
                                 ContactSink& contacts, QueryCounters& counters) {
  const bool to_leaves = level < 0 || level >= tree.maxLevel();
  measureStretches(tree.body(), contact_distance_m, rest_distance_m);
  if (query_spheres_.size() < tree.nodeCount()) query_spheres_.resize(tree.nodeCount());
  if (node_boxes_.size() < tree.nodeCount()) node_boxes_.resize(tree.nodeCount());
  Descent descent{
      tree,     rest,   level,      to_leaves,      contact_distance_m, rest_distance_m, contacts,
      counters, stack_, stretches_, query_spheres_, node_boxes_,        ++query_serial_, width_};
  stack_.clear();
  descent.push(0, 0);
  while (!stack_.empty()) {
    const PendingPair pair = stack_.back();
    stack_.pop_back();
    if (pair.node_a == pair.node_b) {
      descent.visitNode(pair.node_a);
    } else {
      descent.visitPair(pair);
    }
  }
}

void SelfCollisionQuery::measureStretches(const ShapeMatchingBody& body, double contact_distance_m,
                                          double rest_distance_m) {
  stretches_.resize(body.clusterCount());
  const bool quadratic = body.config().mode == DeformationMode::kQuadratic;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const ClusterDeformation& deformation = body.deformation(k);
    ClusterStretch& stretch = stretches_[k];
    stretch.least_stretch = leastSingularValueBound(deformation.transform.leftCols<3>());
    // spectralNorm may fall short of the norm by rounding: the margin makes it a bound.
    stretch.quadratic_norms = quadratic ? (spectralNorm(deformation.transform.middleCols<3>(3)) +
                                           spectralNorm(deformation.transform.rightCols<3>())) *
                                              (1.0 + kMargin)
                                        : 0.0;
    stretch.deviation_m = deformation.goal_deviation_bound_m;
    stretch.rest_center_m = body.cluster(k).rest_center_of_mass;
    stretch.linear = deformation.transform.leftCols<3>();
    stretch.may_keep_apart = stretch.least_stretch * rest_distance_m - stretch.deviation_m >=
                             contact_distance_m * (1.0 + kMargin);
  }
}

}  // namespace deformable_collision
