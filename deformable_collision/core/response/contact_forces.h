#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <vector>

#include "deformable_collision/core/response/contact_response.h"

namespace deformable_collision {

/// The force of every contact (docs/design.md, "Contact forces"). A pair with a dynamic
/// object: the momentum the response exchanged through it this cycle over the step, so that
/// forces obey Newton's third law and balance gravity at rest. A pair of a tracked object
/// with an object the response never moves: the tracked object's contact stiffness times
/// its indentation, how far the touched points lie from where their shape-matching goals
/// put them. Either pair total is shared among the pair's contacts by their depth (or
/// indentation). Holds its scratch, so that steady-state cycles allocate nothing.
class ContactForces {
 public:
  using Objects = std::vector<std::unique_ptr<detail::SceneObject>>;

  explicit ContactForces(const Objects& objects) : objects_(objects) {}
  ContactForces(const ContactForces&) = delete;
  ContactForces& operator=(const ContactForces&) = delete;

  /// Sets force_n and force_error_n of the runs' contacts, from the runs' impulses over
  /// `dt_s` (> 0) and the tracked objects' current state.
  void assign(std::vector<SceneContact>& contacts, const std::vector<ContactRun>& runs,
              double dt_s);
  /// The same for contacts found apart from a cycle (a query at another level): the
  /// impulse of each object pair is the last cycle's (`cycle_runs`), none for a pair
  /// that was not in it.
  void assignQueried(std::vector<SceneContact>& contacts, const std::vector<ContactRun>& cycle_runs,
                     double dt_s);

 private:
  using Object = detail::SceneObject;
  /// How far the contact's node of the tracked `object` is pressed in: the largest component,
  /// towards the partner (`towards`, unit), of its points' goal minus their position (>= 0).
  double indentation(const Object& object, std::uint32_t node, const Eigen::Vector3d& towards);
  /// The magnitude of the force of a pair without a dynamic object, and each contact's
  /// indentation into weights_.
  double stiffnessForce(const std::vector<SceneContact>& contacts, const ContactRun& run);
  /// Shares a pair's force among the run's contacts by weights_. `stiffness_bound_n` is
  /// what the indentation's own error may add to the pair's.
  void share(std::vector<SceneContact>& contacts, const ContactRun& run,
             const Eigen::Vector3d& pair_force_n, double stiffness_bound_n);

  const Objects& objects_;
  std::vector<double> weights_;  ///< Per contact of the run being assigned.
  // The goals of the tracked object being measured (ShapeMatchingBody::goalTransforms).
  const Object* goals_of_ = nullptr;
  std::vector<Eigen::Matrix<double, 3, 9>> goal_transforms_;
  std::vector<Eigen::Vector3d> goal_translations_;
};

}  // namespace deformable_collision
