// The moves and dents of a dynamic object: dents queued per pair, applied once every pair
// has moved it, object by object on the pool's threads.
#include <algorithm>
#include <atomic>
#include <optional>

#include "deformable_collision/core/response/detail/resolving_pair.h"

namespace deformable_collision {
namespace {

using detail::DentScratch;

/// What a pending dent's contacts that need some need beyond the object's move, summed and
/// counted.
struct Beyond {
  double sum_m = 0.0;
  std::uint32_t count = 0;
};

/// Each contact's need along the dent's `away` is `reach(depth)`.
template <typename Reach>
Beyond beyond(const DentScratch& dents, const DentScratch::PendingDent& pending,
              const Reach& reach) {
  Beyond total;
  for (std::uint32_t d = pending.first_depth; d != DentScratch::kNoDepth;
       d = dents.depths[d].next) {
    const double need = reach(dents.depths[d]);
    if (need <= 0.0) continue;
    total.sum_m += need;
    ++total.count;
  }
  return total;
}

/// Adds a point's share of a dent to the object's sums; `other_velocity` is the partner's.
void dentPoint(detail::SceneObject& object, const DentScratch::PendingDent& pending,
               std::uint32_t point, const Beyond& need, const Eigen::Vector3d& other_velocity) {
  DentScratch& dents = object.dents;
  if (dents.displacement_counts[point] == 0) {
    dents.displaced_points.push_back(point);
    dents.run_of_point[point] = pending.run;
  }
  dents.displacement_counts[point] += need.count;
  dents.displacement_sums[point] += need.sum_m * pending.away;
  const double inward =
      std::min(0.0, (object.body.velocities()[point] - other_velocity).dot(pending.away));
  dents.velocity_change_sums[point] -= (need.count * inward) * pending.away;
}

/// Each of the node's contacts with the partner dents it by what it needs beyond the
/// object's move; a point takes the mean over all the dents it gets.
void dentNode(detail::SceneObject& object, const DentScratch::PendingDent& pending,
              const Eigen::Vector3d& other_velocity) {
  const double moved = object.translation.dot(pending.away);
  const SphereNode& node = object.tree.node(pending.node);
  const std::uint32_t* slots = object.tree.pointIndices().data() + node.first_point;
  if (pending.to_surface) {
    // A coarse node against a fixed surface: only its points short of the surface move,
    // each by its own need, as the leaves' contacts would move them. The node's deepest
    // point's depth, given to all, would dent hundreds of points by what one needs.
    const auto& positions = object.body.positions();
    for (std::uint32_t s = 0; s < node.point_count; ++s) {
      const double along = positions[slots[s]].dot(pending.away) + moved;
      const Beyond need = beyond(object.dents, pending, [&](const DentScratch::DentDepth& depth) {
        return depth.surface_m - along;
      });
      if (need.count > 0) dentPoint(object, pending, slots[s], need, other_velocity);
    }
    return;
  }
  const Beyond need = beyond(object.dents, pending, [&](const DentScratch::DentDepth& depth) {
    return depth.depth_unmoved_m - moved;
  });
  if (need.count == 0) return;
  for (std::uint32_t s = 0; s < node.point_count; ++s) {
    dentPoint(object, pending, slots[s], need, other_velocity);
  }
}

}  // namespace

void ContactResponse::queueDents(const ResolvingPair& pair) {
  Object& a = pair.a;
  Object& b = pair.b;
  // Above the leaves a fixed node's surface dents each point to it: a coarse node's depth
  // is its deepest point's. At the leaves a node is a few points, dented whole.
  const bool to_surface = pair.one_side_fixed && !pair.leaves;
  for (const ContactPush& push : pair.scratch->pushes) {
    const std::optional<double> surface =
        to_surface ? std::optional<double>(push.surface_m) : std::nullopt;
    if (a.dynamic() && push.depth_a > 0.0) {
      a.dents.add(push.node_a, push.normal,
                  push.depth_a + pair.translation_before_a.dot(push.normal), pair.index_b, pair.run,
                  pair.serial, surface);
    }
    if (b.dynamic() && push.depth_b > 0.0) {
      b.dents.add(push.node_b, -push.normal,
                  push.depth_b - pair.translation_before_b.dot(push.normal), pair.index_a, pair.run,
                  pair.serial, surface);
    }
  }
}

// A dented point is blocked by the other object: it also stops moving into it (the other
// object takes that momentum). Left alone, the goal step turns each cycle's dent into
// motion towards the contact, and a held contact pumps up speed. Both velocities are those
// after this response's whole-object changes (velocity_after): a point measured before its
// object's own change would be stopped twice, and a resting object would leave each cycle
// moving up.
void ContactResponse::applyObjectResponses(WorkerPool& pool) {
  std::atomic<std::size_t> displaced{0};
  const auto apply = [&](std::size_t i) {
    Object& object = *objects_[i];
    if (object.dynamic())
      displaced.fetch_add(applyObjectResponse(object), std::memory_order_relaxed);
  };
  // A few dynamic objects stay on this thread: waking the workers would cost more than they
  // share, and a scene of tracked objects has nothing to dent at all.
  const auto dynamic_objects = std::count_if(objects_.begin(), objects_.end(),
                                             [](const auto& object) { return object->dynamic(); });
  if (pool.threads() > 1 && static_cast<std::size_t>(dynamic_objects) >= kObjectsWorthSharing) {
    pool.forEach(objects_.size(), apply);
  } else {
    for (std::size_t i = 0; i < objects_.size(); ++i) apply(i);
  }
  points_displaced_ += displaced.load();
  if (!config_.contact_forces) return;
  // In the objects' order, as one thread would add them: the runs' sums are the same bits.
  for (auto& object : objects_) {
    for (const auto& e : object->dents.run_impulses) addImpulse(e.run, *object, e.impulse_ns);
    object->dents.run_impulses.clear();
  }
}

std::size_t ContactResponse::applyObjectResponse(Object& object) const {
  applyPendingDents(object);
  const bool moved = object.translation.squaredNorm() > 0.0 ||
                     object.velocity_change.squaredNorm() > 0.0 ||
                     !object.dents.displaced_points.empty();
  if (!moved) return 0;
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
  std::size_t displaced = 0;
  if (object.dents.displacements.empty()) {
    // The points make the move in the next step's pass over them.
    object.body.deferRigidMove(object.translation, object.velocity_change);
  } else {
    if (config_.contact_forces) sumDentImpulses(object);
    const RigidMotion motion = object.body.rigidMotion();
    const Sphere& bound = object.tree.sphere(0);
    const detail::RigidVelocityChange balance = object.dents.balanceVelocityChanges(
        object.body.positions(), motion, object.body.pointMassKg(),
        (bound.center - motion.center).norm() + bound.radius);
    if (config_.contact_forces) payDentImpulses(object, balance.paid);
    object.body.moveRigidly(object.translation, object.velocity_change - balance.velocity,
                            -balance.spin, balance.center + object.translation);
    displaced = object.dents.displacements.size();
    object.body.displacePoints(object.dents.displacements);
  }
  object.translation.setZero();
  object.velocity_change.setZero();
  object.stale = true;
  return displaced;
}

void ContactResponse::applyPendingDents(Object& object) const {
  for (const DentScratch::PendingDent& pending : object.dents.pending) {
    // The partner's velocity after the response, less this object's own change: what a
    // point's current velocity is compared with.
    const Eigen::Vector3d other_velocity =
        objects_[pending.partner]->velocity_after - object.velocity_change;
    dentNode(object, pending, other_velocity);
  }
  object.dents.pending.clear();
  object.dents.depths.clear();
}

// The dented points' stops are the contact's share of the object's elastic pull against its
// partners (a squeezed object's, which whole-object changes never see); the object's other
// points pay back part of it (balanceVelocityChanges), the rest of the partners' momentum.
// That part is shared among the runs by the size of their stops: a resting object's single
// support takes it all back, and two jaws squeezing from opposite sides pay each other.
void ContactResponse::sumDentImpulses(Object& object) {
  std::vector<DentScratch::RunImpulse>& impulses = object.dents.run_impulses;
  impulses.clear();
  const double mass = object.body.pointMassKg();
  for (const PointDisplacement& d : object.dents.displacements) {
    const std::uint32_t run = object.dents.run_of_point[d.point];
    auto entry = std::find_if(impulses.begin(), impulses.end(),
                              [run](const DentScratch::RunImpulse& e) { return e.run == run; });
    if (entry == impulses.end()) {
      impulses.push_back({run, Eigen::Vector3d::Zero()});
      entry = impulses.end() - 1;
    }
    entry->impulse_ns += mass * d.velocity_change_mps;
  }
}

void ContactResponse::payDentImpulses(Object& object, const Eigen::Vector3d& paid) {
  std::vector<DentScratch::RunImpulse>& impulses = object.dents.run_impulses;
  const double mass = object.body.pointMassKg();
  double total_norm = 0.0;
  for (const DentScratch::RunImpulse& e : impulses) total_norm += e.impulse_ns.norm();
  if (total_norm == 0.0) {
    impulses.clear();
    return;
  }
  for (DentScratch::RunImpulse& e : impulses) {
    const double share = e.impulse_ns.norm() / total_norm;
    e.impulse_ns -= share * mass * paid;
  }
}

}  // namespace deformable_collision
