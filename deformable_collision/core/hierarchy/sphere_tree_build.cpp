// The construction of a SphereTree (paper section 5.1): one branch per cluster, balanced,
// each node's rest sphere the smallest around its own points.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/hierarchy/sphere_tree.h"

namespace deformable_collision {
namespace {

/// Leaves under the largest node of at most SphereTree::kBucketLeaves leaves, for a branch
/// whose `depth` levels split in `wide` at the top `wide_levels` and in `narrow` below.
std::uint64_t bucketLeaves(int depth, int wide_levels, std::uint64_t narrow, std::uint64_t wide) {
  std::uint64_t leaves = 1;
  for (int level = depth - 1; level >= 0; --level) {
    const std::uint64_t split = level < wide_levels ? wide : narrow;
    if (leaves * split > SphereTree::kBucketLeaves) break;
    leaves *= split;
  }
  return leaves;
}

/// The child counts, level by level, under a cluster's branch of `points` points: every
/// node of a level splits into that many equal parts, so the branch ends in as many leaves
/// as the counts' product, all on one level, each within one point of the others (where
/// it has at least as many points as leaves: with leaf_size below branching it may not). Halving
/// alone ends in the next power of two above points / leaf_size leaves, which leaves them
/// half full for a cluster of just over a power of two times leaf_size points, and a query
/// to the leaves pays per leaf pair. The counts are `branching` or `branching + 1`, the
/// wider levels first, so that the levels above the leaves, which make the query's buckets,
/// split in `branching`. Of the products that keep leaves at most `leaf_size` points, the
/// least is taken unless one at most an eighth larger has larger buckets: the query pays
/// per bucket pair as well as per leaf pair, and splits in three all the way down end in
/// buckets of three leaves (a cluster of 5,500 points: 729 leaves in buckets of 3, or 768
/// in buckets of 8).
std::vector<std::uint32_t> levelChildCounts(std::uint32_t points, std::uint32_t leaf_size,
                                            std::uint32_t branching) {
  const std::uint64_t narrow = branching;
  const std::uint64_t wide = narrow + 1;
  const std::uint64_t least_leaves = (std::uint64_t{points} + leaf_size - 1) / leaf_size;
  struct Split {
    std::uint64_t leaves;
    int depth;
    int wide_levels;
  };
  // At each depth the fewest wide levels that reach least_leaves: more wide levels there
  // only add leaves and narrow the buckets. Of `depth` levels, `wide_levels` split in
  // branching + 1: narrow^(depth - wide_levels) * wide^wide_levels leaves, computed by
  // trading one narrow factor for a wide one at a time.
  std::vector<Split> splits;
  std::uint64_t all_narrow = 1;
  for (int depth = 1; all_narrow < least_leaves; ++depth) {
    all_narrow *= narrow;
    std::uint64_t leaves = all_narrow;
    for (int wide_levels = 0; wide_levels <= depth; ++wide_levels) {
      if (leaves >= least_leaves) {
        splits.push_back({leaves, depth, wide_levels});
        break;
      }
      if (wide_levels < depth) leaves = leaves / narrow * wide;
    }
  }
  if (splits.empty()) return {};
  std::uint64_t fewest = splits.front().leaves;
  for (const Split& split : splits) fewest = std::min(fewest, split.leaves);
  const Split* best = nullptr;
  std::uint64_t best_bucket = 0;
  for (const Split& split : splits) {
    if (8 * split.leaves > 9 * fewest) continue;
    const std::uint64_t bucket = bucketLeaves(split.depth, split.wide_levels, narrow, wide);
    if (!best || bucket > best_bucket || (bucket == best_bucket && split.leaves < best->leaves)) {
      best = &split;
      best_bucket = bucket;
    }
  }
  std::vector<std::uint32_t> counts(static_cast<std::size_t>(best->depth), branching);
  std::fill_n(counts.begin(), best->wide_levels, branching + 1);
  return counts;
}

}  // namespace

SphereTree::SphereTree(const ShapeMatchingBody& body, const SphereTreeConfig& config)
    : body_(&body) {
  if (config.branching < 2) {
    throw std::invalid_argument("SphereTreeConfig.branching = " + std::to_string(config.branching) +
                                " must be >= 2");
  }
  if (config.leaf_size < 1) {
    throw std::invalid_argument("SphereTreeConfig.leaf_size = " + std::to_string(config.leaf_size) +
                                " must be >= 1");
  }
  if (config.exact_radius_points < 0) {
    throw std::invalid_argument("SphereTreeConfig.exact_radius_points = " +
                                std::to_string(config.exact_radius_points) + " must be >= 0");
  }
  exact_radius_points_ = static_cast<std::uint32_t>(config.exact_radius_points);
  // The gather addresses a coordinate by a 32-bit signed offset.
  gather_wide_ = wideVectorsAvailable() && 3 * body.pointCount() <= 0x7FFFFFFFu;
  build(config);
  orderLeaves();
  states_.resize(nodes_.size());
  leaves_current_stamps_.assign(nodes_.size(), 0);
  std::size_t most_children = 0;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const SphereNode& node = nodes_[i];
    NodeState& state = states_[i];
    state.first_child = node.first_child;
    state.child_count = node.child_count;
    state.first_point = node.first_point;
    state.point_count = node.point_count;
    state.first_leaf = node.first_leaf;
    state.leaf_count = node.leaf_count;
    state.level = node.level;
    most_children = std::max<std::size_t>(most_children, node.child_count);
  }
  slot_positions_.setZero(3, static_cast<Eigen::Index>(point_indices_.size()));
  cluster_norms_.resize(body.clusterCount());
  scratch_spheres_.reserve(most_children);
  std::size_t largest_node = 0;
  for (const auto& node : nodes_)
    largest_node = std::max<std::size_t>(largest_node, node.point_count);
  scratch_points_.reserve(largest_node);
  scratch_sphere_.order.reserve(largest_node);
  scratch_sphere_.shuffled.reserve(largest_node);
}

namespace {

/// A slot's place along a split's axis. Ties go by point index: the order is total.
struct SplitKey {
  double coordinate;
  std::uint32_t point;
  std::uint32_t slot;
};

}  // namespace

// Kept from node to node: fresh buffers for a large node are fresh pages, each faulted in.
struct SphereTree::BuildScratch {
  std::vector<SplitKey> keys;
  std::vector<std::uint32_t> order;
  std::vector<std::uint32_t> indices;
  std::vector<Eigen::Vector3d> points;
};

void SphereTree::build(const SphereTreeConfig& config) {
  gatherClusterPoints();
  const std::uint32_t first_branch = addRootAndBranches();
  const int branch_level = nodes_[first_branch].level;
  BuildScratch scratch;
  std::vector<std::vector<std::uint32_t>> cluster_child_counts;
  for (std::size_t k = 0; k < body_->clusterCount(); ++k) {
    cluster_child_counts.push_back(levelChildCounts(nodes_[first_branch + k].point_count,
                                                    static_cast<std::uint32_t>(config.leaf_size),
                                                    static_cast<std::uint32_t>(config.branching)));
  }
  // Breadth first: children go to the end of nodes_, so walking nodes_ in order visits
  // each node after its parent and splits every node added on the way.
  for (std::uint32_t index = first_branch; index < nodes_.size(); ++index) {
    const SphereNode& node = nodes_[index];
    max_level_ = std::max<int>(max_level_, node.level);
    const auto& child_counts = cluster_child_counts[static_cast<std::size_t>(node.cluster)];
    const auto depth = static_cast<std::size_t>(node.level - branch_level);
    if (depth >= child_counts.size() || node.point_count < 2) continue;
    const std::uint32_t children = std::min(child_counts[depth], node.point_count);
    // Splits below reorder the children's points, so only leaves need them sorted: a split
    // is linear in the node's points, a sort n log n.
    splitAlongLongestAxis(node, children, depth + 1 >= child_counts.size(), scratch);
    addChildren(index, children);
  }
  for (std::uint32_t i = 0; i < nodes_.size(); ++i) computeRestData(i);
  std::vector<Eigen::Vector3d>().swap(build_points_);
  std::vector<Eigen::Vector3d>().swap(build_offsets_);
}

void SphereTree::gatherClusterPoints() {
  const ShapeMatchingBody& body = *body_;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const Cluster& cluster = body.cluster(k);
    for (std::uint32_t slot = 0; slot < cluster.points.size(); ++slot) {
      point_indices_.push_back(cluster.points[slot]);
      point_slots_.push_back(slot);
      build_points_.push_back(body.restPositions()[cluster.points[slot]]);
      build_offsets_.push_back(cluster.rest_offsets[slot]);
    }
  }
}

std::uint32_t SphereTree::addRootAndBranches() {
  const ShapeMatchingBody& body = *body_;
  const std::size_t cluster_count = body.clusterCount();
  // One cluster is its own object's root; several share a root over all their points.
  if (cluster_count > 1) {
    SphereNode root;
    root.point_count = static_cast<std::uint32_t>(point_indices_.size());
    root.first_child = 1;
    root.child_count = static_cast<std::uint32_t>(cluster_count);
    nodes_.push_back(root);
  }
  std::uint32_t offset = 0;
  for (std::size_t k = 0; k < cluster_count; ++k) {
    SphereNode branch;
    branch.cluster = static_cast<std::int32_t>(k);
    branch.level = cluster_count > 1 ? 1 : 0;
    branch.first_point = offset;
    branch.point_count = static_cast<std::uint32_t>(body.cluster(k).points.size());
    offset += branch.point_count;
    nodes_.push_back(branch);
  }
  return cluster_count > 1 ? 1 : 0;
}

void SphereTree::splitAlongLongestAxis(const SphereNode& node, std::uint32_t children,
                                       bool sort_children, BuildScratch& scratch) {
  const auto begin = static_cast<std::ptrdiff_t>(node.first_point);
  const Eigen::Index axis = longestAxis(node);
  // Slots move with their points: order a permutation of the range, then apply it. With
  // ties by point index, each child gets the same points whether the range is sorted or only
  // split at the children's bounds. The keys lie side by side: compared through the slots,
  // most reads of a large node missed the cache; the algorithms see the same comparisons
  // either way, so they leave the same order.
  std::vector<SplitKey>& keys = scratch.keys;
  keys.resize(node.point_count);
  for (std::uint32_t i = 0; i < node.point_count; ++i) {
    keys[i] = {build_points_[begin + i][axis], point_indices_[begin + i], i};
  }
  const auto before = [](const SplitKey& a, const SplitKey& b) {
    return a.coordinate < b.coordinate || (a.coordinate == b.coordinate && a.point < b.point);
  };
  if (sort_children) {
    std::sort(keys.begin(), keys.end(), before);
  } else {
    for (std::uint32_t c = 1; c < children; ++c) {
      std::nth_element(keys.begin() + node.point_count * (c - 1) / children,
                       keys.begin() + node.point_count * c / children, keys.end(), before);
    }
  }
  scratch.order.resize(node.point_count);
  for (std::uint32_t i = 0; i < node.point_count; ++i) scratch.order[i] = keys[i].slot;
  applyOrder(node, scratch);
}

Eigen::Index SphereTree::longestAxis(const SphereNode& node) const {
  Eigen::AlignedBox3d box;
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    box.extend(build_points_[s]);
  }
  Eigen::Index axis = 0;
  box.sizes().maxCoeff(&axis);
  return axis;
}

namespace {

/// Slot first + i of `values` takes what was slot first + order[i], through `ordered`.
template <typename T>
void permute(std::vector<T>& values, std::size_t first, const std::vector<std::uint32_t>& order,
             std::vector<T>& ordered) {
  ordered.resize(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) ordered[i] = values[first + order[i]];
  std::copy(ordered.begin(), ordered.end(), values.begin() + first);
}

}  // namespace

void SphereTree::applyOrder(const SphereNode& node, BuildScratch& scratch) {
  permute(point_indices_, node.first_point, scratch.order, scratch.indices);
  permute(point_slots_, node.first_point, scratch.order, scratch.indices);
  permute(build_points_, node.first_point, scratch.order, scratch.points);
  permute(build_offsets_, node.first_point, scratch.order, scratch.points);
}

void SphereTree::addChildren(std::uint32_t index, std::uint32_t children) {
  // A copy: adding the children may move nodes_.
  const SphereNode parent = nodes_[index];
  nodes_[index].first_child = static_cast<std::uint32_t>(nodes_.size());
  nodes_[index].child_count = children;
  for (std::uint32_t c = 0; c < children; ++c) {
    SphereNode child;
    child.cluster = parent.cluster;
    child.level = static_cast<std::uint16_t>(parent.level + 1);
    const std::uint32_t from = parent.point_count * c / children;
    const std::uint32_t to = parent.point_count * (c + 1) / children;
    child.first_point = parent.first_point + from;
    child.point_count = to - from;
    nodes_.push_back(child);
  }
}

void SphereTree::orderLeaves() {
  // A node's points are a contiguous slot range, and its leaves split that range: in the
  // order of their first slots, the leaves under any node follow each other.
  for (std::uint32_t i = 0; i < nodes_.size(); ++i) {
    if (nodes_[i].isLeaf()) leaf_nodes_.push_back(i);
  }
  std::sort(leaf_nodes_.begin(), leaf_nodes_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return nodes_[a].first_point < nodes_[b].first_point;
  });
  std::vector<std::uint32_t> leaf_starts(leaf_nodes_.size());
  for (std::uint32_t k = 0; k < leaf_nodes_.size(); ++k)
    leaf_starts[k] = nodes_[leaf_nodes_[k]].first_point;
  for (SphereNode& node : nodes_) {
    const auto first = std::lower_bound(leaf_starts.begin(), leaf_starts.end(), node.first_point);
    const auto last =
        std::lower_bound(first, leaf_starts.end(), node.first_point + node.point_count);
    node.first_leaf = static_cast<std::uint32_t>(first - leaf_starts.begin());
    node.leaf_count = static_cast<std::uint32_t>(last - first);
  }
  for (auto* values :
       {&leaf_spheres_.x, &leaf_spheres_.y, &leaf_spheres_.z, &leaf_spheres_.radius}) {
    values->assign(leaf_nodes_.size(), 0.0);
  }
  leaf_slot_starts_ = leaf_starts;
  leaf_slot_starts_.push_back(static_cast<std::uint32_t>(point_indices_.size()));
  for (const std::uint32_t leaf : leaf_nodes_) {
    leaf_rest_centers_.push_back(nodes_[leaf].rest_center);
    leaf_levels_.push_back(nodes_[leaf].level);
  }
  leaf_stamps_.assign(leaf_nodes_.size(), 0);
  // Depth first, children in order: the buckets come in leaf order.
  std::vector<std::uint32_t> pending{0};
  while (!pending.empty()) {
    const SphereNode& node = nodes_[pending.back()];
    const std::uint32_t index = pending.back();
    pending.pop_back();
    if (node.leaf_count <= kBucketLeaves) {
      buckets_.push_back(index);
      continue;
    }
    for (std::uint32_t c = node.first_child + node.child_count; c-- > node.first_child;) {
      pending.push_back(c);
    }
  }
}

void SphereTree::setSphere(std::uint32_t index, const Sphere& sphere) {
  NodeState& state = states_[index];
  state.sphere = sphere;
  state.stamp = cycle_;
  if (state.child_count > 0) return;
  leaf_stamps_[state.first_leaf] = cycle_;
  leaf_spheres_.x[state.first_leaf] = sphere.center.x();
  leaf_spheres_.y[state.first_leaf] = sphere.center.y();
  leaf_spheres_.z[state.first_leaf] = sphere.center.z();
  leaf_spheres_.radius[state.first_leaf] = sphere.radius;
}

void SphereTree::computeRestData(std::uint32_t index) {
  SphereNode& node = nodes_[index];
  const auto& points = node.cluster < 0 ? build_points_ : build_offsets_;
  scratch_points_.assign(points.begin() + node.first_point,
                         points.begin() + node.first_point + node.point_count);
  const Sphere rest = smallestEnclosingSphere(scratch_points_, scratch_sphere_);
  node.rest_center = rest.center;
  node.rest_radius_m = rest.radius;
  if (node.cluster < 0) return;
  const Eigen::Vector3d& c = rest.center;
  double quadratic_squared = 0.0;
  double mixed_squared = 0.0;
  for (const auto& q : scratch_points_) {
    const Eigen::Vector3d squares(q.x() * q.x() - c.x() * c.x(), q.y() * q.y() - c.y() * c.y(),
                                  q.z() * q.z() - c.z() * c.z());
    const Eigen::Vector3d mixed(q.x() * q.y() - c.x() * c.y(), q.y() * q.z() - c.y() * c.z(),
                                q.z() * q.x() - c.z() * c.x());
    quadratic_squared = std::max(quadratic_squared, squares.squaredNorm());
    mixed_squared = std::max(mixed_squared, mixed.squaredNorm());
  }
  // One root each: a rounded root is monotone, so it is the largest of the points' norms.
  node.quadratic_extent_m2 = std::sqrt(quadratic_squared);
  node.mixed_extent_m2 = std::sqrt(mixed_squared);
}

}  // namespace deformable_collision
