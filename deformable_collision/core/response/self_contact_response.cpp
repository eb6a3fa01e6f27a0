#include "deformable_collision/core/response/self_contact_response.h"

#include <algorithm>

#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {

std::size_t SelfContactResponse::respond(Objects& objects,
                                         const std::vector<SceneContact>& contacts,
                                         std::size_t first, double friction) {
  std::size_t displaced = 0;
  for (std::size_t begin = first; begin < contacts.size();) {
    const std::uint32_t index = contacts[begin].object_a;
    std::size_t end = begin + 1;
    while (end < contacts.size() && contacts[end].object_a == index) ++end;
    Object& object = *objects[index];
    if (object.dynamic()) displaced += respondObject(object, contacts, begin, end, friction);
    begin = end;
  }
  return displaced;
}

std::size_t SelfContactResponse::respondObject(Object& object,
                                               const std::vector<SceneContact>& contacts,
                                               std::size_t begin, std::size_t end,
                                               double friction) {
  if (sums_.size() < object.body.pointCount()) sums_.resize(object.body.pointCount());
  touched_.clear();
  // Every contact's changes are measured on the state before any is applied: the order of
  // the contacts changes nothing but the order of sums.
  for (std::size_t k = begin; k < end; ++k) {
    const SceneContact& contact = contacts[k];
    const NodeChanges changes = changesOf(object, contact, friction);
    addToNode(object, contact.contact.node_a, changes.displacement_a_m,
              changes.velocity_change_a_mps);
    addToNode(object, contact.contact.node_b, changes.displacement_b_m,
              changes.velocity_change_b_mps);
  }
  displacements_.clear();
  for (const std::uint32_t point : touched_) {
    PointSums& sums = sums_[point];
    const double share = 1.0 / sums.count;
    displacements_.push_back(
        {point, share * sums.displacement_m, share * sums.velocity_change_mps});
    sums = PointSums{};
  }
  object.body.displacePoints(displacements_);
  object.stale = true;
  return displacements_.size();
}

SelfContactResponse::NodeChanges SelfContactResponse::changesOf(const Object& object,
                                                                const SceneContact& contact,
                                                                double friction) const {
  const SphereContact& c = contact.contact;
  const double points_a = object.tree.node(c.node_a).point_count;
  const double points_b = object.tree.node(c.node_b).point_count;
  // Each side moves by the other's share of their points: the momentum stays.
  const double share_a = points_b / (points_a + points_b);
  const double share_b = points_a / (points_a + points_b);
  const Eigen::Vector3d push = std::max(0.0, c.depth_m) * c.normal;
  const Eigen::Vector3d relative = meanVelocity(object, c.node_a) - meanVelocity(object, c.node_b);
  const double approach = std::min(0.0, relative.dot(c.normal));
  Eigen::Vector3d change = -approach * c.normal;
  const Eigen::Vector3d sliding = relative - relative.dot(c.normal) * c.normal;
  const double sliding_mps = sliding.norm();
  if (sliding_mps > 0.0) {
    change -= (std::min(sliding_mps, -friction * approach) / sliding_mps) * sliding;
  }
  return {share_a * push, share_a * change, -share_b * push, -share_b * change};
}

Eigen::Vector3d SelfContactResponse::meanVelocity(const Object& object, std::uint32_t node) const {
  const SphereNode& n = object.tree.node(node);
  const std::uint32_t* points = object.tree.pointIndices().data() + n.first_point;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::uint32_t s = 0; s < n.point_count; ++s) sum += object.body.velocities()[points[s]];
  return sum / n.point_count;
}

void SelfContactResponse::addToNode(const Object& object, std::uint32_t node,
                                    const Eigen::Vector3d& displacement_m,
                                    const Eigen::Vector3d& velocity_change_mps) {
  const SphereNode& n = object.tree.node(node);
  const std::uint32_t* points = object.tree.pointIndices().data() + n.first_point;
  for (std::uint32_t s = 0; s < n.point_count; ++s) {
    PointSums& sums = sums_[points[s]];
    if (sums.count == 0) touched_.push_back(points[s]);
    sums.displacement_m += displacement_m;
    sums.velocity_change_mps += velocity_change_mps;
    ++sums.count;
  }
}

}  // namespace deformable_collision
