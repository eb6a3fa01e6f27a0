#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/core/common/enum_names.h"
#include "deformable_collision/core/common/wide_vectors.h"

namespace deformable_collision {

/// The deformation a cluster's goal transform can express (Mueller et al. 2005).
enum class DeformationMode { kRigid, kLinear, kQuadratic };

inline constexpr EnumNames<DeformationMode, 3> kDeformationModeNames{
    {{DeformationMode::kRigid, "rigid"},
     {DeformationMode::kLinear, "linear"},
     {DeformationMode::kQuadratic, "quadratic"}}};

/// The mode named `name` (kDeformationModeNames); std::nullopt for anything else.
inline std::optional<DeformationMode> parseDeformationMode(const std::string& name) {
  return parseEnum(kDeformationModeNames, name);
}
inline const char* toString(DeformationMode mode) { return enumName(kDeformationModeNames, mode); }

/// Shape-matching parameters of one object. Units are SI and named in the field.
struct ShapeMatchingConfig {
  DeformationMode mode = DeformationMode::kLinear;
  int clusters = 1;  ///< Number of shape-matching clusters, in [1, points].
  double cluster_overlap_ratio =
      0.1;                 ///< Seam shared by neighbouring clusters, see partitionIntoClusters.
  double stiffness = 0.5;  ///< alpha in [0, 1]: fraction of the way to the goal per step.
  double beta = 0.5;       ///< [0, 1]: blend of the fitted transform with its rotation.
  /// [0, 1]: fraction of the velocity relative to the object's rigid motion removed per
  /// step (momentum is conserved). Volume preservation is not a conservative force and
  /// needs about 0.1 to keep energy bounded; the other goals are stable undamped.
  double damping = 0.1;
  /// Linear mode: normalise the fitted A to unit determinant (Mueller et al. 2005).
  /// Off, the goal force derives from a potential and the undamped scheme keeps energy bounded.
  bool preserve_volume = true;
  double mass_kg = 1.0;  ///< Total object mass (> 0), split equally among its points.
};

/// Rest-shape data of one cluster, fixed at construction.
struct Cluster {
  /// Indices of the cluster's points: those it holds alone first (`exclusive_count` of
  /// them), then those it shares with other clusters; each part ascending.
  std::vector<std::uint32_t> points;
  std::size_t exclusive_count = 0;
  std::vector<Eigen::Vector3d> rest_offsets;  ///< q_i = x_i^0 - x_cm^0, same order as `points`.
  /// Mass a shared point lends this cluster: its mass over the number of clusters holding it,
  /// which keeps momentum conserved when shared points take the mean of their goals.
  /// Indexed by slot - exclusive_count; an exclusive point lends its whole mass.
  std::vector<double> shared_weights_kg;
  Eigen::Vector3d rest_center_of_mass = Eigen::Vector3d::Zero();  ///< x_cm^0.
  double total_weight_kg = 0.0;
  /// Weighted mean of the quadratic features q~ (zero in its linear part up to rounding).
  /// Centring the features is what lets a quadratic fit recover a quadratic deformation exactly.
  Eigen::Matrix<double, 9, 1> mean_features = Eigen::Matrix<double, 9, 1>::Zero();
  /// Pseudo-inverse of the feature moment matrix (A_qq^-1, 3x3 block used by linear mode).
  Eigen::Matrix<double, 9, 9> moment_inverse = Eigen::Matrix<double, 9, 9>::Zero();
  /// N with T = A_pq A_qq^+ + R N: directions the rest shape does not span (a flat or thin
  /// cluster) follow the rotation instead of collapsing. Zero for a well-spread cluster.
  Eigen::Matrix<double, 3, 9> null_completion = Eigen::Matrix<double, 3, 9>::Zero();
  /// Largest |q~_j| over the cluster's points (first 3 features unless quadratic): how far
  /// a change of the transform can move a fitted point.
  double max_feature_norm = 0.0;
};

/// A change of one point's position and velocity, from a collision response.
struct PointDisplacement {
  std::uint32_t point = 0;
  Eigen::Vector3d displacement_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_change_mps = Eigen::Vector3d::Zero();
};

/// The rigid motion of a whole object, from its clusters' sums: its centre of mass, velocity,
/// angular velocity about that centre and inertia tensor there.
struct RigidMotion {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d spin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();  ///< kg m^2
};

/// What the hierarchy update of one cluster needs: the shape-matching registration of the
/// cluster's current points (the least-squares fit that the next step builds its goals
/// from), x_i ~ transform * q~_i + translation, with q~ the quadratic features of the rest
/// offset q_i (only the first three columns are non-zero unless the mode is quadratic).
struct ClusterDeformation {
  Eigen::Vector3d center_of_mass = Eigen::Vector3d::Zero();  ///< x_cm of the current points.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();     ///< x_cm - transform * mean_features.
  /// [A Q M] of the fit; R alone for a rigid cluster.
  Eigen::Matrix<double, 3, 9> transform = Eigen::Matrix<double, 3, 9>::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< R.
  /// At least the largest |transform * q~_i + translation - x_i| over the cluster's points:
  /// the fit's residual d (docs/design.md, erratum 3), measured by step, track and
  /// setPositions, and grown by displacePoints and moveRigidly so that it stays a bound.
  double goal_deviation_bound_m = 0.0;
};

/// Mass-weighted sums over a cluster's points, taken about `reference` (a point near the
/// cluster, so that coordinates far from the origin lose no precision): everything a fit
/// and the damping need. Weights are the cluster's shares of the point masses.
struct ClusterSums {
  Eigen::Vector3d reference = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  ///< sum w (x - ref)
  Eigen::Matrix<double, 3, 9> offset_features =
      Eigen::Matrix<double, 3, 9>::Zero();                     ///< sum w (x - ref) q~^T
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();          ///< sum w v
  Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();  ///< sum w (x - ref) x v
  Eigen::Matrix3d second_moment = Eigen::Matrix3d::Zero();     ///< sum w (x - ref)(x - ref)^T
};

/// What tracking a cloud leaves in a body (ShapeMatchingBody::track) besides its points: its
/// clusters' sums and fits; every velocity is zero. Passed from a copy of the body that
/// fitted the cloud on another thread (TrackedFitter) to the body itself, the points beside
/// it in a buffer of their own.
struct TrackedState {
  std::vector<ClusterSums> sums;
  std::vector<ClusterDeformation> deformations;
};

namespace detail {

/// A whole-object move the points have not made yet (ShapeMatchingBody::deferRigidMove):
/// x += offset, v += velocity_change. A part that is zero is left out, as moveRigidly leaves
/// it out, so that a deferred move gives its bits.
struct DeferredMove {
  double offset[3] = {};
  double velocity_change[3] = {};
  bool moves_positions = false;
  bool moves_velocities = false;

  bool waiting() const { return moves_positions || moves_velocities; }
  void apply(double* x, double* v) const {
    if (moves_positions) {
      for (int r = 0; r < 3; ++r) x[r] += offset[r];
    }
    if (moves_velocities) {
      for (int r = 0; r < 3; ++r) v[r] += velocity_change[r];
    }
  }
};

}  // namespace detail

/// One object simulated or registered by clustered meshless shape matching.
/// Rest-shape precomputation happens once in the constructor; step() and track() are the
/// per-cycle work and allocate nothing.
class ShapeMatchingBody {
 public:
  /// Runs the per-point passes of a step and of the fit residuals on vectors of up to
  /// `vectors` (the CPU's widest if it has not those): eight (AVX-512) or four (AVX2)
  /// points per instruction, the same bits as the portable code. Sums over points are taken
  /// in eight interleaved parts at every width.
  /// @throw std::invalid_argument naming the bad value: empty or non-finite rest points,
  ///        a mode outside DeformationMode, mass_kg <= 0, stiffness, beta or damping outside
  ///        [0, 1], clusters outside [1, points], negative overlap.
  ShapeMatchingBody(std::vector<Eigen::Vector3d> rest_points, const ShapeMatchingConfig& config,
                    VectorWidth vectors = widestVectors());

  /// One explicit step: v += alpha (g - x) / h + h a, x += h v, with momentum-conserving
  /// damping of the non-rigid velocity. Points shared by clusters move to the mean goal.
  /// The pass that moves the points also sums what the next fit needs; one more pass
  /// measures the new fit's residual.
  /// @throw std::invalid_argument if dt_s is not finite and > 0 or acceleration is not finite.
  void step(double dt_s, const Eigen::Vector3d& acceleration_mps2);

  /// Registers observed positions of all points (same order as the rest shape) without
  /// integrating: the fitted transforms become the goal transforms. Non-finite observations
  /// count as unobserved: a cluster is then fitted on its observed points alone and its
  /// unobserved points move to their goals (a cluster with none observed keeps its last
  /// transform, or if that is not finite, a fresh body's). Velocities become zero.
  /// A registration carries on from the last one (the centres of mass as the reference of
  /// its sums, the rotations as warm starts) unless that state is not finite or its centre
  /// lies over 1000 rest extents from the new points' own: it then starts as a fresh body
  /// does, so that after absurd but finite input (points at 1e100 m, a step at 1e30 m/s)
  /// the next valid input gives a fresh body's state, to rounding.
  /// @return the number of unobserved points.
  /// @throw std::invalid_argument if the size differs; the state is then unchanged.
  std::size_t track(const std::vector<Eigen::Vector3d>& observed_points);

  /// track(), but a cloud without a non-finite point is swapped in instead of copied:
  /// `observed_points` then holds the previous positions, a buffer of the same size to read
  /// the next cloud into. A cloud with holes is copied and left as it was.
  /// @throw std::invalid_argument if the size differs; the state is then unchanged.
  std::size_t trackSwapping(std::vector<Eigen::Vector3d>& observed_points);

  /// Takes the points and state that a copy of this body (the same rest shape and clusters)
  /// reached by its last track(), as TrackedFitter passes them on: the state this body's own
  /// track() of that cloud would reach, bit for bit, carrying on from the fit the copy
  /// carried on from. `positions` is swapped in and gets this body's former points; the sums
  /// and fits are copied, O(clusters). Velocities become zero.
  /// @throw std::invalid_argument if the point count or the state's cluster count differs;
  ///        nothing changes then.
  void takeTrackedState(std::vector<Eigen::Vector3d>& positions, const TrackedState& state);

  /// Places the points (a deformed start, a pose) and sets their velocities to zero. The
  /// per-cluster outputs are refreshed by registering the new positions, as track() does.
  /// @throw std::invalid_argument if the size differs or a point is not finite.
  void setPositions(const std::vector<Eigen::Vector3d>& positions);
  /// Changes the stiffness (alpha) and damping of the next steps.
  /// @throw std::invalid_argument unless both are in [0, 1]; nothing changes then.
  void setMaterial(double stiffness, double damping);

  /// Sets every point's velocity (an initial condition).
  /// @throw std::invalid_argument if the size differs or a velocity is not finite.
  void setVelocities(const std::vector<Eigen::Vector3d>& velocities);

  /// Moves points and changes their velocities by a collision response. The clusters holding
  /// them are refitted from incrementally updated sums, and their residual bounds grow by
  /// the displacement, by how far the refit moves any goal and by the rounding of the
  /// coordinates: the work is proportional to the points moved plus the clusters touched,
  /// not to the object. A point listed more than once moves by the sum of its displacements
  /// and its velocity changes by the sum of its changes, as if listed once with those sums
  /// where it first appears.
  /// @throw std::invalid_argument if a point index is out of range or a change is not
  ///        finite; the state is then unchanged.
  void displacePoints(const std::vector<PointDisplacement>& displacements);

  /// Moves every point by the same offset and adds the same velocity to each (a collision
  /// response on the whole object), in one pass over the points: the fit moves along, its
  /// residual bound grows only by the rounding of the move (a few ulp of the coordinates),
  /// and the sums follow in O(clusters).
  /// @throw std::invalid_argument if the offset or the velocity is not finite; the state is
  ///        then unchanged.
  void moveRigidly(const Eigen::Vector3d& offset_m, const Eigen::Vector3d& velocity_change_mps);
  /// The same, and each point's velocity also turns by `spin_change_radps` about `center`
  /// (taken after the offset): v_i += velocity_change + spin_change x (x_i - center).
  void moveRigidly(const Eigen::Vector3d& offset_m, const Eigen::Vector3d& velocity_change_mps,
                   const Eigen::Vector3d& spin_change_radps, const Eigen::Vector3d& center_m);

  /// moveRigidly(offset, velocity change), but the points move in the next step's pass over
  /// them, with the same bits as moved now: a response's whole-object move costs no pass of
  /// its own. The sums follow at once; positions() and velocities(), and every other
  /// method, make the move first if they come before the step (the AVX-512 step too): two
  /// threads reading the points at once then need the same care as a write.
  /// @throw std::invalid_argument if the offset or the velocity is not finite; the state is
  ///        then unchanged.
  void deferRigidMove(const Eigen::Vector3d& offset_m, const Eigen::Vector3d& velocity_change_mps);

  /// The mean of the points' positions, a deferred move included, summed in point order:
  /// without making the move.
  Eigen::Vector3d meanPosition() const;
  /// Whether a deferred move waits for the next step (or the next read of the points).
  bool hasDeferredMove() const { return deferred_move_.waiting(); }

  /// The whole object's rigid motion (O(clusters)).
  RigidMotion rigidMotion() const;
  /// The centre of mass of the points, a deferred move included, from the clusters' centres
  /// (O(clusters)): meanPosition() to rounding, without reading the points.
  Eigen::Vector3d centerOfMass() const;

  /// Mass-weighted mean velocity of the object, from the fit sums (O(clusters)).
  Eigen::Vector3d meanVelocity() const;

  /// Each cluster's rest shape placed by its fitted rotation and centre of mass (the rigid
  /// goal), as a transform of the quadratic features and a translation, into `transforms`
  /// and `translations` (resized to clusterCount()). O(clusters).
  void restPoseTransforms(std::vector<Eigen::Matrix<double, 3, 9>>& transforms,
                          std::vector<Eigen::Vector3d>& translations) const;
  /// Where those put `point`, undeformed: the mean over the clusters holding it. A contact's
  /// indentation of a tracked object is how far its points lie from here.
  /// @throw std::out_of_range for a bad point index or transforms of another size.
  Eigen::Vector3d goalPosition(std::size_t point,
                               const std::vector<Eigen::Matrix<double, 3, 9>>& transforms,
                               const std::vector<Eigen::Vector3d>& translations) const;

  const ShapeMatchingConfig& config() const { return config_; }
  VectorWidth vectorWidth() const { return vector_width_; }
  std::size_t pointCount() const { return positions_.size(); }
  double pointMassKg() const { return point_mass_kg_; }
  const std::vector<Eigen::Vector3d>& restPositions() const { return rest_->positions; }
  const std::vector<Eigen::Vector3d>& positions() const {
    makeDeferredMove();
    return positions_;
  }
  const std::vector<Eigen::Vector3d>& velocities() const {
    makeDeferredMove();
    return velocities_;
  }
  std::size_t clusterCount() const { return rest_->clusters.size(); }
  const Cluster& cluster(std::size_t k) const { return rest_->clusters[k]; }
  const ClusterDeformation& deformation(std::size_t k) const { return deformations_[k]; }

 private:
  friend class TrackedFitter;
  friend class RegistrationFitter;
  /// A copy that only tracks (TrackedFitter's, RegistrationFitter's): the rest shape shared, the
  /// state copied, a waiting deferred move made, but no velocities (track() makes them all zero,
  /// and sums at rest never read them) and no scratch for displacements.
  ShapeMatchingBody trackingCopy() const;
  /// Passes what its last track() left, for takeTrackedState() of the body it copies: the
  /// points swapped into `positions` (a buffer of the body's size), the sums and fits copied
  /// into `state`. It keeps its fit, from which its next track() carries on, but its points
  /// are then `positions`' former buffer: only track() may follow, which the two fitters, the
  /// callers, keep to (a registration reads the fits, never the points).
  void giveTrackedState(std::vector<Eigen::Vector3d>& positions, TrackedState& state);
  template <DeformationMode Mode, bool Damped>
  void simulate(double dt_s, const Eigen::Vector3d& acceleration_mps2);
  template <DeformationMode Mode>
  void registerPositions(const std::vector<Eigen::Vector3d>* observed);
  /// The number of non-finite points of a tracked cloud, whose size it checks.
  std::size_t countUnobserved(const std::vector<Eigen::Vector3d>& observed_points) const;
  void copyObserved(const std::vector<Eigen::Vector3d>& observed_points, std::size_t unobserved);
  void registerObserved(const std::vector<Eigen::Vector3d>& observed_points,
                        std::size_t unobserved);
  template <DeformationMode Mode>
  void sumCurrentState();
  /// sumCurrentState once every velocity is zero, which it does not read.
  template <DeformationMode Mode>
  void sumStoppedState();
  bool validateDisplacements(const std::vector<PointDisplacement>& displacements);
  const std::vector<PointDisplacement>& mergeRepeatedPoints(
      const std::vector<PointDisplacement>& displacements);
  void beginDisplacementMarks();
  template <DeformationMode Mode>
  void applyDisplacements(const std::vector<PointDisplacement>& displacements);
  template <DeformationMode Mode>
  void refitDisplacedClusters();
  /// Moves the points by a deferred move, if one waits. Logically const: the state it
  /// completes is the one the sums already describe.
  void makeDeferredMove() const;
  /// The sums and fits of a whole-object move (the points apart).
  void followRigidMove(const Eigen::Vector3d& offset_m, const Eigen::Vector3d& velocity_change_mps,
                       const Eigen::Vector3d& spin_change_radps, const Eigen::Vector3d& center_m);

  ShapeMatchingConfig config_;
  VectorWidth vector_width_ = VectorWidth::kPortable;
  double point_mass_kg_ = 0.0;
  /// What the constructor derives from the rest shape and nothing changes after: shared by
  /// a body and its copies (a TrackedFitter's), which then cost only their state.
  struct RestShape {
    std::vector<Eigen::Vector3d> positions;
    std::vector<Cluster> clusters;
    std::vector<std::uint32_t> membership_counts;  ///< Clusters holding each point.
    std::vector<std::uint32_t> shared_points;      ///< Points held by more than one cluster.
    /// Clusters and slots holding each point: those of point i are
    /// point_slots[point_slot_offsets[i] .. point_slot_offsets[i + 1]).
    std::vector<std::uint32_t> point_slot_offsets;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> point_slots;
  };
  std::shared_ptr<const RestShape> rest_;
  // Mutable for the deferred move only (makeDeferredMove).
  mutable std::vector<Eigen::Vector3d> positions_;
  mutable std::vector<Eigen::Vector3d> velocities_;
  /// A whole-object move the points have not made yet (deferRigidMove): the next step
  /// makes it in its pass over them.
  mutable detail::DeferredMove deferred_move_;
  /// Every velocity is zero, as the constructor and a registration leave them: a tracked
  /// object's registrations then write none (false after anything that may move a point).
  bool stopped_ = true;
  std::vector<ClusterDeformation> deformations_;
  /// The clusters' state once the constructor has registered the rest shape: where a
  /// registration starts from, as a fresh body would, when the state it would carry on
  /// from is not usable (detail::carriedStateFits).
  std::vector<ClusterDeformation> fresh_deformations_;
  /// How far the points' centre may lie from the carried reference before a registration
  /// starts afresh: far beyond any motion between two inputs of an object this size.
  double rebase_distance_m_ = 0.0;
  /// What one call of applyDisplacements adds to a cluster's sums, gathered apart so that
  /// the sums are added to once per cluster.
  struct DisplacedMoments {
    double offset[3] = {};
    double offset_features[3][9] = {};
    double momentum[3] = {};
    double angular_momentum[3] = {};
    /// sum w (p + dx / 2) dx^T: the second moment grows by it and its transpose.
    double half_second_moment[3][3] = {};
    double largest_squared_m2 = 0.0;  ///< Of the displacements.
    bool touched = false;
  };
  /// Displacements with the same dx in one cluster, summed once (see applyDisplacements).
  template <int K>
  struct DisplacementRun;
  std::vector<DisplacedMoments> displaced_moments_scratch_;  ///< One per cluster.
  /// Whether a point was listed in the current pass over a displacement list (its `pass` is
  /// displacement_pass_), and where it went in merged_displacements_.
  struct DisplacementMark {
    std::uint32_t pass = 0;
    std::uint32_t merged_index = 0;
  };
  std::vector<DisplacementMark> displacement_marks_;  ///< One per point.
  std::uint32_t displacement_pass_ = 0;
  std::vector<PointDisplacement> merged_displacements_;  ///< Scratch: each point listed once.
  std::vector<Eigen::Vector3d> goal_sums_;               ///< Scratch for shared points' goals.
  std::vector<ClusterSums> cluster_sums_;  ///< Of the current positions and velocities.
  std::vector<Eigen::Matrix<double, 3, 9>> goal_transforms_;  ///< Scratch of one step.
  std::vector<Eigen::Vector3d> goal_translations_;            ///< Scratch of one step.
};

/// Quadratic features q~ = (qx, qy, qz, qx^2, qy^2, qz^2, qx qy, qy qz, qz qx).
inline Eigen::Matrix<double, 9, 1> quadraticFeatures(const Eigen::Vector3d& q) {
  Eigen::Matrix<double, 9, 1> f;
  f << q.x(), q.y(), q.z(), q.x() * q.x(), q.y() * q.y(), q.z() * q.z(), q.x() * q.y(),
      q.y() * q.z(), q.z() * q.x();
  return f;
}

}  // namespace deformable_collision
