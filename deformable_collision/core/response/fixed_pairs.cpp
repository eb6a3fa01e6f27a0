// The pairs between a dynamic object and a fixed one: resolved first, object by object on
// the pool's threads, and their moves combined per object.
#include <algorithm>

#include "deformable_collision/core/response/detail/object_groups.h"
#include "deformable_collision/core/response/detail/resolving_pair.h"

namespace deformable_collision {

// A pair with a fixed object writes only its dynamic object and its run, and reads the fixed
// object's planes and contact nodes' spheres, which are computed on first use: before the
// pairs are handed out (markSupportLinks). So each dynamic object's pairs are resolved on one
// thread in their order, objects in parallel, and their outcomes kept in that order: the same
// bits as on one thread.
void ContactResponse::resolveFixedPairs(WorkerPool& pool, std::size_t count) {
  fixed_groups_->clear();
  fixed_outcomes_.assign(count, PairOutcome{});
  fixed_serials_.assign(count, 0);
  for (std::uint32_t place = 0; place < count; ++place) {
    const ContactRun& run = contact_runs_[resolve_order_[place]];
    const Object& a = *objects_[run.object_a];
    const Object& b = *objects_[run.object_b];
    if (!a.dynamic() && !b.dynamic()) continue;
    fixed_serials_[place] = ++pair_serial_;
    fixed_groups_->add(a.dynamic() ? run.object_a : run.object_b, place);
  }
  const bool shared = pool.threads() > 1 && fixed_groups_->size() >= kFixedPairsWorthSharing;
  if (scratch_.size() < static_cast<std::size_t>(pool.threads())) scratch_.resize(pool.threads());
  const auto resolve = [this](std::uint32_t place, std::size_t lane) {
    const std::uint32_t r = resolve_order_[place];
    resolvePair(*objects_[contact_runs_[r].object_a], *objects_[contact_runs_[r].object_b], r,
                scratch_[lane], fixed_serials_[place], fixed_outcomes_[place]);
  };
  if (shared) {
    fixed_groups_->run(pool, resolve);
  } else {
    for (std::uint32_t place = 0; place < count; ++place) {
      if (fixed_serials_[place] != 0) resolve(place, 0);
    }
  }
  for (PairOutcome& outcome : fixed_outcomes_) keepOutcome(outcome);
}

void ContactResponse::prepareFixedSides() {
  for (const ContactRun& run : contact_runs_) {
    Object& a = *objects_[run.object_a];
    Object& b = *objects_[run.object_b];
    if (a.dynamic() == b.dynamic()) continue;
    Object& fixed = a.dynamic() ? b : a;
    for (std::size_t k = run.begin; k < run.end; ++k) {
      const SphereContact& c = contacts_[k].contact;
      const std::uint32_t node = a.dynamic() ? c.node_b : c.node_a;
      fixed.planes->plane(node);
      fixed.tree.sphere(node);
    }
  }
}

void ContactResponse::keepOutcome(PairOutcome& outcome) {
  if (outcome.exchanged) velocity_exchanges_.push_back(outcome.exchange);
  if (!outcome.fixed_move) return;
  outcome.move.serial = static_cast<std::uint32_t>(fixed_pair_moves_.size());
  fixed_pair_moves_.push_back(outcome.move);
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
void ContactResponse::moveByFixedPartners() {
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

}  // namespace deformable_collision
