// Dents: what a contact node needs beyond its object's move is pushed into the object
// locally, and shape matching restores it.
#include <Eigen/Cholesky>
#include <algorithm>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/response/detail/dent_scratch.h"

namespace deformable_collision {
namespace detail {

void DentScratch::reserve(std::size_t point_count, std::size_t node_count) {
  displacement_sums.assign(point_count, Eigen::Vector3d::Zero());
  velocity_change_sums.assign(point_count, Eigen::Vector3d::Zero());
  displacement_counts.assign(point_count, 0);
  run_of_point.assign(point_count, 0);
  displaced_points.reserve(point_count);
  displacements.reserve(point_count);
  dent_of_node.assign(node_count, 0);
  dent_pair_of_node.assign(node_count, 0);
  // Runs are partners: more than a pile's object touches, so that none grows in a cycle.
  run_impulses.reserve(kRunsReserved);
}

// The contacts of one node with one partner share a direction (the pair's normal, or a
// fixed node's plane): they are kept as one dent with a list of depths, so that the node's
// points are visited once for all of them.
void DentScratch::add(std::uint32_t node, const Eigen::Vector3d& away, double depth_unmoved_m,
                      std::uint32_t partner, std::uint32_t run, std::uint64_t pair_serial,
                      std::optional<double> surface_m) {
  const std::uint32_t depth = static_cast<std::uint32_t>(depths.size());
  depths.push_back({depth_unmoved_m, surface_m.value_or(0.0), kNoDepth});
  if (dent_pair_of_node[node] == pair_serial) {
    PendingDent& last = pending[dent_of_node[node]];
    if (last.away == away) {
      depths[last.last_depth].next = depth;
      last.last_depth = depth;
      return;
    }
  }
  dent_pair_of_node[node] = pair_serial;
  dent_of_node[node] = static_cast<std::uint32_t>(pending.size());
  pending.push_back({node, away, partner, run, depth, depth, surface_m.has_value()});
}

void DentScratch::averageDisplacements() {
  displacements.clear();
  for (const std::uint32_t point : displaced_points) {
    const double share = 1.0 / displacement_counts[point];
    displacements.push_back(
        {point, share * displacement_sums[point], share * velocity_change_sums[point]});
    displacement_sums[point].setZero();
    velocity_change_sums[point].setZero();
    displacement_counts[point] = 0;
  }
  displaced_points.clear();
}

// The whole object already stopped approaching its partners (velocity_change); what a
// dented point's stop adds is mostly the contact's part of the object's own oscillation back
// to its shape, which pulls dented points out against the partner. Were the partner to take
// that momentum, a soft body would leave each resting contact moving off it and turning
// (by how unevenly coarse nodes dent it), and a stack would tip over. So the object's other
// points pay for it, except for angular momentum that slows the object's spin: a contact
// may stop an object turning into it, never start it turning. They pay no faster than the
// fastest stop: when few points are left to pay, the partner takes the rest.
RigidVelocityChange DentScratch::balanceVelocityChanges(
    const std::vector<Eigen::Vector3d>& positions, const RigidMotion& motion, double point_mass_kg,
    double reach_m) {
  RigidVelocityChange balance;
  balance.center = motion.center;
  const std::size_t rest_count = positions.size() - displacements.size();
  if (displacements.empty() || rest_count == 0) return balance;
  // Per unit point mass, about the centre of mass: the dented points' changes of momentum
  // and angular momentum, and the other points' first and second moments.
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();
  Eigen::Vector3d rest_offset = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rest_inertia = motion.inertia / point_mass_kg;
  double fastest_stop = 0.0;
  for (const PointDisplacement& d : displacements) {
    const Eigen::Vector3d arm = positions[d.point] - motion.center;
    momentum += d.velocity_change_mps;
    angular_momentum += arm.cross(d.velocity_change_mps);
    rest_offset -= arm;
    rest_inertia -= arm.squaredNorm() * Eigen::Matrix3d::Identity() - arm * arm.transpose();
    fastest_stop = std::max(fastest_stop, d.velocity_change_mps.norm());
  }
  const Eigen::Vector3d spin_momentum = motion.inertia * motion.spin / point_mass_kg;
  const double spin_norm = spin_momentum.norm();
  if (spin_norm > 0.0) {
    const Eigen::Vector3d axis = spin_momentum / spin_norm;
    angular_momentum += std::clamp(-angular_momentum.dot(axis), 0.0, spin_norm) * axis;
  }
  // The other points' change v + w x arm carries both: count v + w x rest_offset = momentum
  // and rest_offset x v + rest_inertia w = angular_momentum, solved for w through v.
  const double count = static_cast<double>(rest_count);
  const Eigen::Matrix3d about_rest_center =
      rest_inertia + (rest_offset * rest_offset.transpose() -
                      rest_offset.squaredNorm() * Eigen::Matrix3d::Identity()) /
                         count;
  const Eigen::Vector3d turn = angular_momentum - rest_offset.cross(momentum) / count;
  balance.spin = about_rest_center.ldlt().solve(turn);
  // Points on a line have no inertia about it, nor angular momentum to take there.
  if (!balance.spin.allFinite()) {
    balance.spin = pseudoInverseSymmetric<3>(about_rest_center).inverse * turn;
  }
  balance.velocity = (momentum + rest_offset.cross(balance.spin)) / count;
  balance.paid = momentum;
  const double fastest_pay = balance.velocity.norm() + balance.spin.norm() * reach_m;
  if (fastest_pay > fastest_stop) {
    balance.velocity *= fastest_stop / fastest_pay;
    balance.spin *= fastest_stop / fastest_pay;
    balance.paid *= fastest_stop / fastest_pay;
  }
  for (PointDisplacement& d : displacements) {
    d.velocity_change_mps +=
        balance.velocity + balance.spin.cross(positions[d.point] - motion.center);
  }
  return balance;
}

}  // namespace detail

}  // namespace deformable_collision
