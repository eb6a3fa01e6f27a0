#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {

struct SphereTreeConfig {
  /// Children of an internal node, >= 2; the levels nearest the root may split in
  /// branching + 1, where that ends the tree in fewer, fuller leaves.
  int branching = 2;
  int leaf_size = 8;  ///< Largest number of points in a leaf, >= 1.
  /// Nodes of at most this many points measure their radius exactly around the updated
  /// centre instead of bounding it: constant work per node, and much tighter spheres near
  /// the leaves, where most visited nodes are. 0 measures only leaves.
  int exact_radius_points = 64;
};

/// How the spheres of a cycle are obtained.
enum class SphereUpdate {
  /// From each cluster's goal transform and deviation bound (the paper's section 5.2 with
  /// the errata of docs/design.md): constant time per node, only for the nodes a query
  /// visits.
  kDeformation,
  /// Smallest enclosing sphere of the node's current points, for the nodes a query
  /// visits: the tightest wrapped spheres, at a cost linear in the points under a node.
  kExactRefit,
  /// Every node refitted bottom-up when the cycle begins (leaves around their points,
  /// parents around their children): the classic O(n) refit.
  kBottomUpRefit,
};

/// Rest-shape data of one node. Offsets are in the cluster's centred coordinates
/// (x - x_cm^0, docs/design.md, erratum 1), except for an object root over several clusters.
struct SphereNode {
  Eigen::Vector3d rest_center = Eigen::Vector3d::Zero();  ///< c^0 - x_cm^0 of its cluster.
  double rest_radius_m = 0.0;                             ///< r^0.
  double quadratic_extent_m2 = 0.0;                       ///< q_max of the paper's eq. 13, centred.
  double mixed_extent_m2 = 0.0;                           ///< m_max of eq. 14, with erratum 2.
  std::uint32_t first_child = 0;
  std::uint32_t child_count = 0;
  std::uint32_t first_point = 0;  ///< Range of the node's points in pointIndices().
  std::uint32_t point_count = 0;
  /// Range of the leaves under the node in leaf order (SphereTree::leafNode); a leaf's
  /// first_leaf is its own place in that order.
  std::uint32_t first_leaf = 0;
  std::uint32_t leaf_count = 0;
  std::int32_t cluster = -1;  ///< -1 for an object root over several clusters.
  std::uint16_t level = 0;    ///< 0 at the root.
  bool isLeaf() const { return child_count == 0; }
};

/// What a traversal reads of one node, in one cache line: its sphere in the current cycle
/// and where its children and points are.
struct alignas(64) NodeState {
  Sphere sphere;
  std::uint32_t first_child = 0;
  std::uint32_t child_count = 0;
  std::uint32_t first_point = 0;
  std::uint32_t point_count = 0;
  std::uint32_t first_leaf = 0;
  std::uint32_t leaf_count = 0;
  std::uint16_t level = 0;
  bool isLeaf() const { return child_count == 0; }

 private:
  friend class SphereTree;
  std::uint32_t stamp = 0;  ///< The cycle of `sphere`.
};

/// Whether a descent to `level` ends at `node` (a SphereNode or a NodeState): the node sits
/// at that level, or is a leaf above it and stands for itself. The nodes where descents
/// from the root end are the level's cut: every point lies under exactly one of them.
template <typename Node>
bool endsDescentToLevel(const Node& node, int level) {
  // Bitwise or: branch-free in queries, where the outcome is a coin toss.
  return node.isLeaf() | (static_cast<int>(node.level) >= level);
}

/// Points' positions by slot of a tree's pointIndices(), one row per coordinate, so that
/// a leaf's coordinates are contiguous.
using SlotPositions = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor>;

/// The current spheres of a tree's leaves in leaf order, one array per coordinate, so that
/// a leaf can be tested against several others at once.
struct LeafSpheres {
  std::vector<double> x, y, z, radius;
};

/// Counts of one cycle's sphere work.
struct SphereTreeCounters {
  std::size_t spheres_updated = 0;
  std::size_t norm_evaluations = 0;  ///< Spectral norms computed (clusters touched).
};

/// Bounding sphere hierarchy of one ShapeMatchingBody, built once on its rest shape:
/// balanced (children split a node's points into equal parts along its longest axis),
/// wrapped (a node's sphere encloses its own points, not its children's spheres) and with
/// one branch per cluster under the object's root. The body must outlive the tree.
///
/// Each cycle, spheres are computed when first asked for (sphere()), so a query that
/// stops early touches only what it needs. Every point lies inside the sphere of every
/// node that holds it, whatever the deformation: the deformation update adds each
/// cluster's exact goal deviation bound (docs/design.md, erratum 3) and a relative rounding margin.
class SphereTree {
 public:
  /// A tree's buckets are its nodes of at most this many leaves with no such node above
  /// them: a query to the leaves tests the leaves of two buckets all against all.
  static constexpr std::uint32_t kBucketLeaves = 8;

  /// @throw std::invalid_argument if branching < 2, leaf_size < 1 or exact_radius_points < 0.
  SphereTree(const ShapeMatchingBody& body, const SphereTreeConfig& config);

  /// Starts a cycle on the body's current state: spheres computed before are stale.
  /// kBottomUpRefit refits every node now.
  void beginCycle(SphereUpdate method = SphereUpdate::kDeformation);

  /// The node's sphere in the current cycle, computed on first use.
  const Sphere& sphere(std::uint32_t node) { return current(node).sphere; }

  /// The node's state with its sphere in the current cycle, computed on first use: all a
  /// traversal reads of the node.
  const NodeState& current(std::uint32_t node) {
    // Queries ask for the same spheres many times a cycle; only the first ask computes.
    return states_[node].stamp == cycle_ ? states_[node] : updateSphere(node);
  }

  /// current(), and if the node has at most `leaf_limit` leaves, the spheres and point
  /// columns (leafPositions()) of all its leaves too, from one pass over its points. For a
  /// query that will test a small node's leaves whenever it reaches the node: measured one
  /// by one, each point would be read for the node and again for its leaf.
  const NodeState& current(std::uint32_t node, std::uint32_t leaf_limit) {
    const NodeState& state = states_[node];
    if (state.stamp == cycle_ && (state.leaf_count > leaf_limit || state.isLeaf() ||
                                  leaves_current_stamps_[node] == cycle_)) {
      return state;
    }
    return updateWithLeaves(node, leaf_limit);
  }

  /// Asks the memory for what current() of the node's children reads: a descent reaches
  /// them soon after the node, and otherwise waits on each in turn.
  void prefetchChildren(std::uint32_t node) const {
    const NodeState& state = states_[node];
    for (std::uint32_t c = state.first_child; c < state.first_child + state.child_count; ++c) {
      __builtin_prefetch(&states_[c]);
      __builtin_prefetch(&nodes_[c]);
    }
  }

  /// Whether current(node, leaf_limit) would pass over the node's points: a node of at most
  /// `leaf_limit` leaves that is not yet current with its leaves in this cycle.
  bool measuresPoints(std::uint32_t node, std::uint32_t leaf_limit) const {
    const NodeState& state = states_[node];
    return state.leaf_count <= leaf_limit && !state.isLeaf() &&
           leaves_current_stamps_[node] != cycle_;
  }

  /// A sphere around the node's points in the current cycle that reads none of them: with
  /// kDeformation, the bound of the paper's eq. 13/14 (docs/design.md, erratum 3) around the
  /// node's deformed centre, as a rule wider than its measured sphere; otherwise its sphere.
  /// A query rules a node out with it before paying for measuring the node's points.
  Sphere boundWithoutPoints(std::uint32_t node);

  /// The current positions of the leaves' points, one row per coordinate, a column per
  /// slot of pointIndices(), so that a leaf's coordinates are contiguous. A leaf's columns
  /// are valid once current() returned its state in this cycle.
  const SlotPositions& leafPositions() const { return slot_positions_; }

  /// The leaves' current spheres by leaf order. A leaf's entry is valid once current()
  /// returned its state in this cycle.
  const LeafSpheres& leafSpheres() const { return leaf_spheres_; }
  /// The node of the leaf at `ordinal` in leaf order (the order of their points): the
  /// leaves under any node are a contiguous range of that order.
  std::uint32_t leafNode(std::uint32_t ordinal) const { return leaf_nodes_[ordinal]; }
  /// The level of the leaf at `ordinal` in leaf order: a contact's level without reading
  /// the leaf's node.
  std::uint16_t leafLevel(std::uint32_t ordinal) const { return leaf_levels_[ordinal]; }
  /// The buckets (see kBucketLeaves), in leaf order.
  const std::vector<std::uint32_t>& buckets() const { return buckets_; }
  /// The points of the leaf at `ordinal` in leaf order are the slots from
  /// leafSlotStarts()[ordinal] up to leafSlotStarts()[ordinal + 1].
  const std::vector<std::uint32_t>& leafSlotStarts() const { return leaf_slot_starts_; }

  /// Node `index`; 0 is the root, and children always come after their parent.
  const SphereNode& node(std::uint32_t index) const { return nodes_[index]; }
  std::size_t nodeCount() const { return nodes_.size(); }
  /// Deepest level; leaves may also sit higher in smaller clusters.
  int maxLevel() const { return max_level_; }
  /// Body point index of each node slot; a node's points are a contiguous range.
  const std::vector<std::uint32_t>& pointIndices() const { return point_indices_; }
  const ShapeMatchingBody& body() const { return *body_; }
  const SphereTreeCounters& counters() const { return counters_; }

 private:
  struct ClusterNorms {
    double linear = 1.0;
    double quadratic = 0.0;
    double mixed = 0.0;
    std::uint32_t stamp = 0;
  };

  void build(const SphereTreeConfig& config);
  /// The clusters' points, cluster by cluster, in pointIndices() with their cluster slots.
  void gatherClusterPoints();
  /// The object's root (if it has several clusters) and one branch per cluster; returns
  /// the first branch's index.
  std::uint32_t addRootAndBranches();
  /// The buffers the build reuses from node to node (sphere_tree_build.cpp).
  struct BuildScratch;
  /// Orders the node's slots along the longest axis of its points' rest box: sorted if
  /// `sort_children` (children that are leaves keep the order), else only as far as each of
  /// `children` equal parts holds its own points.
  void splitAlongLongestAxis(const SphereNode& node, std::uint32_t children, bool sort_children,
                             BuildScratch& scratch);
  Eigen::Index longestAxis(const SphereNode& node) const;
  /// Slot i of the node takes what was slot scratch.order[i] of it.
  void applyOrder(const SphereNode& node, BuildScratch& scratch);
  /// Splits the node's slots into `children` equal parts (at most its point count), one
  /// child each.
  void addChildren(std::uint32_t index, std::uint32_t children);
  void computeRestData(std::uint32_t index);
  const NodeState& updateSphere(std::uint32_t index);
  const NodeState& updateWithLeaves(std::uint32_t index, std::uint32_t leaf_limit);
  void measureWithLeaves(std::uint32_t index);
  double boundRadius(const SphereNode& node, const ClusterDeformation& deformation);
  const ClusterNorms& norms(std::size_t cluster);
  Sphere deformationSphere(std::uint32_t index);
  Sphere exactSphere(std::uint32_t index);
  Sphere spanningSphere(std::uint32_t index);
  void setSphere(std::uint32_t index, const Sphere& sphere);
  void orderLeaves();
  void refitBottomUp();

  const ShapeMatchingBody* body_;
  std::vector<SphereNode> nodes_;
  std::vector<std::uint32_t> point_indices_;
  std::vector<std::uint32_t> point_slots_;  ///< Slot of each point in its node's cluster.
  /// While building only, per slot of point_indices_: the rest point and its offset in its
  /// cluster, moved with the slots, so that the build reads them in order, not scattered
  /// over the body (in a large object each such read missed the cache).
  std::vector<Eigen::Vector3d> build_points_;
  std::vector<Eigen::Vector3d> build_offsets_;
  int max_level_ = 0;

  SphereUpdate method_ = SphereUpdate::kDeformation;
  std::uint32_t cycle_ = 1;
  std::vector<NodeState> states_;
  /// Per node, the cycle in which its leaves were all last made current with it (as opposed
  /// to leaf_stamps_, one per leaf).
  std::vector<std::uint32_t> leaves_current_stamps_;
  std::vector<ClusterNorms> cluster_norms_;
  /// Visited leaves' positions in slot order, copied where a leaf's sphere is computed: the
  /// leaf-pair tests read each coordinate of a leaf contiguously, several points per
  /// instruction.
  SlotPositions slot_positions_;
  // By leaf order, what the pass over a small node's leaves and the leaf-pair tests read of
  // a leaf, without a cache line of its own per leaf.
  LeafSpheres leaf_spheres_;
  std::vector<std::uint32_t> leaf_nodes_;
  std::vector<std::uint16_t> leaf_levels_;
  std::vector<std::uint32_t> leaf_slot_starts_;
  std::vector<Eigen::Vector3d> leaf_rest_centers_;
  /// The cycle of each leaf's entry in leaf_spheres_; a leaf's NodeState may be older and
  /// is then copied from there when asked for.
  std::vector<std::uint32_t> leaf_stamps_;
  std::vector<std::uint32_t> buckets_;
  std::vector<Eigen::Vector3d> scratch_points_;
  EnclosingSphereScratch scratch_sphere_;
  std::vector<Sphere> scratch_spheres_;
  std::uint32_t exact_radius_points_ = 0;
  /// Whether measureWithLeaves gathers a leaf's points eight per instruction.
  bool gather_wide_ = false;
  SphereTreeCounters counters_;
};

}  // namespace deformable_collision
