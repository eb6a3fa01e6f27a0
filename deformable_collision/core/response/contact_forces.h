#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "deformable_collision/core/response/contact_response.h"

namespace deformable_collision {

/// The force of every contact (docs/design.md, "Contact forces"). A pair with a dynamic
/// object: the momentum the response exchanged through it this cycle over the step, so that
/// forces obey Newton's third law and balance gravity at rest. A pair of a tracked object
/// with an object the response never moves: the tracked object's contact stiffness times
/// its indentation, how far the touched points lie from where their clusters' rigidly posed
/// rest shape puts them. Either pair force is shared among the pair's contacts by their depth
/// (or indentation). Holds its scratch, so that steady-state cycles allocate nothing.
class ContactForces {
 public:
  using Objects = std::vector<std::unique_ptr<detail::SceneObject>>;

  explicit ContactForces(const Objects& objects) : objects_(objects) {}
  ContactForces(const ContactForces&) = delete;
  ContactForces& operator=(const ContactForces&) = delete;

  /// Sets force_n, force_error_n and indentation_error_n of a cycle's contacts (their
  /// registration_error_m set), from its runs' impulses over `dt_s` (> 0) and the tracked
  /// objects' current state, and keeps each dynamic pair's force for queries until the next
  /// cycle.
  void assign(std::vector<SceneContact>& contacts, const std::vector<ContactRun>& runs,
              double dt_s);
  /// The same for contacts found apart from a cycle (a query at another level, in either
  /// order of a pair's objects): a pair with a dynamic object gets the last cycle's force of
  /// the pair (none if it was not in contact then), shared among these contacts.
  void assignQueried(std::vector<SceneContact>& contacts);

 private:
  using Object = detail::SceneObject;
  /// A dynamic pair's force in the last cycle, on its object a.
  struct PairForce {
    std::uint32_t object_a;
    std::uint32_t object_b;
    Eigen::Vector3d force_n;
  };

  /// Assigns one pair's contacts: a dynamic pair shares `dynamic_force_n`; a pair without a
  /// dynamic object gets its stiffness force.
  void assignRun(std::vector<SceneContact>& contacts, const ContactRun& run,
                 const Eigen::Vector3d& dynamic_force_n);
  /// The last cycle's force on `object_a` of the pair, in either order; zero if none.
  Eigen::Vector3d lastCycleForce(std::uint32_t object_a, std::uint32_t object_b) const;
  /// How far the contact's node of the tracked `object` is pressed in: the largest component,
  /// towards the partner (`towards`, unit), of its points' undeformed place minus their
  /// position (>= 0).
  double indentation(const Object& object, std::uint32_t node, const Eigen::Vector3d& towards);
  /// The magnitude of the force of a pair without a dynamic object, and each contact's
  /// indentation into weights_.
  double stiffnessForce(const std::vector<SceneContact>& contacts, const ContactRun& run);
  /// The stiffness force of a pair without a dynamic object, along its mean normal, shared.
  void assignStiffnessRun(std::vector<SceneContact>& contacts, const ContactRun& run);
  /// Shares a pair's force among the run's contacts by weights_. `stiffness_bound_n` is
  /// what the indentation's own error may add to the pair's.
  void share(std::vector<SceneContact>& contacts, const ContactRun& run,
             const Eigen::Vector3d& pair_force_n, double stiffness_bound_n);

  const Objects& objects_;
  std::vector<double> weights_;          ///< Per contact of the run being assigned.
  std::vector<PairForce> cycle_forces_;  ///< The last cycle's dynamic pairs.
  std::vector<ContactRun> queried_runs_;
  // The undeformed places of the tracked object being measured
  // (ShapeMatchingBody::restPoseTransforms).
  const Object* goals_of_ = nullptr;
  std::vector<Eigen::Matrix<double, 3, 9>> goal_transforms_;
  std::vector<Eigen::Vector3d> goal_translations_;
};

}  // namespace deformable_collision
