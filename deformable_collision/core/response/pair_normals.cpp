// The normal of a contact between two dynamic objects: the direction that best separates
// the two sides' contact nodes.
#include <Eigen/Cholesky>
#include <algorithm>
#include <limits>

#include "deformable_collision/core/response/detail/pair_normals.h"
#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {
namespace detail {
namespace {

/// Mean and scatter of points, taken about an origin near them (coordinates may be 1e5 m).
class PointMoments {
 public:
  explicit PointMoments(const Eigen::Vector3d& origin) : origin_(origin) {}
  /// A node's points, `times` over: a leaf's, where the query measured them this cycle,
  /// else its centre.
  void addNode(SphereTree& tree, std::uint32_t node, bool measured_leaf, std::uint32_t times) {
    if (!measured_leaf) {
      const Eigen::Vector3d& c = tree.sphere(node).center;
      addPoints(&c.x(), &c.y(), &c.z(), 1, times);
      return;
    }
    const SphereNode& leaf = tree.node(node);
    const auto& positions = tree.leafPositions();
    addPoints(&positions(0, leaf.first_point), &positions(1, leaf.first_point),
              &positions(2, leaf.first_point), leaf.point_count, times);
  }
  Eigen::Vector3d mean() const { return Eigen::Vector3d(sum_[0], sum_[1], sum_[2]) / count_; }
  Eigen::Matrix3d scatter() const {
    Eigen::Matrix3d squares;
    squares << products_[0], products_[3], products_[5],  //
        products_[3], products_[1], products_[4],         //
        products_[5], products_[4], products_[2];
    const Eigen::Vector3d m = mean();
    return squares / count_ - m * m.transpose();
  }

 private:
  /// `count` points from coordinate arrays (a leaf's columns, or one point's coordinates),
  /// `times` over.
  void addPoints(const double* xs, const double* ys, const double* zs, std::uint32_t count,
                 std::uint32_t times) {
    // Nine separate sums: one running matrix through every point would chain each point's
    // additions to the last point's.
    double sum[3] = {}, products[6] = {};
    for (std::uint32_t s = 0; s < count; ++s) {
      const double x = xs[s] - origin_.x(), y = ys[s] - origin_.y(), z = zs[s] - origin_.z();
      sum[0] += x;
      sum[1] += y;
      sum[2] += z;
      products[0] += x * x;
      products[1] += y * y;
      products[2] += z * z;
      products[3] += x * y;
      products[4] += y * z;
      products[5] += z * x;
    }
    for (int r = 0; r < 3; ++r) sum_[r] += times * sum[r];
    for (int r = 0; r < 6; ++r) products_[r] += times * products[r];
    count_ += times * count;
  }

  Eigen::Vector3d origin_;
  double sum_[3] = {};
  double products_[6] = {};  ///< xx, yy, zz, xy, yz, zx.
  double count_ = 0.0;
};

/// The contact nodes of one side of an object pair, each once, with the number of the
/// pair's contacts it takes part in: leaves take part in a few contacts each, and their
/// points are then read once.
struct ContactNodes {
  SphereTree& tree;
  const std::vector<std::uint32_t>& nodes;
  const std::vector<std::uint32_t>& contacts_of_node;
};

/// The direction from b's contact nodes to a's, for the contacts of one object pair, each
/// node weighted by its contacts. At the leaves it is the one that best separates the two
/// sides' points (Fisher's discriminant): the difference of their means, shrunk along the
/// directions in which the points spread. A flat contact's points spread along the face, so
/// its normal comes out even when a handful of contacts, scattered across the face, are all
/// there is; the plain difference of the means tilts with them. `regularisation_m2` keeps
/// it defined for one contact. Above the leaves only the nodes' centres stand for their
/// points, and those of large nodes spread through the objects rather than along the face:
/// there it is the difference of the means. Not normalised; zero if the means coincide.
Eigen::Vector3d separatingDirection(const ContactNodes& a, const ContactNodes& b, bool leaves,
                                    double regularisation_m2) {
  const Eigen::Vector3d origin = a.tree.sphere(a.nodes.front()).center;
  PointMoments side_a(origin);
  PointMoments side_b(origin);
  for (const std::uint32_t node : a.nodes) {
    side_a.addNode(a.tree, node, leaves, a.contacts_of_node[node]);
  }
  for (const std::uint32_t node : b.nodes) {
    side_b.addNode(b.tree, node, leaves, b.contacts_of_node[node]);
  }
  const Eigen::Vector3d apart = side_a.mean() - side_b.mean();
  if (!leaves) return apart;
  const Eigen::Matrix3d scatter =
      side_a.scatter() + side_b.scatter() + regularisation_m2 * Eigen::Matrix3d::Identity();
  return scatter.ldlt().solve(apart);
}

/// How far the points of a leaf that a query visited this cycle reach along `direction`.
double reachAlong(const SphereTree& tree, std::uint32_t leaf, const Eigen::Vector3d& direction) {
  const SphereNode& node = tree.node(leaf);
  const auto& positions = tree.leafPositions();
  const double* xs = &positions(0, node.first_point);
  const double* ys = &positions(1, node.first_point);
  const double* zs = &positions(2, node.first_point);
  double reach = -std::numeric_limits<double>::infinity();
  for (std::uint32_t s = 0; s < node.point_count; ++s) {
    reach = std::max(reach, xs[s] * direction.x() + ys[s] * direction.y() + zs[s] * direction.z());
  }
  return reach;
}

}  // namespace

void PairNormals::clear(std::size_t runs, std::size_t contacts) {
  added_.clear();
  measured_.resize(runs);
  reach_a_.resize(contacts);
  reach_b_.resize(contacts);
}

void PairNormals::add(std::uint32_t run, const Eigen::Vector3d& side_of_a) {
  added_.push_back(run);
  measured_[run].side_of_a = side_of_a;
}

void PairNormals::measure(WorkerPool& pool, Objects& objects,
                          const std::vector<SceneContact>& contacts,
                          const std::vector<ContactRun>& runs, double contact_distance_m) {
  const bool shared = pool.threads() > 1 && added_.size() >= kRunsWorthSharing;
  if (shared) computeSpheresRead(objects, contacts, runs);
  const auto threads = static_cast<std::size_t>(pool.threads());
  if (lanes_.size() < threads) lanes_.resize(threads);
  const auto measure_run = [&](std::size_t i, std::size_t lane) {
    measureRun(i, lanes_[lane], objects, contacts, runs, contact_distance_m);
  };
  if (shared) {
    pool.forEachOnLane(added_.size(), measure_run);
  } else {
    for (std::size_t i = 0; i < added_.size(); ++i) measure_run(i, 0);
  }
}

// Between two dynamic objects every push goes along one normal: the direction that
// separates a's contact nodes from b's, turned to agree with the side a lies on. Nearest
// point pairs of two clouds point every which way, and more so once the clouds have passed
// into each other; the two sides of the contact do not.
void PairNormals::measureRun(std::size_t index, Lane& lane, Objects& objects,
                             const std::vector<SceneContact>& contacts,
                             const std::vector<ContactRun>& runs, double contact_distance_m) {
  const ContactRun& run = runs[added_[index]];
  Measured& measured = measured_[added_[index]];
  SphereTree& tree_a = objects[run.object_a]->tree;
  SphereTree& tree_b = objects[run.object_b]->tree;
  lane.a.fit(tree_a.nodeCount());
  lane.b.fit(tree_b.nodeCount());
  for (std::size_t k = run.begin; k < run.end; ++k) {
    const SphereContact& c = contacts[k].contact;
    // Where a node's points lie is read below, from node records the query did not touch:
    // asked for now, their cache misses overlap instead of coming one node at a time.
    if (lane.a.contacts_of_node[c.node_a]++ == 0) {
      lane.a.nodes.push_back(c.node_a);
      __builtin_prefetch(&tree_a.node(c.node_a).first_point);
    }
    if (lane.b.contacts_of_node[c.node_b]++ == 0) {
      lane.b.nodes.push_back(c.node_b);
      __builtin_prefetch(&tree_b.node(c.node_b).first_point);
    }
  }
  const bool leaves = contacts[run.begin].contact.point_a != SphereContact::kNoPoint;
  const double spread = 0.1 * contact_distance_m;
  const Eigen::Vector3d across =
      separatingDirection({tree_a, lane.a.nodes, lane.a.contacts_of_node},
                          {tree_b, lane.b.nodes, lane.b.contacts_of_node}, leaves, spread * spread);
  Eigen::Vector3d normal = measured.side_of_a;
  if (across.squaredNorm() > 0.0) {
    normal = across.dot(measured.side_of_a) < 0.0 ? Eigen::Vector3d(-across) : across;
  }
  const double length = normal.norm();
  measured.normal = length > 0.0 ? Eigen::Vector3d(normal / length) : Eigen::Vector3d::UnitZ();
  if (leaves) {
    for (const std::uint32_t node : lane.a.nodes) {
      lane.a.reach_of_node[node] = reachAlong(tree_a, node, -measured.normal);
    }
    for (const std::uint32_t node : lane.b.nodes) {
      lane.b.reach_of_node[node] = reachAlong(tree_b, node, measured.normal);
    }
    for (std::size_t k = run.begin; k < run.end; ++k) {
      reach_a_[k] = lane.a.reach_of_node[contacts[k].contact.node_a];
      reach_b_[k] = lane.b.reach_of_node[contacts[k].contact.node_b];
    }
  }
  for (const std::uint32_t node : lane.a.nodes) lane.a.contacts_of_node[node] = 0;
  for (const std::uint32_t node : lane.b.nodes) lane.b.contacts_of_node[node] = 0;
  lane.a.nodes.clear();
  lane.b.nodes.clear();
}

// The query reads a leaf's points through its bucket's columns and may leave the leaf's own
// sphere uncomputed, and two runs with an object in common would compute it at once.
void PairNormals::computeSpheresRead(Objects& objects, const std::vector<SceneContact>& contacts,
                                     const std::vector<ContactRun>& runs) {
  for (const std::uint32_t r : added_) {
    const ContactRun& run = runs[r];
    SphereTree& tree_a = objects[run.object_a]->tree;
    SphereTree& tree_b = objects[run.object_b]->tree;
    tree_a.sphere(contacts[run.begin].contact.node_a);
    if (contacts[run.begin].contact.point_a != SphereContact::kNoPoint) continue;
    for (std::size_t k = run.begin; k < run.end; ++k) {
      tree_a.sphere(contacts[k].contact.node_a);
      tree_b.sphere(contacts[k].contact.node_b);
    }
  }
}

void PairNormals::Side::fit(std::size_t node_count) {
  if (contacts_of_node.size() >= node_count) return;
  // Outside a run every count is 0; the new ones too.
  contacts_of_node.resize(node_count, 0);
  reach_of_node.resize(node_count, 0.0);
  nodes.reserve(node_count);
}

}  // namespace detail
}  // namespace deformable_collision
