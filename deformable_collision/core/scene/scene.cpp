// The Scene: construction, its objects, one cycle, levels and lookups. Its detection is in
// detection.cpp and the registration of clouds in registration.cpp; the response is
// response/'s ContactResponse.
#include "deformable_collision/core/scene/scene.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "deformable_collision/core/scene/detail/pair_query_lanes.h"
#include "deformable_collision/core/scene/detail/registration_errors.h"
#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {
namespace {

using Clock = std::chrono::steady_clock;

double millisecondsBetween(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

/// The pool is made before the constructor's checks: its count is checked here.
int validThreads(int threads) {
  if (threads < 1 || threads > WorkerPool::kMaxThreads) {
    throw std::invalid_argument("SceneConfig.threads = " + std::to_string(threads) +
                                " must be in [1, " + std::to_string(WorkerPool::kMaxThreads) + "]");
  }
  return threads;
}

}  // namespace

namespace detail {

SceneObject::SceneObject(const ObjectConfig& object_config,
                         std::vector<Eigen::Vector3d> rest_points,
                         const SphereTreeConfig& tree_config)
    : config(object_config),
      body(std::move(rest_points), object_config.shape),
      tree(body, tree_config) {
  if (dynamic()) dents.reserve(body.pointCount(), tree.nodeCount());
}

}  // namespace detail

Scene::Scene(const SceneConfig& config)
    : config_(config),
      planes_gap_m_(config.contact_distance_m),
      response_(objects_, contacts_, contact_runs_, config_),
      forces_(objects_),
      pool_(validThreads(config.threads)),
      pair_lanes_(std::make_unique<detail::PairQueryLanes>()) {
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
  if (config.cycle_budget_ms) {
    try {
      level_budget_.emplace(*config.cycle_budget_ms, 0);
    } catch (const std::invalid_argument& e) {
      fail(std::string("SceneConfig.cycle_budget_ms: ") + e.what());
    }
  }
  if (config.tree.branching < 2 || config.tree.leaf_size < 1 ||
      config.tree.exact_radius_points < 0) {
    value << "SceneConfig.tree (branching " << config.tree.branching << ", leaf_size "
          << config.tree.leaf_size << ", exact_radius_points " << config.tree.exact_radius_points
          << ") needs branching >= 2, leaf_size >= 1, exact_radius_points >= 0";
    fail(value.str());
  }
  validateRegistrationConfig(config.registration);
}

Scene::~Scene() = default;

Scene::PreparedObject::PreparedObject() = default;
Scene::PreparedObject::~PreparedObject() = default;
Scene::PreparedObject::PreparedObject(PreparedObject&&) noexcept = default;
Scene::PreparedObject& Scene::PreparedObject::operator=(PreparedObject&&) noexcept = default;

TrackedFitter Scene::PreparedObject::trackedFitter() const {
  if (empty()) throw std::invalid_argument("trackedFitter: the prepared object is empty");
  return makeTrackedFitter(*object_);
}

TrackedFitter Scene::trackedFitter(std::size_t object) const {
  return makeTrackedFitter(*objects_.at(object));
}

TrackedFitter Scene::makeTrackedFitter(const Object& object) {
  if (object.config.kind != ObjectKind::kTracked) {
    throw std::invalid_argument("object '" + object.config.name + "' is " +
                                toString(object.config.kind) + ", only tracked objects are fitted");
  }
  return TrackedFitter(object.body, object.rest_shape);
}

std::size_t Scene::addObject(const ObjectConfig& config,
                             std::vector<Eigen::Vector3d> rest_points_m) {
  // Before the costly part: a name in use fails at once.
  if (findObject(config.name)) {
    throw std::invalid_argument("object name '" + config.name + "' is used twice");
  }
  PreparedObject prepared = prepareObject(config, std::move(rest_points_m));
  return addObject(std::move(prepared));
}

Scene::PreparedObject Scene::prepareObject(const ObjectConfig& config,
                                           std::vector<Eigen::Vector3d> rest_points_m) const {
  if (config.name.empty()) throw std::invalid_argument("object name is empty");
  ObjectConfig checked = config;
  if (config.kind != ObjectKind::kDynamic) {
    // Only dynamic objects are simulated; the others are registered, never stepped.
    checked.shape.damping = 0.0;
  }
  if (config.kind == ObjectKind::kKinematic) checked.shape.mode = DeformationMode::kRigid;
  PreparedObject prepared;
  prepared.object_ = makeObject(checked, std::move(rest_points_m));
  return prepared;
}

std::size_t Scene::addObject(PreparedObject&& prepared) {
  if (prepared.empty()) throw std::invalid_argument("addObject: the prepared object is empty");
  const std::string& name = prepared.object_->config.name;
  if (findObject(name)) throw std::invalid_argument("object name '" + name + "' is used twice");
  broad_phase_.reserve(objects_.size() + 1);
  objects_.push_back(std::move(prepared.object_));
  objects_.back()->revision = ++revisions_;
  return objects_.size() - 1;
}

void Scene::resetRestShape(std::size_t object, std::vector<Eigen::Vector3d> rest_points_m) {
  std::unique_ptr<Object>& slot = objects_.at(object);
  slot = makeObject(slot->config, std::move(rest_points_m));
  slot->revision = ++revisions_;
}

void Scene::resetRestShape(std::size_t object, PreparedObject&& prepared) {
  std::unique_ptr<Object>& slot = objects_.at(object);
  if (prepared.empty()) throw std::invalid_argument("resetRestShape: the prepared object is empty");
  if (prepared.object_->config.name != slot->config.name) {
    throw std::invalid_argument("resetRestShape: object '" + slot->config.name +
                                "' given a rest shape prepared for '" +
                                prepared.object_->config.name + "'");
  }
  slot = std::move(prepared.object_);
  slot->revision = ++revisions_;
}

std::unique_ptr<Scene::Object> Scene::makeObject(const ObjectConfig& config,
                                                 std::vector<Eigen::Vector3d> rest_points_m) const {
  if (!(config.contact_stiffness_n_per_m >= 0.0) ||
      !std::isfinite(config.contact_stiffness_n_per_m)) {
    throw std::invalid_argument("object '" + config.name + "': contact_stiffness_n_per_m = " +
                                std::to_string(config.contact_stiffness_n_per_m) +
                                " must be finite and >= 0");
  }
  if (!(config.self_rest_distance_m >= 0.0) || !std::isfinite(config.self_rest_distance_m)) {
    throw std::invalid_argument("object '" + config.name + "': self_rest_distance_m = " +
                                std::to_string(config.self_rest_distance_m) +
                                " must be finite and >= 0");
  }
  if (config.self_collision &&
      (config.kind == ObjectKind::kStatic || config.kind == ObjectKind::kKinematic)) {
    throw std::invalid_argument("object '" + config.name +
                                "': self_collision needs a tracked or "
                                "dynamic object; a " +
                                toString(config.kind) +
                                " one moves only rigidly and never touches itself");
  }
  std::unique_ptr<Object> made;
  try {
    made = std::make_unique<Object>(config, std::move(rest_points_m), config_.tree);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("object '" + config.name + "': " + e.what());
  }
  // Numbered for the whole process, not per scene: a fitter of one scene's object cannot
  // pass for another scene's either. Objects are prepared on several threads.
  static std::atomic<std::uint64_t> rest_shapes_made{0};
  made->rest_shape = ++rest_shapes_made;
  // The planes' gap is the contact distance the scene was made with: this runs on the
  // node's reader thread, apart from setContactDistance().
  if (!made->dynamic()) made->planes.emplace(made->body, made->tree, planes_gap_m_);
  if (config.kind == ObjectKind::kStatic) {
    // A wall's root sphere spans the room; its points' box is what it really covers.
    for (const auto& point : made->body.positions()) made->points_box.extend(point);
    made->slabs.measureOnDemand(made->tree, made->body.positions());
  }
  if (config.self_collision) made->rest_spheres.emplace(made->tree);
  if (config.kind == ObjectKind::kKinematic) {
    made->rest_slabs.compute(made->tree, made->body.restPositions());
    made->slabs.pose(made->rest_slabs, Eigen::Isometry3d::Identity());
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
  o.slabs.pose(o.rest_slabs, pose);
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
  Object& o = trackedObject(object);
  const std::size_t unobserved = o.body.track(points_m);
  o.stale = true;
  ++stats_.objects_moved;
  return unobserved;
}

std::size_t Scene::observeSwapping(std::size_t object, std::vector<Eigen::Vector3d>& points_m) {
  Object& o = trackedObject(object);
  const std::size_t unobserved = o.body.trackSwapping(points_m);
  o.stale = true;
  ++stats_.objects_moved;
  return unobserved;
}

void Scene::observeFitted(std::size_t object, std::vector<Eigen::Vector3d>& points_m,
                          const TrackedFit& fit) {
  Object& o = trackedObject(object);
  if (fit.rest_shape != o.rest_shape) {
    throw std::invalid_argument("object '" + o.config.name +
                                "' was given a fit to another rest shape than its own");
  }
  o.body.takeTrackedState(points_m, fit.state);
  o.stale = true;
  ++stats_.objects_moved;
}

Scene::Object& Scene::trackedObject(std::size_t object) {
  return objectOfKind(object, ObjectKind::kTracked, "observations to take");
}

void Scene::cycle() {
  const std::size_t moved_before = stats_.objects_moved;
  stats_ = CycleStats{};
  stats_.objects_moved = moved_before;
  const auto start = Clock::now();
  stepDynamicObjects();
  const auto simulated = Clock::now();

  refreshStaleTrees();
  // Objects that came since the last cycle may have added levels.
  const int max_level = maxLevel();
  if (level_budget_) level_budget_->setMaxLevel(max_level);
  detection_costs_.setMaxLevel(max_level);
  stats_.level = level();
  query_counters_ = QueryCounters{};
  const std::size_t spheres_before = spheresUpdated();
  detectCycleContacts(stats_.level, false);
  const std::size_t spheres_after = spheresUpdated();
  const auto detected = Clock::now();

  stats_.points_displaced = response_.respond(pool_);
  stats_.points_displaced +=
      self_response_.respond(objects_, contacts_, self_contacts_begin_, config_.friction);
  detail::assignRegistrationErrors(objects_, contacts_);
  if (config_.contact_forces) forces_.assign(contacts_, contact_runs_, config_.dt_s);
  // Queries between cycles see the state after the response.
  refreshStaleTrees();
  const auto responded = Clock::now();

  stats_.shape_matching_ms = millisecondsBetween(start, simulated);
  stats_.detection_ms = millisecondsBetween(simulated, detected);
  stats_.detection_ahead_ms = detection_ahead_.ms;
  stats_.response_ms = millisecondsBetween(detected, responded);
  stats_.spheres_updated = spheres_after - spheres_before + detection_ahead_.spheres_updated;
  stats_.node_pairs_tested = query_counters_.node_pairs_tested + detection_ahead_.node_pairs_tested;
  stats_.point_tests = query_counters_.point_tests + detection_ahead_.point_tests;
  stats_.contacts = contacts_.size();
  detection_ahead_ = DetectionAhead{};
  // Detection done ahead found part of this cycle's contacts: the level costs it all the same.
  const double detection_ms = stats_.detection_ms + stats_.detection_ahead_ms;
  detection_costs_.record(stats_.level, detection_ms);
  if (level_budget_) {
    stats_.level_auto = true;
    stats_.cycle_budget_ms = level_budget_->budgetMs();
    level_budget_->record(cycle_cost_source_ ? cycle_cost_source_(stats_)
                                             : detection_ms + stats_.response_ms);
  }
}

void Scene::stepDynamicObjects() {
  std::size_t points = 0;
  for (const auto& object : objects_) {
    if (!object->dynamic()) continue;
    points += object->body.pointCount();
    object->stale = true;
    ++stats_.objects_moved;
  }
  // Each object's step reads and writes only its own body: on any number of threads the
  // states are the same. Below kPointsWorthSharing, waking the workers and the bodies' data
  // left in another core's cache for detection cost more than the step saves (S3's 19k
  // points were 5% slower on two threads).
  const auto step = [this](std::size_t i) {
    Object& object = *objects_[i];
    if (!object.dynamic()) return;
    object.center_before_step = object.body.centerOfMass();
    object.body.step(config_.dt_s, config_.gravity_mps2);
  };
  if (points >= kPointsWorthSharing) {
    pool_.forEach(objects_.size(), step);
  } else {
    for (std::size_t i = 0; i < objects_.size(); ++i) step(i);
  }
}

void Scene::detectAhead() {
  const auto start = Clock::now();
  refreshStaleTrees();
  query_counters_ = QueryCounters{};
  const std::size_t spheres_before = spheresUpdated();
  detectCycleContacts(level(), true);
  detection_ahead_.spheres_updated += spheresUpdated() - spheres_before;
  detection_ahead_.node_pairs_tested += query_counters_.node_pairs_tested;
  detection_ahead_.point_tests += query_counters_.point_tests;
  detection_ahead_.ms += millisecondsBetween(start, Clock::now());
}

std::size_t Scene::spheresUpdated() const {
  std::size_t spheres = 0;
  for (const auto& object : objects_) spheres += object->tree.counters().spheres_updated;
  return spheres;
}

void Scene::refreshStaleTrees() {
  for (auto& object : objects_) {
    if (object->stale) restartTree(*object);
  }
}

void Scene::restartTree(Object& object) {
  object.tree.beginCycle();
  object.stale = false;
  object.revision = ++revisions_;
}

void Scene::setLevel(int level) {
  if (level < -1 || level > maxLevel()) {
    throw std::out_of_range("level " + std::to_string(level) + " is outside [0, " +
                            std::to_string(maxLevel()) + "] (-1: the finest)");
  }
  config_.level = level;
  config_.cycle_budget_ms.reset();
  level_budget_.reset();
}

void Scene::setCycleBudget(std::optional<double> budget_ms) {
  if (!budget_ms) {
    config_.level = level();
    config_.cycle_budget_ms.reset();
    level_budget_.reset();
    return;
  }
  if (level_budget_) {
    level_budget_->setBudget(*budget_ms);
  } else {
    level_budget_.emplace(*budget_ms, maxLevel());
  }
  config_.cycle_budget_ms = budget_ms;
}

void Scene::setCycleCostSource(CycleCostSource source) { cycle_cost_source_ = std::move(source); }

void Scene::setTimeStep(double dt_s) {
  if (!(dt_s > 0.0 && dt_s <= 0.1)) {
    throw std::invalid_argument("time step dt_s = " + std::to_string(dt_s) +
                                " must be in (0, 0.1]");
  }
  config_.dt_s = dt_s;
}

void Scene::setFriction(double friction) {
  if (!(friction >= 0.0) || !std::isfinite(friction)) {
    throw std::invalid_argument("friction = " + std::to_string(friction) +
                                " must be finite and >= 0");
  }
  config_.friction = friction;
}

Scene::Object& Scene::objectOfKind(std::size_t object, ObjectKind kind, const char* what) {
  if (object >= objects_.size()) {
    throw std::out_of_range("object " + std::to_string(object) + " is outside [0, " +
                            std::to_string(objects_.size()) + ")");
  }
  Object& o = *objects_[object];
  if (o.config.kind != kind) {
    throw std::invalid_argument("object '" + o.config.name + "' is " + toString(o.config.kind) +
                                ": only a " + toString(kind) + " one has " + what);
  }
  return o;
}

void Scene::setContactDistance(double contact_distance_m) {
  if (!(contact_distance_m > 0.0) || !std::isfinite(contact_distance_m)) {
    throw std::invalid_argument("contact_distance_m = " + std::to_string(contact_distance_m) +
                                " must be finite and > 0");
  }
  config_.contact_distance_m = contact_distance_m;
  // Pairs that did not move would keep the contacts of the old distance.
  previous_level_.reset();
}

void Scene::setMaterial(std::size_t object, double stiffness, double damping) {
  Object& o = objectOfKind(object, ObjectKind::kDynamic, "a stiffness and damping to change");
  o.body.setMaterial(stiffness, damping);
  o.config.shape.stiffness = stiffness;
  o.config.shape.damping = damping;
}

void Scene::setContactStiffness(std::size_t object, double n_per_m) {
  Object& o = objectOfKind(object, ObjectKind::kTracked, "a contact stiffness");
  if (!(n_per_m >= 0.0) || !std::isfinite(n_per_m)) {
    throw std::invalid_argument("object '" + o.config.name + "': contact_stiffness_n_per_m = " +
                                std::to_string(n_per_m) + " must be finite and >= 0");
  }
  o.config.contact_stiffness_n_per_m = n_per_m;
}

int Scene::level() const {
  if (level_budget_) return std::min(level_budget_->level(), maxLevel());
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
  detail::assignRegistrationErrors(objects_, contacts);
  if (config_.contact_forces) forces_.assignQueried(contacts);
  stats_ = kept;
  query_counters_ = kept_counters;
}

std::optional<ClosestPoints> Scene::closestPoints(std::size_t object_a, std::size_t object_b,
                                                  int level, double max_distance_m) {
  if (level < 0 || level > maxLevel()) {
    throw std::out_of_range("level " + std::to_string(level) + " is outside [0, " +
                            std::to_string(maxLevel()) + "]");
  }
  for (const std::size_t object : {object_a, object_b}) {
    if (object >= objects_.size()) {
      throw std::out_of_range("object " + std::to_string(object) + " is outside [0, " +
                              std::to_string(objects_.size()) + ")");
    }
  }
  Object& a = *objects_[object_a];
  Object& b = *objects_[object_b];
  if (object_a == object_b) {
    throw std::invalid_argument("the distance of object '" + a.config.name + "' to itself");
  }
  refreshStaleTrees();
  QueryCounters counters;
  return distance_.closest(a.tree, b.tree, level, max_distance_m, counters);
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
  if (o.stale) restartTree(o);
  return o.tree.sphere(node);
}

}  // namespace deformable_collision
