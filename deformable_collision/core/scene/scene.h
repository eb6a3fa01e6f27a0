#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/core/common/enum_names.h"
#include "deformable_collision/core/common/worker_pool.h"
#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/lod/level_budget.h"
#include "deformable_collision/core/lod/level_costs.h"
#include "deformable_collision/core/query/broad_phase.h"
#include "deformable_collision/core/query/collision_query.h"
#include "deformable_collision/core/query/distance_query.h"
#include "deformable_collision/core/query/self_collision_query.h"
#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/response/contact_forces.h"
#include "deformable_collision/core/response/contact_response.h"
#include "deformable_collision/core/response/self_contact_response.h"
#include "deformable_collision/core/scene/registration_fitter.h"
#include "deformable_collision/core/scene/tracked_fitter.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {
namespace detail {
struct SceneObject;    // Internal (scene/detail/scene_object.h).
class PairQueryLanes;  // Internal (scene/detail/pair_query_lanes.h).
}  // namespace detail

/// How an object's points move.
enum class ObjectKind {
  kStatic,     ///< Never moves; costs nothing per cycle.
  kKinematic,  ///< Rigid, moved by setPose() (a gripper following a tf frame).
  kTracked,    ///< Moved by observe() (registered clouds of a deforming object).
  kDynamic,    ///< Simulated by shape matching and pushed by the collision response.
};

inline constexpr EnumNames<ObjectKind, 4> kObjectKindNames{{{ObjectKind::kStatic, "static"},
                                                            {ObjectKind::kKinematic, "kinematic"},
                                                            {ObjectKind::kTracked, "tracked"},
                                                            {ObjectKind::kDynamic, "dynamic"}}};

/// The kind named `name` (kObjectKindNames); std::nullopt otherwise.
inline std::optional<ObjectKind> parseObjectKind(const std::string& name) {
  return parseEnum(kObjectKindNames, name);
}
inline const char* toString(ObjectKind kind) { return enumName(kObjectKindNames, kind); }

struct ObjectConfig {
  std::string name;
  ObjectKind kind = ObjectKind::kDynamic;
  ShapeMatchingConfig shape;
  /// Tracked objects (>= 0): the force per metre of indentation that a probe pressed into
  /// the object reads (a calibration); its contacts with objects the response never moves
  /// get that force (ContactForces). 0: those contacts report no force.
  double contact_stiffness_n_per_m = 0.0;
  /// Tracked and dynamic objects: whether the object's contacts with itself (a fold, a
  /// squeeze that closes a gap) are detected, and for a dynamic object resolved
  /// (SelfCollisionQuery). Costs nothing when false.
  bool self_collision = false;
  /// Points closer than this at rest (m, >= 0) are neighbours in the material, never in
  /// self-contact; 0: kSelfRestContactDistances contact distances. Never less than the
  /// contact distance in force, so that an object at rest has no self-contacts.
  double self_rest_distance_m = 0.0;
};

/// The rest distance of self-contacts when an object sets none, in contact distances: two
/// points are then in self-contact only once squeezed to a quarter of their distance at rest.
inline constexpr double kSelfRestContactDistances = 4.0;

struct SceneConfig {
  Eigen::Vector3d gravity_mps2 = Eigen::Vector3d(0.0, 0.0, -9.81);
  double dt_s = 0.01;                 ///< Step of one cycle, in (0, 0.1].
  double contact_distance_m = 0.005;  ///< Points closer than this are in contact (> 0).
  int level = -1;                     ///< Level of detail; -1: the finest (the leaves).
  /// Set (> 0): each cycle runs at the level a LevelBudget picks to fit this many ms of
  /// detection and response, and `level` is not read (Scene::setCycleBudget).
  std::optional<double> cycle_budget_ms;
  /// Coulomb friction coefficient (>= 0) between touching objects: the sliding speed of a
  /// pair drops by at most this times the approach speed the contact stops.
  double friction = 0.5;
  /// Each cycle's contacts get their forces (ContactForces); false: force_n stays zero and
  /// the response keeps no account of the momentum it exchanges.
  bool contact_forces = true;
  SphereTreeConfig tree;
  RegistrationConfig registration;  ///< Of tracked objects' unordered clouds (registerCloud).
  /// Threads a cycle's shape matching runs on, the caller's included, in [1, 64]: dynamic
  /// objects step on them together once they hold enough points to pay for it. Every
  /// count gives the same states, bit for bit.
  int threads = 1;
};

/// A contact between two objects of the scene, or of an object with itself (object_a ==
/// object_b, ObjectConfig::self_collision), at `contact.level`.
struct SceneContact {
  std::uint32_t object_a = 0;
  std::uint32_t object_b = 0;
  SphereContact contact;
  /// The force on object a through this contact (N, scene frame; b gets its opposite), from
  /// the last response (ContactForces).
  Eigen::Vector3d force_n = Eigen::Vector3d::Zero();
  /// How far force_n can be from the sum of the finest level's forces of the two nodes'
  /// points (N, >= 0): 0 at the leaves of a dynamic pair.
  double force_error_n = 0.0;
  /// The part of force_error_n that the indentation's error makes (0 in a dynamic pair):
  /// summed over a pair, how far its total can be from the finest level's.
  double indentation_error_n = 0.0;
  /// How far the contact may be off the real objects' for their registrations' errors (m,
  /// >= 0): the larger of the two objects' SurfaceError, each on the side of its camera
  /// that the pair's contacts face; 0 between objects never registered
  /// (detail::assignRegistrationErrors, whether or not forces are computed).
  double registration_error_m = 0.0;
};

/// The end of the run of contacts of the pair of contacts[begin] (a Scene lists each pair's
/// contacts together).
inline std::size_t pairRunEnd(const std::vector<SceneContact>& contacts, std::size_t begin) {
  std::size_t end = begin + 1;
  while (end < contacts.size() && contacts[end].object_a == contacts[begin].object_a &&
         contacts[end].object_b == contacts[begin].object_b) {
    ++end;
  }
  return end;
}

/// Per-cycle timings (steady clock) and counts.
struct CycleStats {
  double shape_matching_ms = 0.0;
  double detection_ms = 0.0;
  /// Detection done ahead of this cycle (detectAhead()), not in its time: the contacts of the
  /// pairs that did not change since are taken from it. The counts below include its work.
  double detection_ahead_ms = 0.0;
  double response_ms = 0.0;
  int level = 0;                  ///< The level the contacts were found at.
  bool level_auto = false;        ///< The level was picked to fit cycle_budget_ms.
  double cycle_budget_ms = 0.0;   ///< The budget it was picked for; 0 when the level is fixed.
  std::size_t objects_moved = 0;  ///< Stepped, posed or registered this cycle.
  std::size_t object_pairs_tested = 0;  ///< Root sphere tests after the cycle's sweep.
  /// Of those, pairs neither of which changed since the last detection (the last cycle's,
  /// or one ahead of this cycle): their contacts kept, not queried again.
  std::size_t object_pairs_reused = 0;
  std::size_t spheres_updated = 0;
  std::size_t node_pairs_tested = 0;
  std::size_t point_tests = 0;
  std::size_t contacts = 0;
  std::size_t points_displaced = 0;
};

/// What a cycle cost (ms), as the cycle budget counts it, from the cycle's figures.
using CycleCostSource = std::function<double(const CycleStats& cycle)>;

/// Objects, their hierarchies and one simulation cycle (paper section 6): shape matching,
/// a sweep-and-prune broad phase over the objects' root spheres, the hierarchy query at the
/// selected level, and the level-of-detail response. The response separates each pair of
/// touching objects to half the contact distance: the whole object moves by the mean push
/// of its contact nodes (more for stiff objects) and stops approaching the other (with
/// Coulomb friction), and the nodes dent it by what they need beyond that; pairs are
/// resolved one after the other, objects nearer to a fixed support acting as fixed (shock
/// propagation). Steady-state cycles allocate nothing.
class Scene {
  using Object = detail::SceneObject;

 public:
  /// @throw std::invalid_argument naming the bad value.
  explicit Scene(const SceneConfig& config);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  /// An object made for this scene, not yet in it (prepareObject()); empty once added.
  class PreparedObject {
   public:
    PreparedObject();
    ~PreparedObject();
    PreparedObject(PreparedObject&&) noexcept;
    PreparedObject& operator=(PreparedObject&&) noexcept;

    bool empty() const { return object_ == nullptr; }
    /// A fitter of this tracked object's clouds, for once it is added (TrackedFitter).
    /// @throw std::invalid_argument if it is empty or not a tracked object.
    TrackedFitter trackedFitter() const;

   private:
    friend class Scene;
    std::unique_ptr<Object> object_;
  };

  /// Adds an object with its rest shape (in the scene's frame) and returns its index.
  /// @throw std::invalid_argument for an empty or duplicate name or a bad shape.
  std::size_t addObject(const ObjectConfig& config, std::vector<Eigen::Vector3d> rest_points_m);

  /// Makes what addObject(config, rest_points_m) would add (its clusters and hierarchy: the
  /// costly part, tens of milliseconds for thousands of points) without adding it. Reads only
  /// what the scene's construction fixed (its tree and contact distance), never its objects:
  /// another thread may prepare objects while this one cycles.
  /// @throw std::invalid_argument for an empty name or a bad shape.
  PreparedObject prepareObject(const ObjectConfig& config,
                               std::vector<Eigen::Vector3d> rest_points_m) const;
  /// Adds a prepared object and returns its index; `prepared` is then empty. Nothing changes
  /// if it throws.
  /// @throw std::invalid_argument if `prepared` is empty or its name is already used.
  std::size_t addObject(PreparedObject&& prepared);

  /// Replaces an object's rest shape (its points, clusters and hierarchy) and puts it there
  /// at rest; the point count may change. Nothing changes if it throws.
  /// @throw std::invalid_argument for a bad shape, std::out_of_range for a bad index.
  void resetRestShape(std::size_t object, std::vector<Eigen::Vector3d> rest_points_m);
  /// The same with a rest shape prepared (prepareObject()) with the object's configuration;
  /// `prepared` is then empty. Nothing changes if it throws.
  /// @throw std::invalid_argument if `prepared` is empty or made for another name,
  /// std::out_of_range for a bad index.
  void resetRestShape(std::size_t object, PreparedObject&& prepared);

  /// Moves a kinematic object rigidly to `pose` (applied to its rest shape).
  /// @throw std::invalid_argument if the object is not kinematic or the pose not finite.
  void setPose(std::size_t object, const Eigen::Isometry3d& pose);

  /// Sets the velocities of a dynamic object (an initial condition).
  /// @throw std::invalid_argument if the object is not dynamic or the size differs.
  void setVelocities(std::size_t object, const std::vector<Eigen::Vector3d>& velocities_mps);

  /// Registers observed positions of a tracked object (see ShapeMatchingBody::track).
  /// @return the number of unobserved points.
  /// @throw std::invalid_argument if the object is not tracked or the size differs.
  std::size_t observe(std::size_t object, const std::vector<Eigen::Vector3d>& points_m);

  /// observe(), but a cloud without holes is swapped in instead of copied, and `points_m`
  /// gets the object's previous positions (see ShapeMatchingBody::trackSwapping).
  /// @throw std::invalid_argument if the object is not tracked or the size differs.
  std::size_t observeSwapping(std::size_t object, std::vector<Eigen::Vector3d>& points_m);

  /// A fitter of the clouds of tracked object `object` from its state now (TrackedFitter).
  /// @throw std::invalid_argument if the object is not tracked, std::out_of_range for a bad
  ///        index.
  TrackedFitter trackedFitter(std::size_t object) const;

  /// Takes over a cloud of a tracked object fitted by a fitter of it (TrackedFitter::fit),
  /// its fitted points in `points_m`: O(clusters), the points swapped in; `points_m` then
  /// holds the object's former points, a buffer to read the next cloud into.
  /// @throw std::invalid_argument if the object is not tracked, `fit` was fitted to
  ///        another rest shape (another object's, or one this object had before a reset) or
  ///        `points_m` is not of the object's size; nothing changes then.
  ///        std::out_of_range for a bad index.
  void observeFitted(std::size_t object, std::vector<Eigen::Vector3d>& points_m,
                     const TrackedFit& fit);

  /// Fits a tracked object's model to an unordered, partial, noisy cloud of it (any size
  /// and order, non-finite points skipped), seen from `viewpoint_m` if known (the camera's
  /// position; see CloudRegistration). A cloud that does not show the object leaves it
  /// where it was (`held`).
  /// @throw std::invalid_argument if the object is not tracked.
  RegistrationReport registerCloud(
      std::size_t object, const std::vector<Eigen::Vector3d>& cloud_m,
      const std::optional<Eigen::Vector3d>& viewpoint_m = std::nullopt);

  /// A registration of the clouds of tracked object `object` from its state now, to run on
  /// another thread (RegistrationFitter).
  /// @throw std::invalid_argument if the object is not tracked, std::out_of_range for a bad
  ///        index.
  RegistrationFitter registrationFitter(std::size_t object) const;

  /// Takes over a cloud registered by a fitter of the object (RegistrationFitter::fit, not
  /// held), as observeFitted() takes a tracked fit, with that registration's estimate of
  /// the model's error (SceneContact::registration_error_m, as after registerCloud()).
  /// @throw as observeFitted(); nothing changes then.
  void observeRegistered(std::size_t object, std::vector<Eigen::Vector3d>& points_m,
                         const TrackedFit& fit, const SurfaceError& error);
  /// The estimated error of `object`'s model from the last cloud registered to it (zero if
  /// none was). @throw std::out_of_range for a bad index.
  const SurfaceError& registrationError(std::size_t object) const;

  /// Into `points_m` (its capacity reused): the points of the objects other than `object`
  /// that registerCloud() leaves out of its clouds when they are closer than the contact
  /// distance (RegistrationConfig::exclude_near_other_objects), as the objects are now.
  /// Those within the object's root sphere grown by how far a registration may move it
  /// (iterations times max_correspondence_m) and the contact distance: a cloud point beyond
  /// is never matched. Empty if the configuration excludes nothing or the object is alone.
  /// Visits only the other objects' nodes that reach that sphere.
  /// @throw std::out_of_range for a bad index.
  void pointsNearObject(std::size_t object, std::vector<Eigen::Vector3d>& points_m);

  /// One cycle; its contacts are contacts() (with their forces) and its figures stats(). A pair of
  /// objects neither of which changed since the last detection (the last cycle's, or
  /// detectAhead()'s), at the same level, keeps that detection's contacts without a query
  /// (stats().object_pairs_reused).
  void cycle();

  /// Changes the level of the next cycles (no other cost); -1 is the finest, as in
  /// SceneConfig, and stays the finest when deeper objects come. Leaves budget mode. At any
  /// level, a static or kinematic object meets a tracked or dynamic one whose hierarchy
  /// ends at or above the level at its own leaves, as at the finest level.
  /// @throw std::out_of_range if level is not -1 or in [0, maxLevel()].
  void setLevel(int level);
  /// Set: from the next cycle on, each cycle runs at the finest level expected to fit
  /// `budget_ms` of detection and response, from what earlier cycles cost at each level
  /// (LevelBudget; entering budget mode starts from level 0, a new budget in budget mode
  /// keeps the estimates). std::nullopt: the level the budget picked last stays fixed.
  /// @throw std::invalid_argument if budget_ms is not finite and > 0.
  void setCycleBudget(std::optional<double> budget_ms);
  /// The budget in force; std::nullopt when the level is fixed.
  std::optional<double> cycleBudget() const { return config_.cycle_budget_ms; }
  /// What the cycle budget takes as each cycle's cost. By default (and with an empty
  /// function) the cycle's measured detection + response time, whose noise makes the levels
  /// picked differ from run to run; a given source (a cost per level, say) makes them
  /// reproducible, as tests need. stats() keeps the measured times either way, and the source
  /// stays set when budget mode is left or entered. cycle() throws std::invalid_argument,
  /// after the cycle, if the source gives a negative or non-finite cost.
  void setCycleCostSource(CycleCostSource source);
  /// Changes the step of the next cycles (a node whose clouds' stamps time its cycles).
  /// @throw std::invalid_argument unless dt_s is in (0, 0.1].
  void setTimeStep(double dt_s);
  /// Changes the Coulomb friction of the next cycles' response.
  /// @throw std::invalid_argument unless finite and >= 0.
  void setFriction(double friction);
  /// Changes the contact distance of the next detections, responses and queries; the next
  /// cycle queries every pair again. Fixed objects' planes keep the gap of the contact
  /// distance the scene was made with (docs/design.md, "Response").
  /// @throw std::invalid_argument unless finite and > 0.
  void setContactDistance(double contact_distance_m);
  /// Changes a dynamic object's stiffness (alpha) and damping from its next step.
  /// @throw std::out_of_range for a bad index; std::invalid_argument if the object is not
  /// dynamic or a value is outside [0, 1].
  void setMaterial(std::size_t object, double stiffness, double damping);
  /// Changes a tracked object's contact stiffness (N/m of indentation) from the next cycle.
  /// @throw std::out_of_range for a bad index; std::invalid_argument if the object is not
  /// tracked or the value is not finite and >= 0.
  void setContactStiffness(std::size_t object, double n_per_m);
  /// The level of the next cycle: the configured one, maxLevel() for "finest", or the one
  /// the cycle budget picked.
  int level() const;
  /// The finest level over all objects (the leaves).
  int maxLevel() const;
  /// Per level, the detection time (stats().detection_ms) of the cycles run there, over all
  /// object pairs: what a contact query at that level is expected to cost at most, since it
  /// tests those pairs or fewer, on spheres that the cycle may have updated already.
  const LevelCosts& detectionCosts() const { return detection_costs_; }

  /// Detects the contacts of the current state at level(), ahead of the next cycle, which
  /// then queries only the object pairs that change after this call: a node that applies
  /// clouds while it waits for its next cycle detects them meanwhile. Pairs with a dynamic
  /// object are left to the cycle, whose step moves it. The time and the counts go into the
  /// next cycle's stats (detection_ahead_ms); the cycle budget counts that time as the
  /// cycle's. contacts() holds the contacts found until the cycle.
  void detectAhead();

  /// Contacts at `level` on the current state, for objects a and b (std::nullopt: any).
  /// The running level and the contacts of the last cycle are left alone; a pair with a
  /// dynamic object has the last cycle's force, shared among these contacts (ContactForces).
  /// Like cycle(), it
  /// never reports two static objects touching: the broad phase never pairs them, since
  /// neither can move the other.
  /// @throw std::out_of_range if level is not in [0, maxLevel()] or an object index is not.
  void contactsAt(int level, std::optional<std::size_t> object_a,
                  std::optional<std::size_t> object_b, std::vector<SceneContact>& contacts);

  /// The closest points of objects a and b at `level` on the current state, from the same
  /// hierarchies (HierarchyDistance): exact at their leaves, a lower bound with its error
  /// above them; std::nullopt if no two points can be within `max_distance_m`. The running
  /// level and the last cycle's contacts are left alone.
  /// @throw std::out_of_range if level is not in [0, maxLevel()] or an object index is not;
  /// std::invalid_argument if the objects are the same or max_distance_m is negative or not
  /// finite.
  std::optional<ClosestPoints> closestPoints(std::size_t object_a, std::size_t object_b, int level,
                                             double max_distance_m);

  const std::vector<SceneContact>& contacts() const { return contacts_; }
  const CycleStats& stats() const { return stats_; }
  const SceneConfig& config() const { return config_; }

  std::size_t objectCount() const { return objects_.size(); }
  std::optional<std::size_t> findObject(const std::string& name) const;
  const ObjectConfig& objectConfig(std::size_t object) const;
  const ShapeMatchingBody& body(std::size_t object) const;
  const SphereTree& tree(std::size_t object) const;
  /// The sphere of `node` of `object` on the current state, computed on demand (drawing
  /// the hierarchy touches only what is drawn).
  /// @throw std::out_of_range for a bad object or node index.
  const Sphere& currentSphere(std::size_t object, std::uint32_t node);

 private:
  /// A fitter of `object`'s clouds, from its body now.
  static TrackedFitter makeTrackedFitter(const Object& object);
  /// An object with its hierarchy (and rest planes, if fixed); names the object if it throws.
  std::unique_ptr<Object> makeObject(const ObjectConfig& config,
                                     std::vector<Eigen::Vector3d> rest_points_m) const;
  /// @throw std::out_of_range if there is no such object, std::invalid_argument if it is
  /// not tracked.
  Object& trackedObject(std::size_t object);
  /// Object `object` if it is of `kind`; the error says it lacks `what` otherwise.
  /// @throw std::out_of_range for a bad index, std::invalid_argument for another kind.
  Object& objectOfKind(std::size_t object, ObjectKind kind, const char* what);
  void refreshStaleTrees();
  /// Steps every dynamic object, on the pool's threads when their points are enough.
  void stepDynamicObjects();
  static constexpr std::size_t kPointsWorthSharing = 32768;

  /// Appends the points of `object` within `radius_m` of `center_m` to `points_m`.
  void appendPointsWithin(std::size_t object, const Eigen::Vector3d& center_m, double radius_m,
                          std::vector<Eigen::Vector3d>& points_m);

  // The cycle's detection (detection.cpp).
  /// Computes the root sphere of every object the sweep boxes by it, on the pool's threads
  /// if the objects are many.
  void computeRootsOnPool();
  /// Below this many objects their root spheres are computed by the sweep itself.
  static constexpr std::size_t kRootsWorthSharing = 32;
  /// The candidate object pairs of the objects' current boxes.
  const std::vector<BroadPhase::Pair>& sweepAndPrune();
  /// Appends the contacts at `level` and, if `runs` is given, each object pair's range of
  /// them.
  void detect(int level, std::optional<std::size_t> only_a, std::optional<std::size_t> only_b,
              std::vector<SceneContact>& contacts, std::vector<ContactRun>* runs);
  /// Appends the self-contacts at `level` of the objects with self_collision that match the
  /// filter (std::nullopt: any), object by object.
  void appendSelfContacts(int level, std::optional<std::size_t> only_a,
                          std::optional<std::size_t> only_b, std::vector<SceneContact>& contacts);
  /// Appends the contacts of one candidate pair, in this order, found with `query`; safe on
  /// several threads at once for pairs that share no object.
  void queryPair(int level, std::uint32_t first, std::uint32_t second, HierarchyQuery& query,
                 QueryCounters& counters, std::vector<SceneContact>& contacts);
  /// Whether a detection leaves the pair of objects a and b to the cycle (`ahead`: one ahead
  /// of it, which leaves the pairs with a dynamic object).
  bool leftToCycle(std::uint32_t a, std::uint32_t b, bool ahead) const;
  /// Whether the pair keeps its contacts of the last detection (`reusable`: at this level):
  /// neither object changed since.
  bool keepsContacts(std::uint32_t a, std::uint32_t b, bool reusable) const;
  /// Queries on the pool's threads, into pair_lanes_, the candidate pairs that the detection
  /// neither leaves to the cycle nor keeps.
  void queryPairsOnPool(int level, const std::vector<BroadPhase::Pair>& candidate_pairs, bool ahead,
                        bool reusable);
  /// Below this many candidate pairs a detection stays on the cycle's thread.
  static constexpr std::size_t kPairsWorthSharing = 32;
  /// Spheres updated since each object's tree last restarted, over all objects.
  std::size_t spheresUpdated() const;
  /// The cycle's detection into contacts_ and contact_runs_: a pair of objects neither of
  /// which got a revision since the last detection at the same level keeps its contacts, the
  /// others are queried. `ahead`: detectAhead()'s, which leaves the pairs with a dynamic
  /// object out and counts no object pairs in stats_.
  void detectCycleContacts(int level, bool ahead);
  /// Appends the last cycle's contacts of the pair (first, second) to contacts_; `cursor`
  /// walks previous_runs_, which is in the order of the candidate pairs.
  void reusePreviousContacts(std::uint32_t first, std::uint32_t second, std::size_t& cursor);
  /// Invalidates the tree's spheres for the body's current points and numbers the change.
  void restartTree(Object& object);

  SceneConfig config_;
  /// The contact distance at construction: the gap of fixed objects' planes, which
  /// prepareObject() builds on another thread than setContactDistance() runs on.
  const double planes_gap_m_;
  std::vector<std::unique_ptr<Object>> objects_;
  BroadPhase broad_phase_;
  HierarchyQuery query_;
  HierarchyDistance distance_;
  std::optional<LevelBudget> level_budget_;  ///< Set in budget mode.
  CycleCostSource cycle_cost_source_;        ///< Empty: the measured time.
  LevelCosts detection_costs_;
  std::vector<SceneContact> contacts_;
  std::vector<ContactRun> contact_runs_;  ///< The pairs of contacts_, in its order.
  // The last cycle's contacts and runs, for the pairs that did not move since; swapped with
  // contacts_ and contact_runs_ each cycle, so neither is reallocated in steady state.
  std::vector<SceneContact> previous_contacts_;
  std::vector<ContactRun> previous_runs_;
  /// The level of the last detection; none before the first, or after one that threw.
  std::optional<int> previous_level_;
  std::uint64_t revisions_ = 0;  ///< The last revision given to an object.
  /// revisions_ at the last detection (a cycle's, or one ahead of a cycle): objects numbered
  /// up to it kept their points since.
  std::uint64_t revisions_detected_ = 0;
  /// What detectAhead() did since the last cycle, for that cycle's stats.
  struct DetectionAhead {
    double ms = 0.0;
    std::size_t spheres_updated = 0;
    std::size_t node_pairs_tested = 0;
    std::size_t point_tests = 0;
  };
  DetectionAhead detection_ahead_;
  std::vector<std::uint32_t> proximity_stack_;  ///< Nodes appendPointsWithin has to visit.
  std::vector<Eigen::Vector3d> near_points_;    ///< registerCloud()'s, for pointsNearObject.
  QueryCounters query_counters_;
  CycleStats stats_;
  SelfCollisionQuery self_query_;
  /// Where the cycle's self-contacts begin in contacts_: after every pair's.
  std::size_t self_contacts_begin_ = 0;
  ContactResponse response_;  ///< Reads objects_, contacts_, contact_runs_ and config_.
  SelfContactResponse self_response_;
  ContactForces forces_;  ///< Reads objects_.
  WorkerPool pool_;       ///< The cycle's shape matching and pair queries.
  /// The pair queries of a cycle's detection on pool_.
  std::unique_ptr<detail::PairQueryLanes> pair_lanes_;
};

}  // namespace deformable_collision
