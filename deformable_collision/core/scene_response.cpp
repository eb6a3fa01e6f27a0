// The contact response: each pair of touching objects is pushed apart along one normal and
// stops approaching, objects nearer to a fixed support acting as fixed (shock propagation).
#include <algorithm>
#include <limits>

#include "deformable_collision/core/scene_object.h"

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

namespace scene_internal {

ContactMemory::ContactSide* ContactMemory::find(std::uint32_t partner) {
  for (ContactSide& side : sides) {
    if (side.partner == partner) return &side;
  }
  return nullptr;
}

void ContactMemory::remember(std::uint32_t partner, const Eigen::Vector3d& normal,
                             std::uint64_t cycle) {
  if (ContactSide* side = find(partner)) {
    side->normal = normal;
    side->cycle = cycle;
  } else {
    sides.push_back({partner, normal, cycle});
  }
}

void ContactMemory::forgetBefore(std::uint64_t cycle) {
  sides.erase(std::remove_if(sides.begin(), sides.end(),
                             [&](const ContactSide& side) { return side.cycle + 1 < cycle; }),
              sides.end());
}

}  // namespace scene_internal

void Scene::rankSupport() {
  constexpr std::uint32_t kUnsupported = std::numeric_limits<std::uint32_t>::max();
  // Adjacency of the touching pairs (the contact runs), in compressed rows.
  const std::size_t count = objects_.size();
  neighbour_offsets_.assign(count + 1, 0);
  for (ContactRun& run : contact_runs_) {
    run.support_link = isSupportLink(run);
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

void Scene::respond() {
  // Objects are separated to half the contact distance: resting objects stay in contact
  // (closer than the contact distance) and are still held apart.
  ++cycle_count_;
  for (const ContactRun& run : contact_runs_) {
    for (const std::uint32_t index : {run.object_a, run.object_b}) {
      Object& object = *objects_[index];
      if (object.mean_velocity_cycle == cycle_count_) continue;
      object.mean_velocity_cycle = cycle_count_;
      object.mean_velocity =
          object.dynamic() ? object.body.meanVelocity() : Eigen::Vector3d::Zero();
    }
  }
  rankSupport();
  for (auto& object : objects_) object->contact_memory.forgetBefore(cycle_count_);
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
  const auto resolve = [this](std::uint32_t r) {
    const ContactRun& run = contact_runs_[r];
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (a.dynamic() || b.dynamic()) resolvePair(a, b, run.object_a, run.object_b, run.begin, run.end);
  };
  // The pairs with a fixed object come first (support depth 0); their moves are made
  // together before the pairs between dynamic objects are resolved.
  const auto dynamic_pairs =
      std::partition_point(resolve_order_.begin(), resolve_order_.end(),
                           [&](std::uint32_t r) { return nearer_support(contact_runs_[r]) == 0; });
  std::for_each(resolve_order_.begin(), dynamic_pairs, resolve);
  moveByFixedPartners();
  std::for_each(dynamic_pairs, resolve_order_.end(), resolve);
  repeatVelocityExchanges();
  stopApproachToFixedPartners();
  for (const ContactRun& run : contact_runs_) {
    for (const std::uint32_t index : {run.object_a, run.object_b}) {
      Object& object = *objects_[index];
      object.velocity_after = object.mean_velocity + object.velocity_change;
    }
  }
  for (auto& object : objects_) {
    if (object->dynamic()) applyObjectResponse(*object);
  }
  // Queries between cycles see the state after the response.
  refreshStaleTrees();
}

// An object between fixed ones, such as a fruit in a gripper's closed jaws, is pushed from
// opposite sides. Resolved one after the other, the later pair took the object clear of its
// own partner whatever the earlier one had moved it, and so deep into that one: the squeezed
// fruit sat 2.5 cm towards the jaw resolved first, and at coarse levels swung by 3 to 4 cm.
// So each of these pairs is resolved on the object as the dynamic pairs left it (none: they
// come later), and their moves are combined here. Along the pairs' normals one after the
// other, each adding only what the moves before left short of its own, as the pairs would,
// once in each order and averaged: pushes from one side take the largest, from two sides
// at right angles both, and opposed pushes meet halfway. Across the normals (what static
// friction takes back) their mean.
void Scene::moveByFixedPartners() {
  std::sort(fixed_pair_moves_.begin(), fixed_pair_moves_.end(),
            [](const FixedPairMove& x, const FixedPairMove& y) {
              return x.object != y.object ? x.object < y.object : x.serial < y.serial;
            });
  const auto add_shortfall = [](Eigen::Vector3d& along, const FixedPairMove& pair) {
    const double short_of = (pair.move - along).dot(pair.normal);
    if (short_of > 0.0) along += short_of * pair.normal;
  };
  for (auto begin = fixed_pair_moves_.begin(); begin != fixed_pair_moves_.end();) {
    auto end = begin + 1;
    while (end != fixed_pair_moves_.end() && end->object == begin->object) ++end;
    Object& object = *objects_[begin->object];
    if (end - begin == 1) {
      object.translation += begin->move;
      begin = end;
      continue;
    }
    Eigen::Vector3d forward = Eigen::Vector3d::Zero();
    Eigen::Vector3d backward = Eigen::Vector3d::Zero();
    Eigen::Vector3d across = Eigen::Vector3d::Zero();
    int across_count = 0;
    for (auto pair = begin; pair != end; ++pair) {
      add_shortfall(forward, *pair);
      const Eigen::Vector3d tangential = pair->move - pair->move.dot(pair->normal) * pair->normal;
      if (tangential.squaredNorm() == 0.0) continue;
      across += tangential;
      ++across_count;
    }
    for (auto pair = end; pair != begin;) add_shortfall(backward, *--pair);
    object.translation += 0.5 * (forward + backward);
    if (across_count > 0) object.translation += across / across_count;
    begin = end;
  }
}

// One pass over the pairs hands a push down to objects whose own supports it has already
// passed: between objects at the same depth (neighbours in a layer, each half carried by the
// other), an object wedged between tilted neighbours kept a velocity into them that the
// position pushes took back every cycle, never still. Later passes over the velocities alone,
// along each pair's normal and friction as decided in the first, let those exchanges settle;
// the positions stay as the first pass left them. Four passes let the S2 pile come to rest at
// every level, the root spheres of level 0 included (docs/design.md, "Velocity passes").
void Scene::repeatVelocityExchanges() {
  constexpr int kPasses = 4;
  for (int pass = 0; pass < kPasses; ++pass) {
    for (const VelocityExchange& exchange : velocity_exchanges_) exchangeVelocity(exchange);
  }
}

// The pair's relative velocity is taken after this response's changes so far (a fixed
// object is at rest).
void Scene::exchangeVelocity(const VelocityExchange& exchange) {
  Object& a = *objects_[exchange.object_a];
  Object& b = *objects_[exchange.object_b];
  const Eigen::Vector3d relative =
      (a.mean_velocity + a.velocity_change) - (b.mean_velocity + b.velocity_change);
  const Eigen::Vector3d change = exchange.sticks
                                     ? stopSliding(relative, exchange.normal)
                                     : stopApproach(relative, exchange.normal, config_.friction);
  if (a.dynamic()) a.velocity_change += exchange.share_a * change;
  if (b.dynamic()) b.velocity_change -= (1.0 - exchange.share_a) * change;
}

// A pair resolved after an object's pair with a fixed one may push it back into the fixed
// one: two objects that both reach the floor share their pushes, and the upper one's share
// drives the lower one down after the floor stopped it. It would then leave the response
// moving into the floor while the floor holds its position, gain a step of gravity every
// cycle and never rest. So every object stops approaching the fixed objects it was pushed
// off, once all pairs have changed its velocity; the fixed object takes that momentum.
void Scene::stopApproachToFixedPartners() {
  for (const ContactRun& run : contact_runs_) {
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (a.dynamic() == b.dynamic()) continue;
    Object& moving = a.dynamic() ? a : b;
    const auto* side = moving.contact_memory.find(a.dynamic() ? run.object_b : run.object_a);
    if (!side || side->cycle != cycle_count_) continue;
    const double approach =
        (moving.mean_velocity + moving.velocity_change).dot(side->normal);
    if (approach < 0.0) moving.velocity_change -= approach * side->normal;
  }
}

void Scene::applyObjectResponse(Object& object) {
  object.applyPendingDents(objects_);
  const bool moved = object.translation.squaredNorm() > 0.0 ||
                     object.velocity_change.squaredNorm() > 0.0 ||
                     !object.dents.displaced_points.empty();
  if (!moved) return;
  // An object moves at most the contact distance per response beyond what this cycle's
  // step moved it, so it cannot jump past a layer thinner than that before the layer's
  // contacts are seen; deeper overlaps take a few cycles. The step's own motion can always
  // be undone: with a long step, gravity alone takes a resting object deeper than the
  // contact distance (g h^2 = 2.5 cm at h = 0.05 s), and a smaller cap sinks it.
  const double allowed =
      config_.contact_distance_m + config_.dt_s * object.body.meanVelocity().norm();
  const double reach = object.translation.norm();
  if (reach > allowed) object.translation *= allowed / reach;
  object.dents.averageDisplacements();
  if (object.dents.displacements.empty()) {
    // The points make the move in the next step's pass over them.
    object.body.deferRigidMove(object.translation, object.velocity_change);
  } else {
    const RigidMotion motion = object.body.rigidMotion();
    const Sphere& bound = object.tree.sphere(0);
    const scene_internal::RigidVelocityChange balance = object.dents.balanceVelocityChanges(
        object.body.positions(), motion, object.body.pointMassKg(),
        (bound.center - motion.center).norm() + bound.radius);
    object.body.moveRigidly(object.translation, object.velocity_change - balance.velocity,
                            -balance.spin, balance.center + object.translation);
    stats_.points_displaced += object.dents.displacements.size();
    object.body.displacePoints(object.dents.displacements);
  }
  object.translation.setZero();
  object.velocity_change.setZero();
  object.stale = true;
}

void Scene::resolvePair(Object& a, Object& b, std::uint32_t index_a, std::uint32_t index_b,
                        std::size_t run_begin, std::size_t run_end) {
  // Pushes per contact, for a (along +normal) and b (along -normal): a node's depth along
  // a normal from b to a, shared by inverse mass between dynamic nodes.
  pushes_.clear();
  ++pair_serial_;
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
  pair.held = heldContact(pair);
  pair.side_of_a = sideOfA(pair);
  if (!pair.one_side_fixed) {
    pair.dynamic_normal = separatingNormal(pair);
    pair.a_against_fixed = againstFixedPartner(a, pair.dynamic_normal);
    pair.b_against_fixed = againstFixedPartner(b, -pair.dynamic_normal);
  }
  collectPushes(pair);
  if (pushes_.empty()) {
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

bool Scene::againstFixedPartner(const Object& object, const Eigen::Vector3d& direction) const {
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
void Scene::holdClearContact(ResolvingPair& pair) {
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
Eigen::Vector3d Scene::sideOfA(const ResolvingPair& pair) {
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

void Scene::collectPushes(const ResolvingPair& pair) {
  for (std::size_t k = pair.run_begin; k < pair.run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    ContactPush push;
    push.node_a = c.node_a;
    push.node_b = c.node_b;
    push.points_a = pair.a.tree.node(c.node_a).point_count;
    push.points_b = pair.b.tree.node(c.node_b).point_count;
    const bool pushed = pair.one_side_fixed ? pushFromFixedPlane(pair, c, push)
                                            : pushBetweenDynamic(pair, c, push);
    if (pushed) pushes_.push_back(push);
  }
}

struct Scene::FixedSurface {
  Eigen::Vector3d away;         ///< The node's plane normal, towards the dynamic object.
  Eigen::Vector3d plane_point;  ///< The node's sphere centre.
  double reach = 0.0;           ///< How far the object's surface lies from it along away.
};

Scene::FixedSurface Scene::fixedSurface(const ResolvingPair& pair, std::uint32_t node) {
  const bool a_fixed = !pair.a.dynamic();
  Object& fixed = a_fixed ? pair.a : pair.b;
  const int cluster = std::max(0, fixed.tree.node(node).cluster);
  FixedSurface surface{fixed.body.deformation(cluster).rotation * fixed.planes.normals[node],
                       fixed.tree.sphere(node).center, fixed.planes.extent_along[node]};
  if (surface.away.dot(a_fixed ? Eigen::Vector3d(-pair.side_of_a) : pair.side_of_a) < 0.0) {
    surface.away = -surface.away;
    surface.reach = fixed.planes.extent_against[node];
  }
  return surface;
}

// Against a fixed object: its node's plane, oriented towards the dynamic object, and the
// deepest point's signed distance. Unlike the distance to the nearest point, that depth
// does not shrink or flip when points have passed a thin layer such as a floor.
bool Scene::pushFromFixedPlane(const ResolvingPair& pair, const SphereContact& c,
                               ContactPush& push) {
  const bool a_fixed = !pair.a.dynamic();
  Object& moving = a_fixed ? pair.b : pair.a;
  const FixedSurface surface = fixedSurface(pair, a_fixed ? c.node_a : c.node_b);
  const std::uint32_t moving_node = a_fixed ? c.node_b : c.node_a;
  const SphereNode& node = moving.tree.node(moving_node);
  // The object has not moved in this response yet: the pairs with fixed objects come first,
  // and their moves wait for moveByFixedPartners. The node's sphere bounds its points along
  // the plane's normal: where even its lowest point leaves no depth, no point does, and the
  // points are not read (a coarse node holds hundreds, and many of a pile's coarse contacts
  // with a floor or a wall are such). The margin is far above the rounding of these sums, so
  // the outcome is the points' own.
  const Sphere& bound = moving.tree.sphere(moving_node);
  const Eigen::Vector3d from_plane = bound.center - surface.plane_point;
  const double margin = 1e-12 * (from_plane.norm() + bound.radius + std::abs(surface.reach) +
                                 config_.contact_distance_m);
  if (surface.reach + 0.5 * config_.contact_distance_m -
          (from_plane.dot(surface.away) - bound.radius - margin) <=
      0.0) {
    return false;
  }
  double deepest = std::numeric_limits<double>::infinity();
  const auto& positions = moving.body.positions();
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    deepest = std::min(deepest, (positions[moving.tree.pointIndices()[s]] - surface.plane_point)
                                    .dot(surface.away));
  }
  const double depth = surface.reach + 0.5 * config_.contact_distance_m - deepest;
  if (depth <= 0.0) return false;
  push.normal = a_fixed ? Eigen::Vector3d(-surface.away) : surface.away;
  push.depth_a = a_fixed ? 0.0 : depth;
  push.depth_b = a_fixed ? depth : 0.0;
  push.surface_m = surface.plane_point.dot(surface.away) + surface.reach +
                   0.5 * config_.contact_distance_m;
  return true;
}

/// The fixed object's touched nodes seen along `away` (from the fixed object towards the
/// dynamic one): the highest of their surfaces, and the region across `away` that their
/// spheres cover, where a point of the dynamic object lies in line with them.
struct Scene::TouchedSurface {
  Eigen::Vector3d away;
  Eigen::Vector3d across_u;
  Eigen::Vector3d across_v;
  Eigen::AlignedBox2d in_line;
  double level = -std::numeric_limits<double>::infinity();

  bool inLine(const Eigen::Vector3d& point) const {
    return in_line.contains(Eigen::Vector2d(point.dot(across_u), point.dot(across_v)));
  }
};

Scene::TouchedSurface Scene::touchedSurface(const ResolvingPair& pair,
                                            const Eigen::Vector3d& away) {
  const bool a_fixed = !pair.a.dynamic();
  Object& fixed = a_fixed ? pair.a : pair.b;
  TouchedSurface touched{away, away.unitOrthogonal(), Eigen::Vector3d::Zero(), {}};
  touched.across_v = away.cross(touched.across_u);
  for (std::size_t k = pair.run_begin; k < pair.run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    const std::uint32_t node = a_fixed ? c.node_a : c.node_b;
    const FixedSurface surface = fixedSurface(pair, node);
    touched.level = std::max(touched.level, surface.plane_point.dot(away) + surface.reach);
    const Sphere& sphere = fixed.tree.sphere(node);
    const Eigen::Vector2d across(sphere.center.dot(touched.across_u),
                                 sphere.center.dot(touched.across_v));
    touched.in_line.extend(across - Eigen::Vector2d::Constant(sphere.radius));
    touched.in_line.extend(across + Eigen::Vector2d::Constant(sphere.radius));
  }
  return touched;
}

// A long step carries points of a dynamic object past a thin fixed layer, beyond the
// contact distance of any of its points, where no contact sees them; the contacts' pushes
// then undo only about the layer's thickness of a step that took more. So the deepest of
// the object's points in line with the touched nodes (within their spheres across the
// pair's normal), measured against the highest of their surfaces, is brought back by moving
// the whole object when the pair's move leaves it deeper than that: nothing dents it.
void Scene::clearPassedPoints(ResolvingPair& pair) {
  const bool a_fixed = !pair.a.dynamic();
  Object& moving = a_fixed ? pair.b : pair.a;
  const TouchedSurface touched =
      touchedSurface(pair, (a_fixed ? -1.0 : 1.0) * pair.normal_sum.normalized());
  const Eigen::Vector3d& away = touched.away;
  const double lowest = lowestInLine(moving, touched);
  // As in pushFromFixedPlane, the object has not moved in this response yet.
  const double depth = touched.level + 0.5 * config_.contact_distance_m - lowest;
  double deepest_push = 0.0;
  for (const ContactPush& push : pushes_) deepest_push = std::max(deepest_push, push.depth_a + push.depth_b);
  // Points past the contacts' reach are cleared; those within it only brought back within
  // the contact distance, where the next cycle's contacts see them. Even within it the
  // contacts only dent their own nodes' points, and a soft object moves by less than its
  // deepest push: the points in line outside those nodes would stay where the step put them.
  const double needed =
      depth > deepest_push + config_.contact_distance_m ? depth : depth - config_.contact_distance_m;
  Eigen::Vector3d& move = a_fixed ? pair.move_b : pair.move_a;
  const double moved = move.dot(away);
  if (moved < needed) move += (needed - moved) * away;
}

// Down the object's tree rather than over all its points: a gripper's fruit held between two
// jaws on a floor read its 10,000 points three times a cycle, 6% of the demo scene's cycle.
// A node is opened only if its sphere lies in line with the touched nodes and reaches below
// the lowest point found so far, the lowest reaching first, so that the bound tightens
// early. The margin keeps rounding from pruning a point the scan would have taken, so the
// result is the scan's to the bit.
double Scene::lowestInLine(Object& moving, const TouchedSurface& touched) {
  const Eigen::Vector3d& away = touched.away;
  const auto& positions = moving.body.positions();
  const auto& indices = moving.tree.pointIndices();
  double lowest = std::numeric_limits<double>::infinity();
  // The least `away` component the sphere allows its points, or nothing if none of them can
  // be in line.
  const auto reach_in_line = [&](const Sphere& sphere) -> std::optional<double> {
    const double margin = 1e-12 * (sphere.center.norm() + sphere.radius);
    const Eigen::Vector2d across(sphere.center.dot(touched.across_u),
                                 sphere.center.dot(touched.across_v));
    const Eigen::AlignedBox2d box(across.array() - (sphere.radius + margin),
                                  across.array() + (sphere.radius + margin));
    if (!box.intersects(touched.in_line)) return std::nullopt;
    return sphere.center.dot(away) - sphere.radius - margin;
  };
  lowest_descent_.clear();
  if (const auto root = reach_in_line(moving.tree.sphere(0))) lowest_descent_.push_back({0, *root});
  while (!lowest_descent_.empty()) {
    const ReachingNode reaching = lowest_descent_.back();
    lowest_descent_.pop_back();
    if (reaching.lowest_m >= lowest) continue;
    const NodeState& state = moving.tree.current(reaching.node);
    if (state.isLeaf()) {
      for (std::uint32_t k = 0; k < state.point_count; ++k) {
        const Eigen::Vector3d& point = positions[indices[state.first_point + k]];
        if (touched.inLine(point)) lowest = std::min(lowest, point.dot(away));
      }
      continue;
    }
    const std::size_t first_child = lowest_descent_.size();
    for (std::uint32_t child = state.first_child; child < state.first_child + state.child_count;
         ++child) {
      if (const auto reach = reach_in_line(moving.tree.sphere(child))) {
        if (*reach < lowest) lowest_descent_.push_back({child, *reach});
      }
    }
    // The lowest reaching child last on the stack: visited next.
    std::sort(lowest_descent_.begin() + first_child, lowest_descent_.end(),
              [](const ReachingNode& x, const ReachingNode& y) { return x.lowest_m > y.lowest_m; });
  }
  return lowest;
}

// Two dynamic nodes, along the pair's normal, the depth shared by inverse mass. At the
// leaves the depth is how far b's points reach past a's along the normal: the nearest
// pair's distance says nothing of how deep two clouds have passed into each other (it stays
// below the point spacing however deep), and piles would sink into themselves. Above the
// leaves, spheres stand for their points (the query's depth).
bool Scene::pushBetweenDynamic(const ResolvingPair& pair, const SphereContact& c,
                               ContactPush& push) const {
  const Object& a = pair.a;
  const Object& b = pair.b;
  push.normal = pair.dynamic_normal;
  const double overlap = pair.leaves ? pair_nodes_b_.reach_of_node[c.node_b] +
                                           pair_nodes_a_.reach_of_node[c.node_a] +
                                           config_.contact_distance_m
                                     : c.depth_m;
  const double depth = overlap - 0.5 * config_.contact_distance_m -
                       (a.translation - b.translation).dot(push.normal);
  if (depth <= 0.0) return false;
  // Shared by inverse node mass: a's share is b's node mass over both; the object nearer
  // to a support does not move (shock propagation), nor one that the push would drive into
  // a fixed object (a wall) which has pushed it off in this response.
  const double mass_a = a.body.pointMassKg() * push.points_a;
  const double mass_b = b.body.pointMassKg() * push.points_b;
  const bool a_holds = a.support_depth < b.support_depth || pair.a_against_fixed;
  const bool b_holds = b.support_depth < a.support_depth || pair.b_against_fixed;
  const double share_of_a = a_holds && !b_holds   ? 0.0
                            : b_holds && !a_holds ? 1.0
                                                  : mass_b / (mass_a + mass_b);
  push.depth_a = depth * share_of_a;
  push.depth_b = depth - push.depth_a;
  return true;
}

// Each object moves by the mean push of its contact nodes, weighted by their points. A
// stiff object cannot dent, so it moves to clear more of its deepest node: the mean push
// for a soft one (the rest is dented), all of the deepest for a rigid one.
void Scene::moveByMeanPush(ResolvingPair& pair) {
  Eigen::Vector3d mean_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_b = Eigen::Vector3d::Zero();
  double weight_a = 0.0;
  double weight_b = 0.0;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (const ContactPush& push : pushes_) {
    mean_a += push.points_a * push.depth_a * push.normal;
    mean_b -= push.points_b * push.depth_b * push.normal;
    weight_a += push.points_a;
    weight_b += push.points_b;
    normal_sum += (push.depth_a + push.depth_b) * push.normal;
  }
  mean_a /= weight_a;
  mean_b /= weight_b;
  double deepest_a = 0.0;
  double deepest_b = 0.0;
  for (const ContactPush& push : pushes_) {
    deepest_a = std::max(deepest_a, push.depth_a - mean_a.dot(push.normal));
    deepest_b = std::max(deepest_b, push.depth_b + mean_b.dot(push.normal));
  }
  const Eigen::Vector3d pair_direction = normal_sum.normalized();
  // Between two dynamic objects above the leaves nothing dents: the depths are those of the
  // nodes' spheres (they stand for their points), and a dent would push a node's points by
  // how deep the spheres overlap, not the points. Each object clears its deepest node whole.
  const bool dents = pair.leaves || pair.one_side_fixed;
  const double stiffness_a = dents ? pair.a.config.shape.stiffness : 1.0;
  const double stiffness_b = dents ? pair.b.config.shape.stiffness : 1.0;
  if (pair.a.dynamic()) mean_a += stiffness_a * deepest_a * pair_direction;
  if (pair.b.dynamic()) mean_b -= stiffness_b * deepest_b * pair_direction;
  if (pair.held) undoStepApproach(pair, pair_direction, mean_a, mean_b);
  pair.move_a = mean_a;
  pair.move_b = mean_b;
  pair.normal_sum = normal_sum;
}

// Two objects that touched in the last cycle rested on each other: what this cycle's step
// (and the pairs before) brought them together along the pair's normal is undone by moving
// them whole, whatever their stiffness, up to their deepest push; only overlap beyond that
// dents. Otherwise a soft object moves back only by its mean push, and every point above its
// contact ends each cycle lower by the difference: a soft box under another one compacts into
// itself, and with no stiffness at all it never stops.
void Scene::undoStepApproach(const ResolvingPair& pair, const Eigen::Vector3d& normal,
                             Eigen::Vector3d& move_a, Eigen::Vector3d& move_b) const {
  const Object& a = pair.a;
  const Object& b = pair.b;
  const Eigen::Vector3d step_a = stepOf(a);
  const Eigen::Vector3d step_b = stepOf(b);
  const double approach =
      -((step_a + pair.translation_before_a) - (step_b + pair.translation_before_b)).dot(normal);
  if (approach <= 0.0) return;
  double depth_a = 0.0;
  double depth_b = 0.0;
  double deepest_a = 0.0;
  double deepest_b = 0.0;
  for (const ContactPush& push : pushes_) {
    depth_a += push.depth_a;
    depth_b += push.depth_b;
    deepest_a = std::max(deepest_a, push.depth_a);
    deepest_b = std::max(deepest_b, push.depth_b);
  }
  const double share_a = depth_a / (depth_a + depth_b);
  const double need_a = std::min(share_a * approach, deepest_a);
  const double need_b = std::min((1.0 - share_a) * approach, deepest_b);
  if (a.dynamic() && move_a.dot(normal) < need_a) move_a += (need_a - move_a.dot(normal)) * normal;
  if (b.dynamic() && -move_b.dot(normal) < need_b) move_b -= (need_b + move_b.dot(normal)) * normal;
}

Eigen::Vector3d Scene::stepOf(const Object& object) const {
  return config_.dt_s * object.mean_velocity;
}

bool Scene::heldContact(const ResolvingPair& pair) {
  Object& remembering = pair.a.dynamic() ? pair.a : pair.b;
  const auto* remembered =
      remembering.contact_memory.find(&remembering == &pair.a ? pair.index_b : pair.index_a);
  return remembered && remembered->cycle + 1 >= cycle_count_;
}

void Scene::queueDents(const ResolvingPair& pair) {
  Object& a = pair.a;
  Object& b = pair.b;
  // Above the leaves a fixed node's surface dents each point to it: a coarse node's depth
  // is its deepest point's. At the leaves a node is a few points, dented whole.
  const bool to_surface = pair.one_side_fixed && !pair.leaves;
  for (const ContactPush& push : pushes_) {
    const std::optional<double> surface =
        to_surface ? std::optional<double>(push.surface_m) : std::nullopt;
    if (a.dynamic() && push.depth_a > 0.0) {
      a.dents.add(push.node_a, push.normal,
                  push.depth_a + pair.translation_before_a.dot(push.normal), pair.index_b,
                  pair_serial_, surface);
    }
    if (b.dynamic() && push.depth_b > 0.0) {
      b.dents.add(push.node_b, -push.normal,
                  push.depth_b - pair.translation_before_b.dot(push.normal), pair.index_a,
                  pair_serial_, surface);
    }
  }
}

void Scene::rememberSide(const ResolvingPair& pair, const Eigen::Vector3d& normal) {
  Object& remembering = pair.a.dynamic() ? pair.a : pair.b;
  const bool is_a = &remembering == &pair.a;
  remembering.contact_memory.remember(is_a ? pair.index_b : pair.index_a,
                                      is_a ? normal : Eigen::Vector3d(-normal), cycle_count_);
}

// Gauss-Seidel over the pairs: each sees the velocity changes of the pairs before it; a
// Jacobi sweep stops an object resting on two others twice, and piles explode.
void Scene::exchangeVelocities(ResolvingPair& pair, const Eigen::Vector3d& normal) {
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
  velocity_exchanges_.push_back({pair.index_a, pair.index_b, normal, share_a, sticks});
  exchangeVelocity(velocity_exchanges_.back());
  if (pair.one_side_fixed) {
    const bool a_moves = a.dynamic();
    fixed_pair_moves_.push_back({a_moves ? pair.index_a : pair.index_b,
                                 static_cast<std::uint32_t>(fixed_pair_moves_.size()),
                                 a_moves ? normal : Eigen::Vector3d(-normal),
                                 a_moves ? pair.move_a : pair.move_b});
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
bool Scene::holdStaticFriction(ResolvingPair& pair, const Eigen::Vector3d& normal,
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
bool Scene::isSupportLink(const ContactRun& run) {
  Object& a = *objects_[run.object_a];
  Object& b = *objects_[run.object_b];
  if (a.dynamic() == b.dynamic()) return true;
  ResolvingPair pair{a, b, run.object_a, run.object_b, run.begin, run.end, true,
                     contacts_[run.begin].contact.point_a != SphereContact::kNoPoint,
                     Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
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
