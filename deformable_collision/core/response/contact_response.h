#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "deformable_collision/core/common/worker_pool.h"

namespace deformable_collision {

struct SceneConfig;
struct SceneContact;
struct SphereContact;
namespace detail {
struct SceneObject;
class ObjectGroups;
class PairNormals;
}  // namespace detail

/// The contacts of one object pair: contacts[begin, end).
struct ContactRun {
  std::uint32_t object_a = 0;
  std::uint32_t object_b = 0;
  std::size_t begin = 0;
  std::size_t end = 0;
  bool support_link = true;  ///< Whether the support ranking counts the pair.
  /// The momentum this cycle's response gave object a through the pair (N s, scene frame):
  /// -impulse_ns went to b.
  Eigen::Vector3d impulse_ns = Eigen::Vector3d::Zero();
};

/// The level-of-detail response (paper section 6) to a cycle's contacts: each pair of
/// touching objects is separated to half the contact distance. The whole object moves by the
/// mean push of its contact nodes (more for stiff objects) and stops approaching the other
/// (with Coulomb friction), and the nodes dent it by what they need beyond that; pairs are
/// resolved one after the other, objects nearer to a fixed support acting as fixed (shock
/// propagation). Holds the scratch of every step, so that steady-state responses allocate
/// nothing.
class ContactResponse {
 public:
  using Objects = std::vector<std::unique_ptr<detail::SceneObject>>;

  /// Reads the scene's objects, contacts, runs and configuration through these references,
  /// which must outlive it.
  ContactResponse(Objects& objects, const std::vector<SceneContact>& contacts,
                  std::vector<ContactRun>& runs, const SceneConfig& config);
  ~ContactResponse();
  ContactResponse(const ContactResponse&) = delete;
  ContactResponse& operator=(const ContactResponse&) = delete;

  /// Moves and dents the dynamic objects of the runs' pairs and changes their velocities;
  /// marks what it moved stale. The pairs are resolved on this thread, their normals measured
  /// before on `pool`'s threads; the objects, each touching only its own body, are then moved
  /// and dented on them, when there are many: the same bits on any count.
  /// @return the number of points displaced by dents.
  std::size_t respond(WorkerPool& pool);

 private:
  using Object = detail::SceneObject;
  struct ContactPush;
  struct ResolvingPair;
  struct FixedSurface;
  struct TouchedSurface;
  /// A pair's velocity exchange as its resolution decided it.
  struct VelocityExchange {
    std::uint32_t object_a;
    std::uint32_t object_b;
    Eigen::Vector3d normal;  ///< From b to a.
    double share_a;          ///< a's share of the change (shock propagation).
    bool sticks;             ///< Static friction held the pair in position.
    std::uint32_t run;       ///< Its contact run, which counts the momentum exchanged.
  };
  /// A dynamic object's move for one of its pairs with a fixed object, kept until every
  /// such pair is resolved (fixed_pair_moves_).
  struct FixedPairMove {
    std::uint32_t object;
    std::uint32_t serial;    ///< Order of resolution, for a stable grouping by object.
    Eigen::Vector3d normal;  ///< The pair's normal, towards the dynamic object.
    Eigen::Vector3d move;
  };
  /// A node lowestInLine still has to visit, and how low its sphere reaches.
  struct ReachingNode {
    std::uint32_t node;
    double lowest_m;
  };
  struct PairScratch;
  /// What resolving a pair leaves to the passes after all pairs: a velocity exchange, and
  /// with a fixed object the dynamic one's move (`serial` set when kept).
  struct PairOutcome {
    bool exchanged = false;
    VelocityExchange exchange{};
    bool fixed_move = false;
    FixedPairMove move{};
  };

  /// Reads each touching object's mean velocity once for this response.
  void readMeanVelocities();
  /// Sets each run's support_link (isSupportLink), on `pool`'s threads when they are many.
  void markSupportLinks(WorkerPool& pool);
  /// Below this many runs their links are marked on the calling thread. Not above
  /// kFixedPairsWorthSharing: resolveFixedPairs shares only what this prepared.
  static constexpr std::size_t kRunsWorthSharing = 32;
  /// Counts each object's hops to a fixed one over the runs that link them (support_depth).
  void rankSupport();
  /// Between a fixed and a dynamic object: whether the dynamic one lay on the touched
  /// surface before this cycle's step. Between dynamic objects: true.
  bool isSupportLink(const ContactRun& run);
  /// The normal of every pair between dynamic objects, before any is resolved.
  void measureDynamicNormals(WorkerPool& pool);
  /// Resolves the pairs from the supports up.
  void resolvePairs(WorkerPool& pool);
  /// Resolves the first `count` pairs of resolve_order_, those with a fixed object, into
  /// fixed_outcomes_: object by object on `pool`'s threads when they are many.
  void resolveFixedPairs(WorkerPool& pool, std::size_t count);
  /// Below this many pairs with a fixed object they are resolved on the calling thread.
  static constexpr std::size_t kFixedPairsWorthSharing = 32;
  /// Computes, on this thread, the fixed objects' planes and contact nodes' spheres that the
  /// runs between a fixed and a dynamic object read: on first use otherwise, from any thread.
  void prepareFixedSides();
  /// Adds a resolved pair's exchange and move to the lists the later passes read.
  void keepOutcome(PairOutcome& outcome);
  /// Moves each dynamic object by its pairs with fixed objects taken together.
  void moveByFixedPartners();
  /// Passes over the pairs' velocities after the first (velocity_exchanges_).
  void repeatVelocityExchanges();
  /// Hands the momentum each dynamic object took as fixed (carried_impulse) down to its
  /// supports' runs, from the top of the support ranking to the fixed objects: a floor
  /// carries the whole stack on it.
  void passCarriedImpulsesDown();
  /// Whether the run links its object a or b (`upper`) to a partner nearer to a support.
  bool supportsFrom(const ContactRun& run, std::uint32_t& upper, std::uint32_t& lower) const;
  /// Stops a pair's approach (or, where it sticks, its sliding) along the exchange's normal,
  /// shared by its share_a.
  void exchangeVelocity(const VelocityExchange& exchange);
  /// Once every pair is resolved: no object leaves moving into a fixed one it was pushed off.
  void stopApproachToFixedPartners();
  /// Moves a dynamic object by its pairs' pushes and dents it where they need more; reads
  /// and writes that object alone. Returns the points it displaced.
  std::size_t applyObjectResponse(Object& object) const;
  /// applyObjectResponse() for every dynamic object, then the dents' momentum into the runs
  /// in the objects' order.
  void applyObjectResponses(WorkerPool& pool);
  /// Below this many dynamic objects the response stays on the calling thread.
  static constexpr std::size_t kObjectsWorthSharing = 32;
  /// Dents the pending nodes by what their contacts need beyond the object's move, once
  /// every pair has added to that move.
  void applyPendingDents(Object& object) const;
  /// Sums per run the momentum the object's dented points' stops exchange with the partners
  /// (its dents' run_impulses), before the other points pay for them.
  static void sumDentImpulses(Object& object);
  /// Takes from those the share of `paid` (per unit point mass) the object's other points
  /// paid for them.
  static void payDentImpulses(Object& object, const Eigen::Vector3d& paid);
  /// Adds `impulse` on `object` to the run: on its a, or against its b.
  void addImpulse(std::uint32_t run, const Object& object, const Eigen::Vector3d& impulse);
  /// Resolves one pair with `scratch`; reads and writes the pair's objects and run, and only
  /// the dynamic one of a pair with a fixed object. `serial` keys the pair's dents.
  void resolvePair(Object& a, Object& b, std::uint32_t run, PairScratch& scratch,
                   std::uint64_t serial, PairOutcome& outcome);
  void holdClearContact(ResolvingPair& pair);
  bool heldContact(const ResolvingPair& pair);
  /// How far an object in contact was carried by its mean velocity in this cycle's step (0
  /// if not dynamic).
  Eigen::Vector3d stepOf(const Object& object) const;
  void undoStepApproach(const ResolvingPair& pair, const Eigen::Vector3d& normal,
                        Eigen::Vector3d& move_a, Eigen::Vector3d& move_b) const;
  Eigen::Vector3d sideOfA(const ResolvingPair& pair);
  /// Whether moving `object` along the unit `direction` drives it into a fixed object that
  /// pushed it off in this response (within 45 degrees of straight into it).
  bool againstFixedPartner(const Object& object, const Eigen::Vector3d& direction) const;
  /// One push per contact still too deep into the pair's scratch.
  void collectPushes(const ResolvingPair& pair);
  /// The surface of the fixed object's `node` that faces the dynamic one.
  FixedSurface fixedSurface(const ResolvingPair& pair, std::uint32_t node);
  TouchedSurface touchedSurface(const ResolvingPair& pair, const Eigen::Vector3d& away);
  bool pushFromFixedPlane(const ResolvingPair& pair, const SphereContact& contact,
                          ContactPush& push);
  void clearPassedPoints(ResolvingPair& pair);
  /// The least `touched.away` component of the object's points in line with the touched
  /// nodes (infinity if none).
  double lowestInLine(Object& moving, const TouchedSurface& touched,
                      std::vector<ReachingNode>& descent);
  /// The push of contact `contact`, of a pair between dynamic objects.
  bool pushBetweenDynamic(const ResolvingPair& pair, std::size_t contact, ContactPush& push) const;
  void moveByMeanPush(ResolvingPair& pair);
  void queueDents(const ResolvingPair& pair);
  void rememberSide(const ResolvingPair& pair, const Eigen::Vector3d& normal);
  void exchangeVelocities(ResolvingPair& pair, const Eigen::Vector3d& normal);
  /// Whether the pair sticks: its slip is taken back.
  bool holdStaticFriction(ResolvingPair& pair, const Eigen::Vector3d& normal, double share_a) const;

  /// One contact's push: depths along `normal` (from b to a) that a and b must move.
  struct ContactPush {
    std::uint32_t node_a = 0;
    std::uint32_t node_b = 0;
    double points_a = 0.0;  ///< Points of node_a: its weight in a's mean push.
    double points_b = 0.0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double depth_a = 0.0;
    double depth_b = 0.0;
    /// Against a fixed node: the level along the push, unmoved, where the moving object's
    /// points are clear of its surface by half the contact distance.
    double surface_m = 0.0;
  };

  Objects& objects_;
  const std::vector<SceneContact>& contacts_;
  std::vector<ContactRun>& contact_runs_;
  const SceneConfig& config_;

  /// What resolving one pair needs for itself: one per thread resolving pairs.
  struct PairScratch {
    std::vector<ContactPush> pushes;
    std::vector<ReachingNode> descent;  ///< lowestInLine's nodes to visit.
  };

  /// Per thread of the pool, the first the calling thread's.
  std::vector<PairScratch> scratch_;
  std::unique_ptr<detail::PairNormals> pair_normals_;
  std::unique_ptr<detail::ObjectGroups> fixed_groups_;
  /// Per pair with a fixed object, by its place in resolve_order_.
  std::vector<PairOutcome> fixed_outcomes_;
  std::vector<std::uint64_t> fixed_serials_;
  std::vector<std::uint32_t> support_queue_;
  std::vector<std::uint32_t> resolve_order_;  ///< contact_runs_ indices, supports first.
  /// The velocity exchanges of this response's pairs, in their order, for the later passes.
  std::vector<VelocityExchange> velocity_exchanges_;
  std::vector<FixedPairMove> fixed_pair_moves_;
  std::vector<std::uint32_t> neighbour_offsets_;
  std::vector<std::uint32_t> neighbour_fill_;
  std::vector<std::uint32_t> neighbours_;
  std::size_t points_displaced_ = 0;  ///< By this response's dents.
  std::uint64_t cycle_count_ = 1;
  std::uint64_t pair_serial_ = 0;  ///< Counts resolved pairs: keys each pair's dents.
};

}  // namespace deformable_collision
