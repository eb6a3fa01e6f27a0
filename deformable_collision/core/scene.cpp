#include "deformable_collision/core/scene.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace deformable_collision {
namespace {

using Clock = std::chrono::steady_clock;

double millisecondsBetween(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

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
        products_[3], products_[1], products_[4],          //
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

struct Scene::Object {
  Object(const ObjectConfig& object_config, std::vector<Eigen::Vector3d> rest_points,
         const SphereTreeConfig& tree_config)
      : config(object_config),
        body(std::move(rest_points), object_config.shape),
        tree(body, tree_config) {
    if (config.kind == ObjectKind::kDynamic) {
      displacement_sums.assign(body.pointCount(), Eigen::Vector3d::Zero());
      velocity_change_sums.assign(body.pointCount(), Eigen::Vector3d::Zero());
      displacement_counts.assign(body.pointCount(), 0);
      // Every point may be dented some cycle: the first such cycle must not allocate either.
      displaced_points.reserve(body.pointCount());
      displacements.reserve(body.pointCount());
      contacts_of_node.assign(tree.nodeCount(), 0);
      reach_of_node.assign(tree.nodeCount(), 0.0);
      contact_nodes.reserve(tree.nodeCount());
      dent_of_node.assign(tree.nodeCount(), 0);
      dent_pair_of_node.assign(tree.nodeCount(), 0);
    }
  }

  bool dynamic() const { return config.kind == ObjectKind::kDynamic; }

  /// Rest-shape plane of every node (objects the response never moves). A node's own points
  /// may be too few to span a plane (a leaf of a two-layer floor is a small cube), so it
  /// takes the normal of its nearest ancestor that is clearly planar (16 points or more,
  /// least spread under a tenth of the middle one), or the root's. The plane is anchored at
  /// the node's sphere centre; its surfaces are where the node's own points reach from there.
  void computeNodePlanes() {
    const std::uint32_t count = static_cast<std::uint32_t>(tree.nodeCount());
    std::vector<std::uint32_t> parent(count, 0);
    for (std::uint32_t n = 0; n < count; ++n) {
      const SphereNode& node = tree.node(n);
      for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) parent[c] = n;
    }
    const auto& rest = body.restPositions();
    std::vector<Eigen::Vector3d> own_normal(count);
    std::vector<std::uint8_t> planar(count, 0);
    for (std::uint32_t n = 0; n < count; ++n) {
      const SphereNode& node = tree.node(n);
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        mean += rest[tree.pointIndices()[s]];
      }
      mean /= node.point_count;
      Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        const Eigen::Vector3d d = rest[tree.pointIndices()[s]] - mean;
        covariance += d * d.transpose();
      }
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
      own_normal[n] = solver.eigenvectors().col(0);
      // A handful of points always fits some plane (three do exactly), often a wrong one.
      planar[n] = node.point_count >= 16 && solver.eigenvalues()(0) < 0.1 * solver.eigenvalues()(1);
    }
    node_normals.resize(count);
    node_extent_along.resize(count);
    node_extent_against.resize(count);
    for (std::uint32_t n = 0; n < count; ++n) {
      std::uint32_t source = n;
      while (!planar[source] && source != 0) source = parent[source];
      node_normals[n] = own_normal[source];
      const SphereNode& node = tree.node(n);
      const Eigen::Vector3d center =
          node.cluster < 0 ? node.rest_center
                           : Eigen::Vector3d(node.rest_center +
                                             body.cluster(node.cluster).rest_center_of_mass);
      // The sphere's centre need not lie midway between the layers of a slab (a few points
      // of the top layer may fix the sphere), so each side is measured on its own.
      double along = 0.0;
      double against = 0.0;
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        const double offset = (rest[tree.pointIndices()[s]] - center).dot(node_normals[n]);
        along = std::max(along, offset);
        against = std::max(against, -offset);
      }
      node_extent_along[n] = along;
      node_extent_against[n] = against;
    }
  }

  /// Dents a node's points by what its contact needs beyond the object's move, once every
  /// pair has added to that move. A dented point is blocked by the other object: it also
  /// stops moving into it (the other object takes that momentum). Left alone, the goal step
  /// turns each cycle's dent into motion towards the contact, and a held contact pumps up
  /// speed. Both velocities are those after this response's whole-object changes
  /// (velocity_after): a point measured before its object's own change would be stopped
  /// twice, and a resting object would leave each cycle moving up.
  void applyPendingDents(const std::vector<std::unique_ptr<Object>>& objects) {
    const auto& velocities = body.velocities();
    for (const PendingDent& pending : pending_dents) {
      // Each of the node's contacts with the partner dents it by what it needs beyond the
      // object's move; a point takes the mean over all the dents it gets.
      const double moved = translation.dot(pending.away);
      double beyond_sum = 0.0;
      std::uint32_t beyond_count = 0;
      for (std::uint32_t d = pending.first_depth; d != kNoDepth; d = dent_depths[d].next) {
        const double beyond = dent_depths[d].depth_unmoved_m - moved;
        if (beyond <= 0.0) continue;
        beyond_sum += beyond;
        ++beyond_count;
      }
      if (beyond_count == 0) continue;
      // The partner's velocity after the response, less this object's own change: what a
      // point's current velocity is compared with.
      const Eigen::Vector3d other_velocity = objects[pending.partner]->velocity_after - velocity_change;
      const Eigen::Vector3d displacement = beyond_sum * pending.away;
      const SphereNode& node = tree.node(pending.node);
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        const std::uint32_t point = tree.pointIndices()[s];
        if (displacement_counts[point] == 0) displaced_points.push_back(point);
        displacement_counts[point] += beyond_count;
        displacement_sums[point] += displacement;
        const double inward = std::min(0.0, (velocities[point] - other_velocity).dot(pending.away));
        velocity_change_sums[point] -= (beyond_count * inward) * pending.away;
      }
    }
    pending_dents.clear();
    dent_depths.clear();
  }

  /// Notes a contact's dent of `node`, pushed along `away` by `partner` in the pair resolved
  /// as `pair_serial`. The contacts of one node with one partner share a direction (the
  /// pair's normal, or a fixed node's plane): they are kept as one dent with a list of
  /// depths, so that the node's points are visited once for all of them.
  void addDent(std::uint32_t node, const Eigen::Vector3d& away, double depth_unmoved_m,
               std::uint32_t partner, std::uint64_t pair_serial) {
    const std::uint32_t depth = static_cast<std::uint32_t>(dent_depths.size());
    dent_depths.push_back({depth_unmoved_m, kNoDepth});
    if (dent_pair_of_node[node] == pair_serial) {
      PendingDent& last = pending_dents[dent_of_node[node]];
      if (last.away == away) {
        dent_depths[last.last_depth].next = depth;
        last.last_depth = depth;
        return;
      }
    }
    dent_pair_of_node[node] = pair_serial;
    dent_of_node[node] = static_cast<std::uint32_t>(pending_dents.size());
    pending_dents.push_back({node, away, partner, depth, depth});
  }

  ObjectConfig config;
  ShapeMatchingBody body;
  SphereTree tree;
  bool stale = false;  ///< Moved since its tree's spheres were last invalidated.
  /// Box around the object's points, grown by half the contact distance, for the broad
  /// phase: around the root sphere, or, for a static object, its points' own box once.
  Eigen::AlignedBox3d sweep_box;
  // Response scratch: changes summed per point, averaged when applied.
  std::vector<Eigen::Vector3d> displacement_sums;
  std::vector<Eigen::Vector3d> velocity_change_sums;
  std::vector<std::uint32_t> displacement_counts;
  std::vector<std::uint32_t> displaced_points;
  std::vector<PointDisplacement> displacements;
  std::vector<Eigen::Vector3d> posed_points;  ///< Kinematic objects: the rest shape posed.
  static constexpr std::uint32_t kNoDepth = std::numeric_limits<std::uint32_t>::max();
  /// A contact node's push, kept until the object's move over all its pairs is known.
  struct PendingDent {
    std::uint32_t node = 0;
    Eigen::Vector3d away = Eigen::Vector3d::UnitZ();  ///< Direction this object is pushed.
    std::uint32_t partner = 0;  ///< The object it touches.
    /// Its contacts' depths in dent_depths, a list from first_depth to last_depth.
    std::uint32_t first_depth = kNoDepth;
    std::uint32_t last_depth = kNoDepth;
  };
  struct DentDepth {
    double depth_unmoved_m = 0.0;  ///< How far the node must go if the object did not move.
    std::uint32_t next = kNoDepth;
  };
  std::vector<PendingDent> pending_dents;
  std::vector<DentDepth> dent_depths;
  /// Response scratch of the pair being resolved (dynamic partners): its contact nodes, and
  /// per node its number of the pair's contacts (0 outside them) and how far its points
  /// reach along the pair's normal, towards the partner.
  std::vector<std::uint32_t> contact_nodes;
  std::vector<std::uint32_t> contacts_of_node;
  std::vector<double> reach_of_node;
  /// Per node: its dent in pending_dents, valid for the pair resolved as dent_pair_of_node.
  std::vector<std::uint32_t> dent_of_node;
  std::vector<std::uint64_t> dent_pair_of_node;
  /// The side each partner touched this object from, kept while the contact lasts: an
  /// object pushed past the middle of a thin wall must still be pushed back, not through.
  struct ContactSide {
    std::uint32_t partner = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Away from the partner.
    std::uint64_t cycle = 0;                             ///< Last cycle in contact.
  };
  std::vector<ContactSide> sides;
  /// Contacts between this object and a fixed one, counted in hops over touching objects
  /// (0: fixed itself); unsupported objects have the largest value.
  std::uint32_t support_depth = 0;
  // Response scratch of the whole object.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_change = Eigen::Vector3d::Zero();
  /// Mean velocity once velocity_change is applied (zero for objects the response never moves).
  Eigen::Vector3d velocity_after = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> node_normals;  ///< Fixed objects: rest plane normal per node.
  /// Fixed objects: how far the node's points reach from its sphere's centre along that
  /// normal and against it.
  std::vector<double> node_extent_along;
  std::vector<double> node_extent_against;
};

std::optional<ObjectKind> parseObjectKind(const std::string& name) {
  if (name == "static") return ObjectKind::kStatic;
  if (name == "kinematic") return ObjectKind::kKinematic;
  if (name == "tracked") return ObjectKind::kTracked;
  if (name == "dynamic") return ObjectKind::kDynamic;
  return std::nullopt;
}

const char* toString(ObjectKind kind) {
  switch (kind) {
    case ObjectKind::kStatic:
      return "static";
    case ObjectKind::kKinematic:
      return "kinematic";
    case ObjectKind::kTracked:
      return "tracked";
    case ObjectKind::kDynamic:
      return "dynamic";
  }
  return "unknown";
}

Scene::Scene(const SceneConfig& config) : config_(config) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument(what); };
  std::ostringstream value;
  if (!config.gravity_mps2.allFinite()) fail("SceneConfig.gravity_mps2 is not finite");
  if (!(config.dt_s > 0.0 && config.dt_s <= 0.1)) {
    value << "SceneConfig.dt_s = " << config.dt_s << " must be in (0, 0.1]";
    fail(value.str());
  }
  if (!(config.contact_distance_m > 0.0) || !std::isfinite(config.contact_distance_m)) {
    value << "SceneConfig.contact_distance_m = " << config.contact_distance_m
          << " must be finite and > 0";
    fail(value.str());
  }
  if (!(config.friction >= 0.0) || !std::isfinite(config.friction)) {
    value << "SceneConfig.friction = " << config.friction << " must be finite and >= 0";
    fail(value.str());
  }
  if (config.level < -1) {
    value << "SceneConfig.level = " << config.level << " must be >= 0, or -1 for the finest";
    fail(value.str());
  }
  if (config.tree.branching < 2 || config.tree.leaf_size < 1 ||
      config.tree.exact_radius_points < 0) {
    value << "SceneConfig.tree (branching " << config.tree.branching << ", leaf_size "
          << config.tree.leaf_size << ", exact_radius_points " << config.tree.exact_radius_points
          << ") needs branching >= 2, leaf_size >= 1, exact_radius_points >= 0";
    fail(value.str());
  }
}

Scene::~Scene() = default;

std::size_t Scene::addObject(const ObjectConfig& config, std::vector<Eigen::Vector3d> rest_points_m) {
  if (config.name.empty()) throw std::invalid_argument("object name is empty");
  if (findObject(config.name)) {
    throw std::invalid_argument("object name '" + config.name + "' is used twice");
  }
  ObjectConfig checked = config;
  if (config.kind != ObjectKind::kDynamic) {
    // Only dynamic objects are simulated; the others are registered, never stepped.
    checked.shape.damping = 0.0;
  }
  if (config.kind == ObjectKind::kKinematic) checked.shape.mode = DeformationMode::kRigid;
  objects_.push_back(makeObject(checked, std::move(rest_points_m)));
  sweep_entries_.reserve(objects_.size());
  return objects_.size() - 1;
}

void Scene::resetRestShape(std::size_t object, std::vector<Eigen::Vector3d> rest_points_m) {
  std::unique_ptr<Object>& slot = objects_.at(object);
  slot = makeObject(slot->config, std::move(rest_points_m));
}

std::unique_ptr<Scene::Object> Scene::makeObject(const ObjectConfig& config,
                                                 std::vector<Eigen::Vector3d> rest_points_m) const {
  std::unique_ptr<Object> made;
  try {
    made = std::make_unique<Object>(config, std::move(rest_points_m), config_.tree);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("object '" + config.name + "': " + e.what());
  }
  if (!made->dynamic()) made->computeNodePlanes();
  if (config.kind == ObjectKind::kStatic) {
    // A wall's root sphere spans the room; its points' box is what it really covers.
    for (const auto& point : made->body.positions()) made->sweep_box.extend(point);
    made->sweep_box.min().array() -= 0.5 * config_.contact_distance_m;
    made->sweep_box.max().array() += 0.5 * config_.contact_distance_m;
  }
  return made;
}

void Scene::setPose(std::size_t object, const Eigen::Isometry3d& pose) {
  Object& o = *objects_.at(object);
  if (o.config.kind != ObjectKind::kKinematic) {
    throw std::invalid_argument("object '" + o.config.name + "' is " + toString(o.config.kind) +
                                ", only kinematic objects take a pose");
  }
  if (!pose.matrix().allFinite()) {
    throw std::invalid_argument("pose of object '" + o.config.name + "' is not finite");
  }
  const auto& rest = o.body.restPositions();
  o.posed_points.resize(rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) o.posed_points[i] = pose * rest[i];
  o.body.setPositions(o.posed_points);
  o.stale = true;
  ++stats_.objects_moved;
}

void Scene::setVelocities(std::size_t object, const std::vector<Eigen::Vector3d>& velocities_mps) {
  Object& o = *objects_.at(object);
  if (!o.dynamic()) {
    throw std::invalid_argument("object '" + o.config.name + "' is " + toString(o.config.kind) +
                                ", only dynamic objects have velocities");
  }
  o.body.setVelocities(velocities_mps);
}

std::size_t Scene::observe(std::size_t object, const std::vector<Eigen::Vector3d>& points_m) {
  Object& o = *objects_.at(object);
  if (o.config.kind != ObjectKind::kTracked) {
    throw std::invalid_argument("object '" + o.config.name + "' is " + toString(o.config.kind) +
                                ", only tracked objects take observations");
  }
  const std::size_t unobserved = o.body.track(points_m);
  o.stale = true;
  ++stats_.objects_moved;
  return unobserved;
}

void Scene::cycle() {
  const std::size_t moved_before = stats_.objects_moved;
  stats_ = CycleStats{};
  stats_.objects_moved = moved_before;
  const auto start = Clock::now();
  for (auto& object : objects_) {
    if (!object->dynamic()) continue;
    object->body.step(config_.dt_s, config_.gravity_mps2);
    object->stale = true;
    ++stats_.objects_moved;
  }
  const auto simulated = Clock::now();

  refreshStaleTrees();
  stats_.level = level();
  contacts_.clear();
  contact_runs_.clear();
  query_counters_ = QueryCounters{};
  std::size_t spheres_before = 0;
  for (const auto& object : objects_) spheres_before += object->tree.counters().spheres_updated;
  detect(stats_.level, std::nullopt, std::nullopt, contacts_, &contact_runs_);
  std::size_t spheres_after = 0;
  for (const auto& object : objects_) spheres_after += object->tree.counters().spheres_updated;
  const auto detected = Clock::now();

  respond();
  const auto responded = Clock::now();

  stats_.shape_matching_ms = millisecondsBetween(start, simulated);
  stats_.detection_ms = millisecondsBetween(simulated, detected);
  stats_.response_ms = millisecondsBetween(detected, responded);
  stats_.spheres_updated = spheres_after - spheres_before;
  stats_.node_pairs_tested = query_counters_.node_pairs_tested;
  stats_.point_tests = query_counters_.point_tests;
  stats_.contacts = contacts_.size();
}

void Scene::refreshStaleTrees() {
  for (auto& object : objects_) {
    if (!object->stale) continue;
    object->tree.beginCycle();
    object->stale = false;
  }
}

void Scene::sweepAndPrune() {
  const double margin = 0.5 * config_.contact_distance_m;
  if (sweep_entries_.size() != objects_.size()) {
    sweep_entries_.clear();
    for (std::uint32_t i = 0; i < objects_.size(); ++i) sweep_entries_.push_back({{}, i, false});
  }
  for (SweepEntry& entry : sweep_entries_) {
    Object& o = *objects_[entry.object];
    entry.is_static = o.config.kind == ObjectKind::kStatic;
    // Static objects keep their points' box, set when they were made.
    if (!entry.is_static) {
      const Sphere& root = o.tree.sphere(0);
      const Eigen::Vector3d reach = Eigen::Vector3d::Constant(root.radius + margin);
      o.sweep_box = Eigen::AlignedBox3d(root.center - reach, root.center + reach);
    }
    entry.box = o.sweep_box;
  }
  const auto before = [](const SweepEntry& a, const SweepEntry& b) {
    return a.box.min().x() < b.box.min().x() ||
           (a.box.min().x() == b.box.min().x() && a.object < b.object);
  };
  for (std::size_t i = 1; i < sweep_entries_.size(); ++i) {
    const SweepEntry entry = sweep_entries_[i];
    std::size_t j = i;
    for (; j > 0 && before(entry, sweep_entries_[j - 1]); --j) {
      sweep_entries_[j] = sweep_entries_[j - 1];
    }
    sweep_entries_[j] = entry;
  }
  candidate_pairs_.clear();
  // Objects overlapping the current one along x are those after it whose interval starts
  // before its own ends; of those, the ones whose boxes overlap along y and z are kept.
  for (std::size_t s = 0; s < sweep_entries_.size(); ++s) {
    const SweepEntry& first = sweep_entries_[s];
    for (std::size_t t = s + 1; t < sweep_entries_.size(); ++t) {
      const SweepEntry& second = sweep_entries_[t];
      if (second.box.min().x() > first.box.max().x()) break;
      // Overlapping along x by the sweep; y and z decide, without a branch.
      const bool overlap = (second.box.min().y() <= first.box.max().y()) &
                           (first.box.min().y() <= second.box.max().y()) &
                           (second.box.min().z() <= first.box.max().z()) &
                           (first.box.min().z() <= second.box.max().z()) &
                           !(first.is_static & second.is_static);
      if (!overlap) continue;
      candidate_pairs_.emplace_back(std::min(first.object, second.object),
                                    std::max(first.object, second.object));
    }
  }
  // Deterministic contact order, whatever the sweep order: by first object (a counting
  // sort), then by second (an object has a handful of partners).
  pair_offsets_.assign(objects_.size() + 1, 0);
  for (const auto& pair : candidate_pairs_) ++pair_offsets_[pair.first + 1];
  for (std::size_t i = 0; i < objects_.size(); ++i) pair_offsets_[i + 1] += pair_offsets_[i];
  sorted_pairs_.resize(candidate_pairs_.size());
  for (const auto& pair : candidate_pairs_) sorted_pairs_[pair_offsets_[pair.first]++] = pair;
  // Each offset now ends its object's run, where the next object's begins.
  std::uint32_t run_begin = 0;
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    const std::uint32_t run_end = pair_offsets_[i];
    for (std::uint32_t k = run_begin + 1; k < run_end; ++k) {
      const auto pair = sorted_pairs_[k];
      std::uint32_t j = k;
      for (; j > run_begin && pair.second < sorted_pairs_[j - 1].second; --j) {
        sorted_pairs_[j] = sorted_pairs_[j - 1];
      }
      sorted_pairs_[j] = pair;
    }
    run_begin = run_end;
  }
  candidate_pairs_.swap(sorted_pairs_);
}

namespace {

/// Writes a query's contacts straight into the scene's list, tagged with their objects.
class PairContacts final : public ContactSink {
 public:
  PairContacts(std::vector<SceneContact>& contacts, std::uint32_t object_a, std::uint32_t object_b)
      : contacts_(contacts), object_a_(object_a), object_b_(object_b) {}
  SphereContact& add() override {
    return contacts_.emplace_back(SceneContact{object_a_, object_b_, SphereContact{}}).contact;
  }

 private:
  std::vector<SceneContact>& contacts_;
  std::uint32_t object_a_;
  std::uint32_t object_b_;
};

}  // namespace

void Scene::detect(int level, std::optional<std::size_t> only_a, std::optional<std::size_t> only_b,
                   std::vector<SceneContact>& contacts, std::vector<ContactRun>* runs) {
  sweepAndPrune();
  const auto matches = [&](std::size_t a, std::size_t b) {
    const bool a_ok = !only_a || *only_a == a;
    const bool b_ok = !only_b || *only_b == b;
    return a_ok && b_ok;
  };
  for (const auto& [a, b] : candidate_pairs_) {
    // A pair matches the filter in either order; contacts keep the order asked for.
    const bool forward = matches(a, b);
    const bool backward = !forward && matches(b, a);
    if (!forward && !backward) continue;
    const std::uint32_t first = forward ? a : b;
    const std::uint32_t second = forward ? b : a;
    ++stats_.object_pairs_tested;
    PairContacts pair_contacts(contacts, first, second);
    const std::size_t begin = contacts.size();
    query_.collide(objects_[first]->tree, objects_[second]->tree, level,
                   config_.contact_distance_m, pair_contacts, query_counters_);
    if (runs && contacts.size() > begin) runs->push_back({first, second, begin, contacts.size()});
  }
}

void Scene::rankSupport() {
  constexpr std::uint32_t kUnsupported = std::numeric_limits<std::uint32_t>::max();
  // Adjacency of the touching pairs (the contact runs), in compressed rows.
  const std::size_t count = objects_.size();
  neighbour_offsets_.assign(count + 1, 0);
  for (const ContactRun& run : contact_runs_) {
    ++neighbour_offsets_[run.object_a + 1];
    ++neighbour_offsets_[run.object_b + 1];
  }
  for (std::size_t i = 0; i < count; ++i) neighbour_offsets_[i + 1] += neighbour_offsets_[i];
  neighbours_.resize(neighbour_offsets_[count]);
  neighbour_fill_.assign(neighbour_offsets_.begin(), neighbour_offsets_.end() - 1);
  for (const ContactRun& run : contact_runs_) {
    neighbours_[neighbour_fill_[run.object_a]++] = run.object_b;
    neighbours_[neighbour_fill_[run.object_b]++] = run.object_a;
  }
  // Breadth-first from the fixed objects.
  support_queue_.clear();
  for (std::uint32_t i = 0; i < count; ++i) {
    objects_[i]->support_depth = objects_[i]->dynamic() ? kUnsupported : 0;
    if (!objects_[i]->dynamic()) support_queue_.push_back(i);
  }
  for (std::size_t head = 0; head < support_queue_.size(); ++head) {
    const std::uint32_t from = support_queue_[head];
    const std::uint32_t depth = objects_[from]->support_depth + 1;
    for (std::uint32_t n = neighbour_offsets_[from]; n < neighbour_offsets_[from + 1]; ++n) {
      Object& other = *objects_[neighbours_[n]];
      if (other.support_depth <= depth) continue;
      other.support_depth = depth;
      support_queue_.push_back(neighbours_[n]);
    }
  }
}

void Scene::respond() {
  // Objects are separated to half the contact distance: resting objects stay in contact
  // (closer than the contact distance) and are still held apart.
  ++cycle_count_;
  rankSupport();
  for (auto& object : objects_) {
    auto& sides = object->sides;
    sides.erase(std::remove_if(sides.begin(), sides.end(),
                               [&](const Object::ContactSide& k) { return k.cycle + 1 < cycle_count_; }),
                sides.end());
  }
  // Each pair of touching objects is resolved in two parts. The whole object moves by the
  // mean push of its contact nodes (weighted by their points) and stops approaching the
  // other along the pair's normal (perfectly inelastic between the centres of mass); only
  // what a node needs beyond that mean is pushed into the object locally, as a dent that
  // shape matching restores. A rigid object thus lands without deforming and a soft one
  // dents where it touches most. Velocity corrections of single nodes, tried first, do not
  // survive the next goal step: it spreads them over the object, so a resting object
  // sinks, or, cancelling the motion the goals give the pushed points, bounces.
  for (const ContactRun& run : contact_runs_) {
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (a.dynamic() || b.dynamic()) resolvePair(a, b, run.object_a, run.object_b, run.begin, run.end);
  }
  for (auto& object : objects_) {
    object->velocity_after = object->dynamic()
                                 ? Eigen::Vector3d(object->body.meanVelocity() + object->velocity_change)
                                 : Eigen::Vector3d::Zero();
  }
  for (auto& object : objects_) {
    if (!object->dynamic()) continue;
    object->applyPendingDents(objects_);
    const bool moved = object->translation.squaredNorm() > 0.0 ||
                       object->velocity_change.squaredNorm() > 0.0 ||
                       !object->displaced_points.empty();
    if (!moved) continue;
    // An object moves at most the contact distance per response beyond what this cycle's
    // step moved it, so it cannot jump past a layer thinner than that before the layer's
    // contacts are seen; deeper overlaps take a few cycles. The step's own motion can
    // always be undone: with a long step, gravity alone takes a resting object deeper than
    // the contact distance (g h^2 = 2.5 cm at h = 0.05 s), and a smaller cap sinks it.
    const double allowed =
        config_.contact_distance_m + config_.dt_s * object->body.meanVelocity().norm();
    const double reach = object->translation.norm();
    if (reach > allowed) object->translation *= allowed / reach;
    object->body.moveRigidly(object->translation, object->velocity_change);
    object->translation.setZero();
    object->velocity_change.setZero();
    object->displacements.clear();
    for (const std::uint32_t point : object->displaced_points) {
      const double share = 1.0 / object->displacement_counts[point];
      object->displacements.push_back({point, share * object->displacement_sums[point],
                                       share * object->velocity_change_sums[point]});
      object->displacement_sums[point].setZero();
      object->velocity_change_sums[point].setZero();
      object->displacement_counts[point] = 0;
    }
    stats_.points_displaced += object->displaced_points.size();
    object->displaced_points.clear();
    object->body.displacePoints(object->displacements);
    object->stale = true;
  }
  // Queries between cycles see the state after the response.
  refreshStaleTrees();
}

void Scene::resolvePair(Object& a, Object& b, std::uint32_t index_a, std::uint32_t index_b,
                        std::size_t run_begin, std::size_t run_end) {
  // Pushes per contact, for a (along +normal) and b (along -normal): a node's depth along
  // a normal from b to a, shared by inverse mass between dynamic nodes.
  pushes_.clear();
  ++pair_serial_;
  const bool fixed_pair = a.dynamic() != b.dynamic();
  const Eigen::Vector3d translation_before_a = a.translation;
  const Eigen::Vector3d translation_before_b = b.translation;
  // The side a lies on, seen from b: as in the last cycle of this contact, or for a new
  // contact, where the objects' centres are. A fixed object's centre says little (a wall's
  // lies a metre above what touches it), so its side is where its touched nodes are.
  Object& keeper = a.dynamic() ? a : b;
  const std::uint32_t partner = static_cast<std::uint32_t>(&keeper == &a ? index_b : index_a);
  auto kept = std::find_if(keeper.sides.begin(), keeper.sides.end(),
                           [&](const Object::ContactSide& k) { return k.partner == partner; });
  Eigen::Vector3d side = Eigen::Vector3d::Zero();
  if (kept != keeper.sides.end() && kept->cycle + 1 >= cycle_count_) {
    side = &keeper == &a ? kept->normal : Eigen::Vector3d(-kept->normal);
  } else if (fixed_pair) {
    const bool a_fixed = !a.dynamic();
    Object& fixed = a_fixed ? a : b;
    Eigen::Vector3d touched = Eigen::Vector3d::Zero();
    for (std::size_t k = run_begin; k < run_end; ++k) {
      const SphereContact& c = contacts_[k].contact;
      touched += fixed.tree.sphere(a_fixed ? c.node_a : c.node_b).center;
    }
    touched /= static_cast<double>(run_end - run_begin);
    const Eigen::Vector3d moving_center = (a_fixed ? b : a).tree.sphere(0).center;
    side = a_fixed ? Eigen::Vector3d(touched - moving_center) : Eigen::Vector3d(moving_center - touched);
  } else {
    side = a.tree.sphere(0).center - b.tree.sphere(0).center;
  }
  // Between two dynamic objects every push goes along one normal: the direction that
  // separates a's contact nodes from b's, turned to agree with the side a lies on. Nearest
  // point pairs of two clouds point every which way, and more so once the clouds have
  // passed into each other; the two sides of the contact do not.
  Eigen::Vector3d pair_normal_ab = side;
  // One query found all of a pair's contacts, at the leaves or above them.
  const bool leaves = contacts_[run_begin].contact.point_a != SphereContact::kNoPoint;
  if (!fixed_pair) {
    for (std::size_t k = run_begin; k < run_end; ++k) {
      const SphereContact& c = contacts_[k].contact;
      if (a.contacts_of_node[c.node_a]++ == 0) a.contact_nodes.push_back(c.node_a);
      if (b.contacts_of_node[c.node_b]++ == 0) b.contact_nodes.push_back(c.node_b);
    }
    const double spread = 0.1 * config_.contact_distance_m;
    const Eigen::Vector3d across =
        separatingDirection({a.tree, a.contact_nodes, a.contacts_of_node},
                            {b.tree, b.contact_nodes, b.contacts_of_node}, leaves, spread * spread);
    if (across.squaredNorm() > 0.0) {
      pair_normal_ab = across.dot(side) < 0.0 ? Eigen::Vector3d(-across) : across;
    }
    const double length = pair_normal_ab.norm();
    pair_normal_ab =
        length > 0.0 ? Eigen::Vector3d(pair_normal_ab / length) : Eigen::Vector3d::UnitZ();
    for (const std::uint32_t node : a.contact_nodes) {
      if (leaves) a.reach_of_node[node] = reachAlong(a.tree, node, -pair_normal_ab);
      a.contacts_of_node[node] = 0;
    }
    for (const std::uint32_t node : b.contact_nodes) {
      if (leaves) b.reach_of_node[node] = reachAlong(b.tree, node, pair_normal_ab);
      b.contacts_of_node[node] = 0;
    }
    a.contact_nodes.clear();
    b.contact_nodes.clear();
  }
  for (std::size_t k = run_begin; k < run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    ContactPush push;
    push.node_a = c.node_a;
    push.node_b = c.node_b;
    push.points_a = a.tree.node(c.node_a).point_count;
    push.points_b = b.tree.node(c.node_b).point_count;
    if (fixed_pair) {
      // Against a fixed object: its node's plane, oriented towards the dynamic object, and
      // the deepest point's signed distance. Unlike the distance to the nearest point, that
      // depth does not shrink or flip when points have passed a thin layer such as a floor.
      const bool a_fixed = !a.dynamic();
      Object& fixed = a_fixed ? a : b;
      Object& moving = a_fixed ? b : a;
      const std::uint32_t fixed_node = a_fixed ? c.node_a : c.node_b;
      const SphereNode& node = moving.tree.node(a_fixed ? c.node_b : c.node_a);
      const int cluster = std::max(0, fixed.tree.node(fixed_node).cluster);
      Eigen::Vector3d away = fixed.body.deformation(cluster).rotation * fixed.node_normals[fixed_node];
      const Eigen::Vector3d plane_point = fixed.tree.sphere(fixed_node).center;
      double surface = fixed.node_extent_along[fixed_node];
      if (away.dot(a_fixed ? Eigen::Vector3d(-side) : side) < 0.0) {
        away = -away;
        surface = fixed.node_extent_against[fixed_node];
      }
      // Pairs resolved before this one may have moved the object already.
      double lowest = moving.translation.dot(away);
      double deepest = std::numeric_limits<double>::infinity();
      const auto& positions = moving.body.positions();
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        deepest = std::min(deepest, (positions[moving.tree.pointIndices()[s]] - plane_point).dot(away));
      }
      lowest += deepest;
      const double depth =
          surface + 0.5 * config_.contact_distance_m - lowest;
      if (depth <= 0.0) continue;
      push.normal = a_fixed ? Eigen::Vector3d(-away) : away;
      push.depth_a = a_fixed ? 0.0 : depth;
      push.depth_b = a_fixed ? depth : 0.0;
    } else {
      // Two dynamic nodes, along the pair's normal, the depth shared by inverse mass. At
      // the leaves the depth is how far b's points reach past a's along the normal: the
      // nearest pair's distance says nothing of how deep two clouds have passed into each
      // other (it stays below the point spacing however deep), and piles sank into
      // themselves. Above the leaves, spheres stand for their points (the query's depth).
      push.normal = pair_normal_ab;
      const double overlap =
          leaves ? b.reach_of_node[c.node_b] + a.reach_of_node[c.node_a] + config_.contact_distance_m
                 : c.depth_m;
      const double depth = overlap - 0.5 * config_.contact_distance_m -
                           (a.translation - b.translation).dot(push.normal);
      if (depth <= 0.0) continue;
      // Shared by inverse node mass: a's share is b's node mass over both.
      const double mass_a = a.body.pointMassKg() * push.points_a;
      const double mass_b = b.body.pointMassKg() * push.points_b;
      const double share_of_a = a.support_depth < b.support_depth   ? 0.0
                                : b.support_depth < a.support_depth ? 1.0
                                                                    : mass_b / (mass_a + mass_b);
      push.depth_a = depth * share_of_a;
      push.depth_b = depth - push.depth_a;
    }
    pushes_.push_back(push);
  }
  if (pushes_.empty()) return;

  Eigen::Vector3d mean_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_b = Eigen::Vector3d::Zero();
  double weight_a = 0.0;
  double weight_b = 0.0;
  Eigen::Vector3d pair_normal = Eigen::Vector3d::Zero();
  for (const ContactPush& push : pushes_) {
    mean_a += push.points_a * push.depth_a * push.normal;
    mean_b -= push.points_b * push.depth_b * push.normal;
    weight_a += push.points_a;
    weight_b += push.points_b;
    pair_normal += (push.depth_a + push.depth_b) * push.normal;
  }
  mean_a /= weight_a;
  mean_b /= weight_b;
  // A stiff object cannot dent, so it moves to clear more of its deepest node: the mean
  // push for a soft one (the rest is dented), all of the deepest for a rigid one.
  double deepest_a = 0.0;
  double deepest_b = 0.0;
  for (const ContactPush& push : pushes_) {
    deepest_a = std::max(deepest_a, push.depth_a - mean_a.dot(push.normal));
    deepest_b = std::max(deepest_b, push.depth_b + mean_b.dot(push.normal));
  }
  const Eigen::Vector3d pair_direction = pair_normal.normalized();
  if (a.dynamic()) mean_a += a.config.shape.stiffness * deepest_a * pair_direction;
  if (b.dynamic()) mean_b -= b.config.shape.stiffness * deepest_b * pair_direction;
  // Gauss-Seidel over the pairs: each sees the velocity changes of the pairs before it; a
  // Jacobi sweep stops an object resting on two others twice, and piles explode.
  const Eigen::Vector3d velocity_a =
      a.dynamic() ? Eigen::Vector3d(a.body.meanVelocity() + a.velocity_change) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d velocity_b =
      b.dynamic() ? Eigen::Vector3d(b.body.meanVelocity() + b.velocity_change) : Eigen::Vector3d::Zero();
  // Dents wait until every pair has moved the object: a later pair may move it back, as
  // the second jaw of a gripper does, and a dent sized against this pair's move alone
  // would leave the first jaw's contact deep inside.
  for (const ContactPush& push : pushes_) {
    if (a.dynamic() && push.depth_a > 0.0) {
      a.addDent(push.node_a, push.normal, push.depth_a + translation_before_a.dot(push.normal),
                index_b, pair_serial_);
    }
    if (b.dynamic() && push.depth_b > 0.0) {
      b.addDent(push.node_b, -push.normal, push.depth_b - translation_before_b.dot(push.normal),
                index_a, pair_serial_);
    }
  }

  const Eigen::Vector3d normal = pair_normal.normalized();
  const Eigen::Vector3d kept_normal = &keeper == &a ? normal : Eigen::Vector3d(-normal);
  if (kept != keeper.sides.end()) {
    kept->normal = kept_normal;
    kept->cycle = cycle_count_;
  } else {
    keeper.sides.push_back({partner, kept_normal, cycle_count_});
  }
  const Eigen::Vector3d relative = velocity_a - velocity_b;
  const double approach = std::min(0.0, relative.dot(normal));
  const Eigen::Vector3d sliding = relative - relative.dot(normal) * normal;
  const double sliding_speed = sliding.norm();
  // The change of the relative velocity: stop the approach, and brake the sliding by at
  // most friction times that.
  Eigen::Vector3d change = -approach * normal;
  if (sliding_speed > 0.0) {
    change -= std::min(sliding_speed, -config_.friction * approach) / sliding_speed * sliding;
  }
  // Shock propagation (Guendelman et al. 2003): of two touching objects, the one nearer to
  // a fixed support acts as fixed, so that pushes never drive an object into what carries
  // it, such as the bottom of a pile into the floor or a wall.
  const double inverse_a =
      a.dynamic() && a.support_depth >= b.support_depth ? 1.0 / a.body.config().mass_kg : 0.0;
  const double inverse_b =
      b.dynamic() && b.support_depth >= a.support_depth ? 1.0 / b.body.config().mass_kg : 0.0;
  const double share_a = inverse_a / (inverse_a + inverse_b);
  // Static friction on the positions: what the pair slid across its normal over the cycle,
  // the step and every push so far, is taken back while it is inside the friction cone of
  // this push. A resting object is pushed back each cycle by what gravity moved it, along
  // normals that are never exact (fitted planes, nearest point pairs), and without this it
  // walks sideways, by a normal's tilt times g h^2 per cycle. Sliding contacts are left to
  // the velocity friction above. Only where one side holds (fixed, or nearer to a support):
  // between two objects carried alike, taking the slip back moves both against supports
  // this pass does not see; a bar leaning on a ball lifted the ball off the floor.
  const Eigen::Vector3d step_a =
      a.dynamic() ? Eigen::Vector3d(config_.dt_s * a.body.meanVelocity()) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d step_b =
      b.dynamic() ? Eigen::Vector3d(config_.dt_s * b.body.meanVelocity()) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d moved =
      (step_a + translation_before_a + mean_a) - (step_b + translation_before_b + mean_b);
  const Eigen::Vector3d slip = moved - moved.dot(normal) * normal;
  const double pressed = (mean_a - mean_b).dot(normal);
  const bool one_side_holds = share_a == 0.0 || share_a == 1.0;
  if (one_side_holds && slip.norm() <= config_.friction * pressed) {
    mean_a -= share_a * slip;
    mean_b += (1.0 - share_a) * slip;
  }
  if (a.dynamic()) {
    a.translation += mean_a;
    a.velocity_change += share_a * change;
  }
  if (b.dynamic()) {
    b.translation += mean_b;
    b.velocity_change -= (1.0 - share_a) * change;
  }
}

void Scene::setLevel(int level) {
  if (level < 0 || level > maxLevel()) {
    throw std::out_of_range("level " + std::to_string(level) + " is outside [0, " +
                            std::to_string(maxLevel()) + "]");
  }
  config_.level = level;
}

int Scene::level() const {
  return config_.level < 0 ? maxLevel() : std::min(config_.level, maxLevel());
}

int Scene::maxLevel() const {
  int deepest = 0;
  for (const auto& object : objects_) deepest = std::max(deepest, object->tree.maxLevel());
  return deepest;
}

void Scene::contactsAt(int level, std::optional<std::size_t> object_a,
                       std::optional<std::size_t> object_b, std::vector<SceneContact>& contacts) {
  if (level < 0 || level > maxLevel()) {
    throw std::out_of_range("level " + std::to_string(level) + " is outside [0, " +
                            std::to_string(maxLevel()) + "]");
  }
  for (const auto& object : {object_a, object_b}) {
    if (object && *object >= objects_.size()) {
      throw std::out_of_range("object " + std::to_string(*object) + " is outside [0, " +
                              std::to_string(objects_.size()) + ")");
    }
  }
  const CycleStats kept = stats_;
  const QueryCounters kept_counters = query_counters_;
  refreshStaleTrees();
  contacts.clear();
  detect(level, object_a, object_b, contacts, nullptr);
  stats_ = kept;
  query_counters_ = kept_counters;
}

std::optional<std::size_t> Scene::findObject(const std::string& name) const {
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (objects_[i]->config.name == name) return i;
  }
  return std::nullopt;
}

const ObjectConfig& Scene::objectConfig(std::size_t object) const {
  return objects_.at(object)->config;
}

const ShapeMatchingBody& Scene::body(std::size_t object) const { return objects_.at(object)->body; }

const SphereTree& Scene::tree(std::size_t object) const { return objects_.at(object)->tree; }

const Sphere& Scene::currentSphere(std::size_t object, std::uint32_t node) {
  Object& o = *objects_.at(object);
  if (node >= o.tree.nodeCount()) {
    throw std::out_of_range("node " + std::to_string(node) + " of object '" + o.config.name +
                            "' is outside [0, " + std::to_string(o.tree.nodeCount()) + ")");
  }
  if (o.stale) {
    o.tree.beginCycle();
    o.stale = false;
  }
  return o.tree.sphere(node);
}

}  // namespace deformable_collision
