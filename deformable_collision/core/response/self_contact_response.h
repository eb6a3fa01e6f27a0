#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "deformable_collision/core/response/contact_response.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {

/// The response to the self-contacts of dynamic objects (ObjectConfig::self_collision), at
/// their level as the pair response is: the two nodes of a contact are pushed apart along
/// its normal by its depth and stop approaching each other, their sliding slowed by Coulomb
/// friction; each side takes the share of its partner's points, so that the object's
/// momentum stays. A point in several contacts takes the mean of their changes. Holds its
/// scratch, so that steady-state responses allocate nothing.
class SelfContactResponse {
 public:
  using Objects = ContactResponse::Objects;

  /// Responds to contacts[first, contacts.size()), self-contacts grouped by object; those
  /// of objects that are not dynamic are left alone. Marks what it moved stale.
  /// @return the number of points displaced.
  std::size_t respond(Objects& objects, const std::vector<SceneContact>& contacts,
                      std::size_t first, double friction);

 private:
  using Object = detail::SceneObject;
  /// A point's changes over the contacts that reach it.
  struct PointSums {
    Eigen::Vector3d displacement_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d velocity_change_mps = Eigen::Vector3d::Zero();
    std::uint32_t count = 0;
  };
  /// One contact's changes for every point of each of its nodes.
  struct NodeChanges {
    Eigen::Vector3d displacement_a_m;
    Eigen::Vector3d velocity_change_a_mps;
    Eigen::Vector3d displacement_b_m;
    Eigen::Vector3d velocity_change_b_mps;
  };

  /// Responds to one object's contacts[begin, end).
  std::size_t respondObject(Object& object, const std::vector<SceneContact>& contacts,
                            std::size_t begin, std::size_t end, double friction);
  NodeChanges changesOf(const Object& object, const SceneContact& contact, double friction) const;
  Eigen::Vector3d meanVelocity(const Object& object, std::uint32_t node) const;
  void addToNode(const Object& object, std::uint32_t node, const Eigen::Vector3d& displacement_m,
                 const Eigen::Vector3d& velocity_change_mps);

  std::vector<PointSums> sums_;         ///< Per point of the object being resolved.
  std::vector<std::uint32_t> touched_;  ///< Its points with a change, in first-touch order.
  std::vector<PointDisplacement> displacements_;
};

}  // namespace deformable_collision
