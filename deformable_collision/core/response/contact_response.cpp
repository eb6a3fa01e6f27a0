// The contact response: each pair of touching objects is pushed apart along one normal and
// stops approaching, objects nearer to a fixed support acting as fixed (shock propagation).
#include <algorithm>
#include <limits>

#include "deformable_collision/core/response/detail/object_groups.h"
#include "deformable_collision/core/response/detail/pair_normals.h"
#include "deformable_collision/core/response/detail/resolving_pair.h"

namespace deformable_collision {
namespace {

/// cos 45 degrees: a fixed surface carries a dynamic object if it faces more up than sideways.
constexpr double kCarryingCosine = 0.70710678118654752;

/// The change of a's velocity relative to b's that stops their approach along `normal` and
/// brakes their sliding across it by at most `friction` times that (Coulomb).
Eigen::Vector3d stopApproach(const Eigen::Vector3d& relative, const Eigen::Vector3d& normal,
                             double friction) {
  const double approach = std::min(0.0, relative.dot(normal));
  const Eigen::Vector3d sliding = relative - relative.dot(normal) * normal;
  const double sliding_speed = sliding.norm();
  Eigen::Vector3d change = -approach * normal;
  if (sliding_speed > 0.0) {
    change -= std::min(sliding_speed, -friction * approach) / sliding_speed * sliding;
  }
  return change;
}

/// The change of a's velocity relative to b's that stops their approach along `normal` and
/// all their sliding across it (static friction).
Eigen::Vector3d stopSliding(const Eigen::Vector3d& relative, const Eigen::Vector3d& normal) {
  const double along = relative.dot(normal);
  return -std::min(0.0, along) * normal - (relative - along * normal);
}

}  // namespace

// Each run's link reads its objects, and the fixed one's planes and spheres, which are
// computed before on this thread; it writes only the run.
void ContactResponse::markSupportLinks(WorkerPool& pool) {
  if (pool.threads() == 1 || contact_runs_.size() < kRunsWorthSharing) {
    for (ContactRun& run : contact_runs_) run.support_link = isSupportLink(run);
    return;
  }
  prepareFixedSides();
  pool.forEach(contact_runs_.size(), [this](std::size_t r) {
    contact_runs_[r].support_link = isSupportLink(contact_runs_[r]);
  });
}

void ContactResponse::rankSupport() {
  constexpr std::uint32_t kUnsupported = std::numeric_limits<std::uint32_t>::max();
  // Adjacency of the touching pairs (the contact runs), in compressed rows.
  const std::size_t count = objects_.size();
  neighbour_offsets_.assign(count + 1, 0);
  for (const ContactRun& run : contact_runs_) {
    if (!run.support_link) continue;
    ++neighbour_offsets_[run.object_a + 1];
    ++neighbour_offsets_[run.object_b + 1];
  }
  for (std::size_t i = 0; i < count; ++i) neighbour_offsets_[i + 1] += neighbour_offsets_[i];
  neighbours_.resize(neighbour_offsets_[count]);
  neighbour_fill_.assign(neighbour_offsets_.begin(), neighbour_offsets_.end() - 1);
  for (const ContactRun& run : contact_runs_) {
    if (!run.support_link) continue;
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

ContactResponse::ContactResponse(Objects& objects, const std::vector<SceneContact>& contacts,
                                 std::vector<ContactRun>& runs, const SceneConfig& config)
    : objects_(objects),
      contacts_(contacts),
      contact_runs_(runs),
      config_(config),
      scratch_(1),
      pair_normals_(std::make_unique<detail::PairNormals>()),
      fixed_groups_(std::make_unique<detail::ObjectGroups>()) {}

ContactResponse::~ContactResponse() = default;

std::size_t ContactResponse::respond(WorkerPool& pool) {
  // Objects are separated to half the contact distance: resting objects stay in contact
  // (closer than the contact distance) and are still held apart.
  ++cycle_count_;
  points_displaced_ = 0;
  for (ContactRun& run : contact_runs_) {
    run.impulse_ns.setZero();
    for (const std::uint32_t index : {run.object_a, run.object_b}) {
      Object& object = *objects_[index];
      object.carried_impulse.setZero();
      object.support_impulse = 0.0;
      object.supports = 0;
    }
  }
  readMeanVelocities();
  markSupportLinks(pool);
  rankSupport();
  for (auto& object : objects_) object->contact_memory.forgetBefore(cycle_count_);
  measureDynamicNormals(pool);
  resolvePairs(pool);
  repeatVelocityExchanges();
  stopApproachToFixedPartners();
  if (config_.contact_forces) passCarriedImpulsesDown();
  for (const ContactRun& run : contact_runs_) {
    for (const std::uint32_t index : {run.object_a, run.object_b}) {
      Object& object = *objects_[index];
      object.velocity_after = object.mean_velocity + object.velocity_change;
    }
  }
  applyObjectResponses(pool);
  return points_displaced_;
}

void ContactResponse::readMeanVelocities() {
  for (const ContactRun& run : contact_runs_) {
    for (const std::uint32_t index : {run.object_a, run.object_b}) {
      Object& object = *objects_[index];
      if (object.mean_velocity_cycle == cycle_count_) continue;
      object.mean_velocity_cycle = cycle_count_;
      object.mean_velocity =
          object.dynamic() ? object.body.meanVelocity() : Eigen::Vector3d::Zero();
    }
  }
}

// A pair's normal between dynamic objects depends on its contacts, the spheres and leaf
// columns the query left and the side it remembers, none of which resolving other pairs
// changes.
void ContactResponse::measureDynamicNormals(WorkerPool& pool) {
  pair_normals_->clear(contact_runs_.size(), contacts_.size());
  for (std::uint32_t r = 0; r < contact_runs_.size(); ++r) {
    const ContactRun& run = contact_runs_[r];
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (!a.dynamic() || !b.dynamic()) continue;
    ResolvingPair pair{a,       b,     run.object_a, run.object_b,  run.begin,
                       run.end, false, false,        a.translation, b.translation};
    pair_normals_->add(r, sideOfA(pair));
  }
  pair_normals_->measure(pool, objects_, contacts_, contact_runs_, config_.contact_distance_m);
}

void ContactResponse::resolvePairs(WorkerPool& pool) {
  // Each pair of touching objects is resolved in two parts. The whole object moves by the
  // mean push of its contact nodes (weighted by their points) and stops approaching the
  // other along the pair's normal (perfectly inelastic between the centres of mass); only
  // what a node needs beyond that mean is pushed into the object locally, as a dent that
  // shape matching restores. A rigid object thus lands without deforming and a soft one
  // dents where it touches most. Velocity corrections of single nodes do not survive the
  // next goal step: it spreads them over the object, so a resting object sinks, or,
  // cancelling the motion the goals give the pushed points, bounces.
  // Shock propagation resolves the pairs from the supports up: a pair sees the objects under
  // it already stopped against what carries them. In contact order, an object stopped
  // against the one under it before that one's own pair with the floor was resolved kept
  // that one's step of gravity every cycle, held up by the pushes alone.
  resolve_order_.clear();
  for (std::uint32_t r = 0; r < contact_runs_.size(); ++r) resolve_order_.push_back(r);
  const auto nearer_support = [this](const ContactRun& run) {
    return std::min(objects_[run.object_a]->support_depth, objects_[run.object_b]->support_depth);
  };
  std::sort(resolve_order_.begin(), resolve_order_.end(), [&](std::uint32_t x, std::uint32_t y) {
    const std::uint32_t depth_x = nearer_support(contact_runs_[x]);
    const std::uint32_t depth_y = nearer_support(contact_runs_[y]);
    return depth_x != depth_y ? depth_x < depth_y : x < y;
  });
  velocity_exchanges_.clear();
  fixed_pair_moves_.clear();
  // The pairs with a fixed object come first (support depth 0); their moves are made
  // together before the pairs between dynamic objects are resolved.
  const auto dynamic_pairs =
      std::partition_point(resolve_order_.begin(), resolve_order_.end(),
                           [&](std::uint32_t r) { return nearer_support(contact_runs_[r]) == 0; });
  resolveFixedPairs(pool, static_cast<std::size_t>(dynamic_pairs - resolve_order_.begin()));
  moveByFixedPartners();
  std::for_each(dynamic_pairs, resolve_order_.end(), [this](std::uint32_t r) {
    Object& a = *objects_[contact_runs_[r].object_a];
    Object& b = *objects_[contact_runs_[r].object_b];
    PairOutcome outcome;
    resolvePair(a, b, r, scratch_.front(), ++pair_serial_, outcome);
    keepOutcome(outcome);
  });
}

// One pass over the pairs hands a push down to objects whose own supports it has already
// passed: between objects at the same depth (neighbours in a layer, each half carried by the
// other), an object wedged between tilted neighbours kept a velocity into them that the
// position pushes took back every cycle, never still. Later passes over the velocities alone,
// along each pair's normal and friction as decided in the first, let those exchanges settle;
// the positions stay as the first pass left them. Four passes let the S2 pile come to rest at
// every level, the root spheres of level 0 included (docs/design.md, "Velocity passes").
void ContactResponse::repeatVelocityExchanges() {
  constexpr int kPasses = 4;
  for (int pass = 0; pass < kPasses; ++pass) {
    for (const VelocityExchange& exchange : velocity_exchanges_) exchangeVelocity(exchange);
  }
}

// The pair's relative velocity is taken after this response's changes so far (a fixed
// object is at rest).
void ContactResponse::exchangeVelocity(const VelocityExchange& exchange) {
  Object& a = *objects_[exchange.object_a];
  Object& b = *objects_[exchange.object_b];
  const Eigen::Vector3d relative =
      (a.mean_velocity + a.velocity_change) - (b.mean_velocity + b.velocity_change);
  const Eigen::Vector3d change = exchange.sticks
                                     ? stopSliding(relative, exchange.normal)
                                     : stopApproach(relative, exchange.normal, config_.friction);
  if (a.dynamic()) a.velocity_change += exchange.share_a * change;
  if (b.dynamic()) b.velocity_change -= (1.0 - exchange.share_a) * change;
  // An object nearer to the support acts as fixed (share 0 or 1): the momentum is what the
  // moving one took, and the one acting as fixed carries it on to its own supports.
  if (!config_.contact_forces) return;
  const Eigen::Vector3d impulse =
      exchange.share_a > 0.0 ? Eigen::Vector3d(a.body.config().mass_kg * exchange.share_a * change)
                             : Eigen::Vector3d(b.body.config().mass_kg * change);
  contact_runs_[exchange.run].impulse_ns += impulse;
  if (exchange.share_a == 0.0 && a.dynamic()) a.carried_impulse += impulse;
  if (exchange.share_a == 1.0 && b.dynamic()) b.carried_impulse -= impulse;
}

bool ContactResponse::supportsFrom(const ContactRun& run, std::uint32_t& upper,
                                   std::uint32_t& lower) const {
  const Object& a = *objects_[run.object_a];
  const Object& b = *objects_[run.object_b];
  if (!run.support_link || a.support_depth == b.support_depth) return false;
  upper = a.support_depth > b.support_depth ? run.object_a : run.object_b;
  lower = upper == run.object_a ? run.object_b : run.object_a;
  return objects_[upper]->dynamic();
}

// Pairs come in resolve_order_ from the supports up; walked backwards, every pair that hands
// momentum to an object comes before the pairs under it, which hand it on. Each support takes
// a share by the momentum it already gave the object (equal shares if none).
void ContactResponse::passCarriedImpulsesDown() {
  std::uint32_t upper = 0, lower = 0;
  for (const ContactRun& run : contact_runs_) {
    if (!supportsFrom(run, upper, lower)) continue;
    Object& object = *objects_[upper];
    object.support_impulse += run.impulse_ns.norm();
    ++object.supports;
  }
  for (auto r = resolve_order_.rbegin(); r != resolve_order_.rend(); ++r) {
    ContactRun& run = contact_runs_[*r];
    if (!supportsFrom(run, upper, lower)) continue;
    const Object& object = *objects_[upper];
    const double share = object.support_impulse > 0.0
                             ? run.impulse_ns.norm() / object.support_impulse
                             : 1.0 / object.supports;
    const Eigen::Vector3d handed = share * object.carried_impulse;
    addImpulse(*r, object, -handed);
    if (objects_[lower]->dynamic()) objects_[lower]->carried_impulse += handed;
  }
}

void ContactResponse::addImpulse(std::uint32_t run, const Object& object,
                                 const Eigen::Vector3d& impulse) {
  ContactRun& r = contact_runs_[run];
  if (objects_[r.object_a].get() == &object) {
    r.impulse_ns += impulse;
  } else {
    r.impulse_ns -= impulse;
  }
}

// A pair resolved after an object's pair with a fixed one may push it back into the fixed
// one: two objects that both reach the floor share their pushes, and the upper one's share
// drives the lower one down after the floor stopped it. It would then leave the response
// moving into the floor while the floor holds its position, gain a step of gravity every
// cycle and never rest. So every object stops approaching the fixed objects it was pushed
// off, once all pairs have changed its velocity; the fixed object takes that momentum.
void ContactResponse::stopApproachToFixedPartners() {
  for (std::uint32_t r = 0; r < contact_runs_.size(); ++r) {
    const ContactRun& run = contact_runs_[r];
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (a.dynamic() == b.dynamic()) continue;
    Object& moving = a.dynamic() ? a : b;
    const auto* side = moving.contact_memory.find(a.dynamic() ? run.object_b : run.object_a);
    if (!side || side->cycle != cycle_count_) continue;
    const double approach = (moving.mean_velocity + moving.velocity_change).dot(side->normal);
    if (approach >= 0.0) continue;
    moving.velocity_change -= approach * side->normal;
    if (config_.contact_forces) {
      addImpulse(r, moving, -approach * moving.body.config().mass_kg * side->normal);
    }
  }
}

void ContactResponse::resolvePair(Object& a, Object& b, std::uint32_t run, PairScratch& scratch,
                                  std::uint64_t serial, PairOutcome& outcome) {
  const ContactRun& r = contact_runs_[run];
  const std::uint32_t index_a = r.object_a;
  const std::uint32_t index_b = r.object_b;
  const std::size_t run_begin = r.begin;
  const std::size_t run_end = r.end;
  // Pushes per contact, for a (along +normal) and b (along -normal): a node's depth along
  // a normal from b to a, shared by inverse mass between dynamic nodes.
  scratch.pushes.clear();
  ResolvingPair pair{a,
                     b,
                     index_a,
                     index_b,
                     run_begin,
                     run_end,
                     a.dynamic() != b.dynamic(),
                     contacts_[run_begin].contact.point_a != SphereContact::kNoPoint,
                     a.translation,
                     b.translation};
  pair.run = run;
  pair.scratch = &scratch;
  pair.serial = serial;
  pair.outcome = &outcome;
  pair.held = heldContact(pair);
  if (pair.one_side_fixed) {
    pair.side_of_a = sideOfA(pair);
  } else {
    pair.side_of_a = pair_normals_->sideOfA(run);
    pair.dynamic_normal = pair_normals_->normal(run);
    pair.a_against_fixed = againstFixedPartner(a, pair.dynamic_normal);
    pair.b_against_fixed = againstFixedPartner(b, -pair.dynamic_normal);
  }
  collectPushes(pair);
  if (scratch.pushes.empty()) {
    holdClearContact(pair);
    return;
  }
  moveByMeanPush(pair);
  if (pair.one_side_fixed) clearPassedPoints(pair);
  // Dents wait until every pair has moved the object: a later pair may move it back, as
  // the second jaw of a gripper does, and a dent sized against this pair's move alone
  // would leave the first jaw's contact deep inside.
  if (pair.leaves || pair.one_side_fixed) queueDents(pair);
  const Eigen::Vector3d normal = pair.normal_sum.normalized();
  rememberSide(pair, normal);
  exchangeVelocities(pair, normal);
}

bool ContactResponse::againstFixedPartner(const Object& object,
                                          const Eigen::Vector3d& direction) const {
  for (const auto& side : object.contact_memory.sides) {
    if (side.cycle != cycle_count_ || objects_[side.partner]->dynamic()) continue;
    // Within 45 degrees of straight into the partner, the cone in which a surface carries.
    if (side.normal.dot(direction) < -kCarryingCosine) return true;
  }
  return false;
}

// A pair in contact whose points are all clear of half the contact distance needs no push,
// but a contact seen in the last cycle still stops the approach along its side: a resting
// object that a later pair lifted a little would otherwise fall freely for a cycle, pass
// half the contact distance and be pushed back, and never rest.
void ContactResponse::holdClearContact(ResolvingPair& pair) {
  if (!pair.held) return;
  const Eigen::Vector3d normal = pair.side_of_a.normalized();
  rememberSide(pair, normal);
  exchangeVelocities(pair, normal);
}

// The side a lies on, seen from b: as in the last cycle of this contact, or for a new
// contact, where the objects' centres are. A fixed object's centre says little (a wall's
// lies a metre above what touches it), so its side is where its touched nodes are, and the
// dynamic one's is where it was before the step: a long step may carry its centre past a
// thin floor's nodes, and seen from there the floor would push it on through.
Eigen::Vector3d ContactResponse::sideOfA(const ResolvingPair& pair) {
  Object& a = pair.a;
  Object& b = pair.b;
  Object& remembering = a.dynamic() ? a : b;
  const std::uint32_t partner = &remembering == &a ? pair.index_b : pair.index_a;
  const auto* remembered = remembering.contact_memory.find(partner);
  if (remembered && remembered->cycle + 1 >= cycle_count_) {
    return &remembering == &a ? remembered->normal : Eigen::Vector3d(-remembered->normal);
  }
  if (!pair.one_side_fixed) return a.tree.sphere(0).center - b.tree.sphere(0).center;
  const bool a_fixed = !a.dynamic();
  Object& fixed = a_fixed ? a : b;
  Eigen::Vector3d touched = Eigen::Vector3d::Zero();
  for (std::size_t k = pair.run_begin; k < pair.run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    touched += fixed.tree.sphere(a_fixed ? c.node_a : c.node_b).center;
  }
  touched /= static_cast<double>(pair.run_end - pair.run_begin);
  const Eigen::Vector3d& moving_center = (a_fixed ? b : a).center_before_step;
  return a_fixed ? Eigen::Vector3d(touched - moving_center)
                 : Eigen::Vector3d(moving_center - touched);
}

Eigen::Vector3d ContactResponse::stepOf(const Object& object) const {
  return config_.dt_s * object.mean_velocity;
}

bool ContactResponse::heldContact(const ResolvingPair& pair) {
  Object& remembering = pair.a.dynamic() ? pair.a : pair.b;
  const auto* remembered =
      remembering.contact_memory.find(&remembering == &pair.a ? pair.index_b : pair.index_a);
  return remembered && remembered->cycle + 1 >= cycle_count_;
}

void ContactResponse::rememberSide(const ResolvingPair& pair, const Eigen::Vector3d& normal) {
  Object& remembering = pair.a.dynamic() ? pair.a : pair.b;
  const bool is_a = &remembering == &pair.a;
  remembering.contact_memory.remember(is_a ? pair.index_b : pair.index_a,
                                      is_a ? normal : Eigen::Vector3d(-normal), cycle_count_);
}

// Gauss-Seidel over the pairs: each sees the velocity changes of the pairs before it; a
// Jacobi sweep stops an object resting on two others twice, and piles explode.
void ContactResponse::exchangeVelocities(ResolvingPair& pair, const Eigen::Vector3d& normal) {
  Object& a = pair.a;
  Object& b = pair.b;
  // Shock propagation (Guendelman et al. 2003): of two touching objects, the one nearer to
  // a fixed support acts as fixed, so that pushes never drive an object into what carries
  // it, such as the bottom of a pile into the floor or a wall.
  const double inverse_mass_a =
      a.dynamic() && a.support_depth >= b.support_depth ? 1.0 / a.body.config().mass_kg : 0.0;
  const double inverse_mass_b =
      b.dynamic() && b.support_depth >= a.support_depth ? 1.0 / b.body.config().mass_kg : 0.0;
  const double share_a = inverse_mass_a / (inverse_mass_a + inverse_mass_b);
  // A pair that sticks in position sticks in velocity too: a sliding velocity kept while
  // the slip is taken back each cycle moves nothing, and it stays. On a coarse normal tilted
  // past the friction cone, a resting object kept sliding down it at a steady few cm/s while
  // its position stood still, and the objects it carried took that velocity on.
  const bool sticks = holdStaticFriction(pair, normal, share_a);
  PairOutcome& outcome = *pair.outcome;
  outcome.exchanged = true;
  outcome.exchange = {pair.index_a, pair.index_b, normal, share_a, sticks, pair.run};
  exchangeVelocity(outcome.exchange);
  if (pair.one_side_fixed) {
    const bool a_moves = a.dynamic();
    outcome.fixed_move = true;
    outcome.move = {a_moves ? pair.index_a : pair.index_b, 0,
                    a_moves ? normal : Eigen::Vector3d(-normal),
                    a_moves ? pair.move_a : pair.move_b};
    return;
  }
  if (a.dynamic()) a.translation += pair.move_a;
  if (b.dynamic()) b.translation += pair.move_b;
}

// Static friction on the positions: what the pair slid across its normal over the cycle,
// the step and every push so far, is taken back while it is inside the friction cone of
// this push. A resting object is pushed back each cycle by what gravity moved it, along
// normals that are never exact (fitted planes, nearest point pairs); without this it walks
// sideways, by a normal's tilt times g h^2 per cycle. Sliding contacts are left to the
// velocity friction. Only where one side holds (fixed, or nearer to a support): between two
// objects carried alike, taking the slip back moves both against supports this pass does
// not see, and a bar leaning on a ball would lift the ball off the floor.
// A sticking pair separates back along the way it came together (the step and the pushes
// before this pair), not along the normal: a coarse normal between two dynamic objects
// tilts by some degrees, and a box in a stack, lifted a little along it each cycle and
// falling back straight, would walk off the box below.
bool ContactResponse::holdStaticFriction(ResolvingPair& pair, const Eigen::Vector3d& normal,
                                         double share_a) const {
  const Object& a = pair.a;
  const Object& b = pair.b;
  const Eigen::Vector3d step_a = stepOf(a);
  const Eigen::Vector3d step_b = stepOf(b);
  const Eigen::Vector3d moved = (step_a + pair.translation_before_a + pair.move_a) -
                                (step_b + pair.translation_before_b + pair.move_b);
  const Eigen::Vector3d slip = moved - moved.dot(normal) * normal;
  const double pressed = (pair.move_a - pair.move_b).dot(normal);
  const bool one_side_holds = share_a == 0.0 || share_a == 1.0;
  if (!one_side_holds || slip.norm() > config_.friction * pressed) return false;
  const Eigen::Vector3d came =
      (step_b + pair.translation_before_b) - (step_a + pair.translation_before_a);
  const double came_along = came.dot(normal);
  Eigen::Vector3d change = -slip;
  if (came_along > 0.0 && (came - came_along * normal).norm() <= config_.friction * came_along) {
    change = moved.dot(normal) / came_along * came - moved;
  }
  pair.move_a += share_a * change;
  pair.move_b -= (1.0 - share_a) * change;
  return true;
}

// Whether a run links its objects in rankSupport. Between dynamic objects always; between a
// fixed object and a dynamic one when the fixed one carries it: when the dynamic object lay
// within the contact distance of the touched surface before this cycle's step. After a long
// step, an object high in a stack may have come within reach of the floor only because the
// objects under it sank into the floor in the same step; counted as carried by the floor it
// would share its pushes with them and drive them further in.
bool ContactResponse::isSupportLink(const ContactRun& run) {
  Object& a = *objects_[run.object_a];
  Object& b = *objects_[run.object_b];
  if (a.dynamic() == b.dynamic()) return true;
  ResolvingPair pair{a,
                     b,
                     run.object_a,
                     run.object_b,
                     run.begin,
                     run.end,
                     true,
                     contacts_[run.begin].contact.point_a != SphereContact::kNoPoint,
                     Eigen::Vector3d::Zero(),
                     Eigen::Vector3d::Zero()};
  pair.side_of_a = sideOfA(pair);
  const bool a_fixed = !a.dynamic();
  const Object& moving = a_fixed ? b : a;
  // Along the touched nodes' planes, as the pushes will be: the side the objects' centres
  // give is tilted wherever the dynamic object is not right above a fixed node's centre.
  Eigen::Vector3d away = Eigen::Vector3d::Zero();
  for (std::size_t k = run.begin; k < run.end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    away += fixedSurface(pair, a_fixed ? c.node_a : c.node_b).away;
  }
  // Only a surface that faces more up than sideways carries what lies on it. A wall beside
  // an object of a pile would otherwise rank it with the objects on the floor: sharing the
  // stop of each step of gravity with the one it rests on, which the floor then stops
  // whole, it would keep half of it every cycle and be held up by the pushes alone.
  const double gravity = config_.gravity_mps2.norm();
  if (gravity > 0.0 && -away.normalized().dot(config_.gravity_mps2) < kCarryingCosine * gravity) {
    return false;
  }
  const TouchedSurface touched = touchedSurface(pair, away.normalized());
  const auto& positions = moving.body.positions();
  const auto& velocities = moving.body.velocities();
  const double reach = touched.level + config_.contact_distance_m;
  const auto carried = [&](std::uint32_t point) {
    const Eigen::Vector3d before = positions[point] - config_.dt_s * velocities[point];
    return before.dot(touched.away) < reach && touched.inLine(before);
  };
  // A resting object's contact nodes hold such a point: the whole object is read only when
  // they do not.
  const auto& indices = moving.tree.pointIndices();
  for (std::size_t k = run.begin; k < run.end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    const SphereNode& node = moving.tree.node(a_fixed ? c.node_b : c.node_a);
    for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
      if (carried(indices[s])) return true;
    }
  }
  for (std::uint32_t i = 0; i < positions.size(); ++i) {
    if (carried(i)) return true;
  }
  return false;
}

}  // namespace deformable_collision
