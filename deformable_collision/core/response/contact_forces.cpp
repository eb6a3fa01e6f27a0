// Contact forces from the response's momentum (dynamic pairs) or from a tracked object's
// indentation and stiffness (pairs the response does not move).
#include "deformable_collision/core/response/contact_forces.h"

#include <algorithm>

#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {

void ContactForces::assign(std::vector<SceneContact>& contacts, const std::vector<ContactRun>& runs,
                           double dt_s) {
  goals_of_ = nullptr;
  cycle_forces_.clear();
  for (const ContactRun& run : runs) {
    const Eigen::Vector3d force = run.impulse_ns / dt_s;
    if (objects_[run.object_a]->dynamic() || objects_[run.object_b]->dynamic()) {
      cycle_forces_.push_back({run.object_a, run.object_b, force});
    }
    assignRun(contacts, run, force);
  }
}

void ContactForces::assignQueried(std::vector<SceneContact>& contacts) {
  goals_of_ = nullptr;
  queried_runs_.clear();
  for (std::size_t begin = 0; begin < contacts.size();) {
    const std::size_t end = pairRunEnd(contacts, begin);
    queried_runs_.push_back({contacts[begin].object_a, contacts[begin].object_b, begin, end});
    begin = end;
  }
  for (const ContactRun& run : queried_runs_) {
    assignRun(contacts, run, lastCycleForce(run.object_a, run.object_b));
  }
}

Eigen::Vector3d ContactForces::lastCycleForce(std::uint32_t object_a,
                                              std::uint32_t object_b) const {
  for (const PairForce& pair : cycle_forces_) {
    if (pair.object_a == object_a && pair.object_b == object_b) return pair.force_n;
    if (pair.object_a == object_b && pair.object_b == object_a) return -pair.force_n;
  }
  return Eigen::Vector3d::Zero();
}

void ContactForces::assignRun(std::vector<SceneContact>& contacts, const ContactRun& run,
                              const Eigen::Vector3d& dynamic_force_n) {
  if (!objects_[run.object_a]->dynamic() && !objects_[run.object_b]->dynamic()) {
    assignStiffnessRun(contacts, run);
    return;
  }
  weights_.clear();
  for (std::size_t k = run.begin; k < run.end; ++k) {
    weights_.push_back(contacts[k].contact.depth_m);
  }
  share(contacts, run, dynamic_force_n, 0.0);
}

void ContactForces::assignStiffnessRun(std::vector<SceneContact>& contacts, const ContactRun& run) {
  const Object& a = *objects_[run.object_a];
  const Object& b = *objects_[run.object_b];
  const double magnitude = stiffnessForce(contacts, run);
  const double stiffness =
      std::max(a.config.contact_stiffness_n_per_m, b.config.contact_stiffness_n_per_m);
  double bound = 0.0;
  // Along the pair's mean normal, as a probe's force is read: the normals of single point
  // pairs scatter across a flat face.
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (std::size_t k = run.begin; k < run.end; ++k) {
    bound = std::max(bound, contacts[k].contact.error_bound_m);
    normal += weights_[k - run.begin] * contacts[k].contact.normal;
  }
  const double length = normal.norm();
  const Eigen::Vector3d force =
      length > 0.0 ? Eigen::Vector3d(magnitude / length * normal) : Eigen::Vector3d::Zero();
  // The pair's registration error, set for all its contacts (assignRegistrationErrors).
  share(contacts, run, force, stiffness * (bound + contacts[run.begin].registration_error_m));
}

// One stiffness per pair: a probe pressed a given depth into the object reads the same force
// at every level, however many contacts the level splits it into. Two tracked objects press
// each other as springs in series would: the mean of the two estimates.
double ContactForces::stiffnessForce(const std::vector<SceneContact>& contacts,
                                     const ContactRun& run) {
  weights_.assign(run.end - run.begin, 0.0);
  double estimates = 0.0;
  int sides = 0;
  for (const bool side_a : {true, false}) {
    const Object& object = *objects_[side_a ? run.object_a : run.object_b];
    const double stiffness = object.config.contact_stiffness_n_per_m;
    if (object.config.kind != ObjectKind::kTracked || stiffness <= 0.0) continue;
    double deepest = 0.0;
    for (std::size_t k = run.begin; k < run.end; ++k) {
      const SphereContact& c = contacts[k].contact;
      const Eigen::Vector3d towards = side_a ? Eigen::Vector3d(-c.normal) : c.normal;
      const double depth = indentation(object, side_a ? c.node_a : c.node_b, towards);
      weights_[k - run.begin] += depth;
      deepest = std::max(deepest, depth);
    }
    estimates += stiffness * deepest;
    ++sides;
  }
  return sides == 0 ? 0.0 : estimates / sides;
}

double ContactForces::indentation(const Object& object, std::uint32_t node,
                                  const Eigen::Vector3d& towards) {
  if (goals_of_ != &object) {
    object.body.restPoseTransforms(goal_transforms_, goal_translations_);
    goals_of_ = &object;
  }
  const SphereNode& n = object.tree.node(node);
  const std::uint32_t* slots = object.tree.pointIndices().data() + n.first_point;
  const auto& positions = object.body.positions();
  double deepest = 0.0;
  for (std::uint32_t s = 0; s < n.point_count; ++s) {
    const Eigen::Vector3d goal =
        object.body.goalPosition(slots[s], goal_transforms_, goal_translations_);
    deepest = std::max(deepest, (goal - positions[slots[s]]).dot(towards));
  }
  return deepest;
}

// A contact's share of its pair is known to the precision of the depths that weigh it: exact
// at the leaves; above them, anywhere between none and all of the pair. The shares add up to
// the pair's force, whose own error is the indentation's alone.
void ContactForces::share(std::vector<SceneContact>& contacts, const ContactRun& run,
                          const Eigen::Vector3d& pair_force_n, double stiffness_bound_n) {
  const double magnitude_n = pair_force_n.norm();
  double total = 0.0;
  for (const double w : weights_) total += w;
  for (std::size_t k = run.begin; k < run.end; ++k) {
    SceneContact& contact = contacts[k];
    const double w = total > 0.0 ? weights_[k - run.begin] / total : 0.0;
    contact.force_n = w * pair_force_n;
    contact.indentation_error_n = w * stiffness_bound_n;
    const double split = contact.contact.error_bound_m > 0.0 ? std::max(w, 1.0 - w) : 0.0;
    contact.force_error_n = split * magnitude_n + contact.indentation_error_n;
  }
}

}  // namespace deformable_collision
