// Internal to the core: the dents the response leaves in a dynamic object.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {
namespace detail {

/// A change of every point's velocity by `velocity + spin x (x - center)`.
struct RigidVelocityChange {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d spin = Eigen::Vector3d::Zero();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  /// The momentum the points outside the dents give up for them, per unit point mass.
  Eigen::Vector3d paid = Eigen::Vector3d::Zero();
};

/// The dents of a dynamic object: each contact node's push, kept until the object's move
/// over all its pairs is known, and the per-point sums they turn into.
struct DentScratch {
  static constexpr std::uint32_t kNoDepth = std::numeric_limits<std::uint32_t>::max();
  /// A contact node's dent by one partner.
  struct PendingDent {
    std::uint32_t node = 0;
    Eigen::Vector3d away = Eigen::Vector3d::UnitZ();  ///< Direction this object is pushed.
    std::uint32_t partner = 0;                        ///< The object it touches.
    std::uint32_t run = 0;                            ///< The pair's contact run.
    /// Its contacts' depths in depths, a list from first_depth to last_depth.
    std::uint32_t first_depth = kNoDepth;
    std::uint32_t last_depth = kNoDepth;
    /// Each point goes to its contacts' surfaces (DentDepth::surface_m), not the whole node
    /// by its deepest point's depth.
    bool to_surface = false;
  };
  struct DentDepth {
    double depth_unmoved_m = 0.0;  ///< How far the node must go if the object did not move.
    /// For a dent to_surface: where along `away` its points are cleared to, unmoved.
    double surface_m = 0.0;
    std::uint32_t next = kNoDepth;
  };

  /// Sized once, so that no cycle allocates, even the first that dents every point.
  void reserve(std::size_t point_count, std::size_t node_count);
  /// Notes a contact's dent of `node`, pushed along `away` by `partner` in the pair resolved
  /// as `pair_serial`; with `surface_m`, each of the node's points only as far as it lies
  /// short of that level along `away` (every contact of a pair dents alike).
  void add(std::uint32_t node, const Eigen::Vector3d& away, double depth_unmoved_m,
           std::uint32_t partner, std::uint32_t run, std::uint64_t pair_serial,
           std::optional<double> surface_m = std::nullopt);
  /// Turns the sums into one mean displacement per dented point (in displacements) and
  /// clears them.
  void averageDisplacements();
  /// Makes the dented points' velocity changes (in displacements) leave the object's momentum
  /// and angular momentum as they were, but for slowing its spin: returns the rigid change
  /// every point gives up for them (no point's faster than the fastest of them, its points
  /// lying within `reach_m` of the centre of mass) and adds it back to the dented points'.
  RigidVelocityChange balanceVelocityChanges(const std::vector<Eigen::Vector3d>& positions,
                                             const RigidMotion& motion, double point_mass_kg,
                                             double reach_m);

  std::vector<PendingDent> pending;
  std::vector<DentDepth> depths;
  /// Per node: its dent in `pending`, valid for the pair resolved as dent_pair_of_node.
  std::vector<std::uint32_t> dent_of_node;
  std::vector<std::uint64_t> dent_pair_of_node;
  // Changes summed per point, averaged when applied.
  std::vector<Eigen::Vector3d> displacement_sums;
  std::vector<Eigen::Vector3d> velocity_change_sums;
  std::vector<std::uint32_t> displacement_counts;
  /// The run of each displaced point's first dent this response: the pair whose partner
  /// takes its stop's momentum.
  std::vector<std::uint32_t> run_of_point;
  std::vector<std::uint32_t> displaced_points;
  std::vector<PointDisplacement> displacements;
  /// The momentum the dented points' stops exchange with each run's partner, less what the
  /// object's other points paid back: added to the runs once every object is dented.
  struct RunImpulse {
    std::uint32_t run;
    Eigen::Vector3d impulse_ns;
  };
  std::vector<RunImpulse> run_impulses;
  static constexpr std::size_t kRunsReserved = 16;
};

}  // namespace detail
}  // namespace deformable_collision
