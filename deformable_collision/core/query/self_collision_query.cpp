#include "deformable_collision/core/query/self_collision_query.h"

#include <algorithm>
#include <cmath>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/query/detail/node_contact.h"

namespace deformable_collision {

RestSpheres::RestSpheres(const SphereTree& tree) : tree_(&tree) {
  spheres_.reserve(tree.nodeCount());
  for (std::uint32_t i = 0; i < tree.nodeCount(); ++i) {
    const SphereNode& node = tree.node(i);
    // A cluster's nodes are centred on its rest centre of mass; an object root over several
    // clusters is not (erratum 1 of docs/design.md).
    const Eigen::Vector3d origin = node.cluster < 0
                                       ? Eigen::Vector3d::Zero()
                                       : tree.body().cluster(node.cluster).rest_center_of_mass;
    spheres_.push_back({node.rest_center + origin, node.rest_radius_m});
  }
}

namespace {

/// Relative margin of the rest and stretch tests, far above their rounding.
constexpr double kMargin = 1e-9;

/// A sphere at most this many times its rest radius (plus the contact distance) is used as the
/// tree gives it; a wider one is measured from the points.
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

/// A lower bound of the least singular value of a 3x3 matrix: the product of the three is
/// |det|, and the other two are at most the largest. Exact for a rotation and tight for a
/// nearly uniform stretch; rounding is covered by a relative margin far above it.
double leastSingularValueBound(const Eigen::Matrix3d& matrix) {
  const double largest = spectralNorm(matrix);
  if (!(largest > 0.0)) return 0.0;
  return std::abs(matrix.determinant()) / (largest * largest) * (1.0 - kMargin);
}

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
  std::vector<MeasuredSphere>& measured_spheres;
  std::uint64_t query_serial;

  /// Whether the fits of nodes a's and b's clusters keep every pair of their points farther
  /// than the rest distance apart at rest from coming within the contact distance: tried
  /// with the stretch of either's cluster.
  bool keptApartByClusters(std::uint32_t a, std::uint32_t b) const {
    const SphereNode& na = tree.node(a);
    const SphereNode& nb = tree.node(b);
    if (na.cluster < 0 || nb.cluster < 0) return false;
    if (na.cluster == nb.cluster) return keptApartInCluster(na, nb);
    return keptApartAcross(a, na.cluster, b, nb.cluster) ||
           keptApartAcross(b, nb.cluster, a, na.cluster);
  }

  /// One cluster's fit f: |f(u) - f(v)| >= stretch |u - v| (ClusterStretch) for u and v of
  /// the two nodes, with e from their rest spheres (centred coordinates).
  bool keptApartInCluster(const SphereNode& na, const SphereNode& nb) const {
    const ClusterStretch& k = stretches[na.cluster];
    const double extent_m = std::max(na.rest_center.norm() + na.rest_radius_m,
                                     nb.rest_center.norm() + nb.rest_radius_m);
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

  /// Whether some point of node a and some point of node b (a itself if a == b) may lie
  /// more than the rest distance apart at rest: only then can the pair hold a self-contact.
  /// The relative margins keep both tests on the safe side of their rounding.
  bool mayHoldDistantPair(std::uint32_t a, std::uint32_t b) const {
    const Sphere& ra = rest[a];
    const Sphere& rb = rest[b];
    const double farthest_m =
        a == b ? 2.0 * ra.radius : (ra.center - rb.center).norm() + ra.radius + rb.radius;
    return farthest_m * (1.0 + kMargin) > rest_distance_m;
  }

  /// Whether every point of a lies more than the rest distance from every point of b at rest.
  bool allDistant(std::uint32_t a, std::uint32_t b) const {
    const Sphere& ra = rest[a];
    const Sphere& rb = rest[b];
    const double nearest_m = (ra.center - rb.center).norm() - ra.radius - rb.radius;
    return nearest_m > rest_distance_m * (1.0 + kMargin);
  }

  /// The node's sphere from the tree, or, where its cluster's fit is poor (a fold inside the
  /// cluster: the sphere far wider than at rest), one measured around its points' mean.
  /// A loose sphere would keep every node of a folded cluster in reach of every other.
  const Sphere& sphere(std::uint32_t node) {
    const Sphere& fitted = tree.current(node).sphere;
    if (fitted.radius <= kLooseSphere * rest[node].radius + contact_distance_m) return fitted;
    MeasuredSphere& measured = measured_spheres[node];
    if (measured.query != query_serial) {
      measured = {measureSphere(node), query_serial};
    }
    return measured.sphere.radius < fitted.radius ? measured.sphere : fitted;
  }

  Sphere measureSphere(std::uint32_t node) const {
    const SphereNode& n = tree.node(node);
    const auto& positions = tree.body().positions();
    const std::uint32_t* points = tree.pointIndices().data() + n.first_point;
    Eigen::Vector3d center = Eigen::Vector3d::Zero();
    for (std::uint32_t s = 0; s < n.point_count; ++s) center += positions[points[s]];
    center /= n.point_count;
    double squared_m2 = 0.0;
    for (std::uint32_t s = 0; s < n.point_count; ++s) {
      squared_m2 = std::max(squared_m2, (positions[points[s]] - center).squaredNorm());
    }
    // The root rounds below the distance it bounds by far less than this margin.
    const double radius_m = std::sqrt(squared_m2);
    return {center, radius_m + kMargin * (radius_m + center.cwiseAbs().maxCoeff())};
  }

  bool terminal(const NodeState& node) const {
    return to_leaves ? node.isLeaf() : endsDescentToLevel(node, level);
  }

  /// Stacks the pair if it may hold a self-contact: in reach now, and apart at rest.
  void push(std::uint32_t a, std::uint32_t b) {
    ++counters.node_pairs_tested;
    if (a != b && !withinReach(sphere(a), sphere(b), contact_distance_m)) {
      return;
    }
    if (mayHoldDistantPair(a, b) && !keptApartByClusters(a, b)) stack.push_back({a, b});
  }

  /// A node against itself: its children against each other and each against itself.
  void visitNode(std::uint32_t index) {
    const NodeState& node = tree.current(index);
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
    const bool distant = allDistant(pair.node_a, pair.node_b);
    const bool stop_a = terminal(na);
    const bool stop_b = terminal(nb);
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

  /// The closest pair of a's and b's points (each pair once if a is b) that is closer than
  /// the contact distance and, unless `distant`, farther than the rest distance at rest.
  void testLeaves(const NodeState& a, const NodeState& b, bool distant) {
    ++counters.leaf_pairs_tested;
    const auto& positions = tree.leafPositions();
    const double rest_squared_m2 = rest_distance_m * rest_distance_m;
    ClosestSlots closest{contact_distance_m * contact_distance_m};
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
        const double squared_m2 = (positions.col(s) - positions.col(t)).squaredNorm();
        if (squared_m2 >= closest.squared_distance_m2) continue;
        if (!distant && (rest.slotPoint(s) - rest.slotPoint(t)).squaredNorm() <= rest_squared_m2) {
          continue;
        }
        closest = {squared_m2, s, t, true};
      }
    }
    if (closest.found) addLeafContact(a, b, closest);
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
  measureStretches(tree.body());
  if (measured_spheres_.size() < tree.nodeCount()) measured_spheres_.resize(tree.nodeCount());
  Descent descent{tree,     rest,     level,  to_leaves,  contact_distance_m, rest_distance_m,
                  contacts, counters, stack_, stretches_, measured_spheres_,  ++query_serial_};
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

void SelfCollisionQuery::measureStretches(const ShapeMatchingBody& body) {
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
  }
}

}  // namespace deformable_collision
