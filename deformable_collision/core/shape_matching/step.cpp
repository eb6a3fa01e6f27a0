#include "deformable_collision/core/shape_matching/shape_matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/shape_matching/detail/kernels.h"
#include "deformable_collision/core/shape_matching/detail/wide.h"
#include "deformable_collision/core/shape_matching/fit.h"

namespace deformable_collision {
namespace {

using detail::featureArray;
using detail::GoalKernel;
using detail::kFeatureCount;
using detail::kParts;
using detail::kStepTerms;
using detail::PartialMoments;
using detail::SlotLanes;
using detail::StepMotion;

/// The centre of mass of the whole object from the clusters' centres, each weighted by its
/// share of the point masses; summed about the first one's (coordinates may be 1e5 m).
Eigen::Vector3d objectCenterOfMass(const std::vector<Cluster>& clusters,
                                   const std::vector<ClusterDeformation>& deformations) {
  double mass = 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const Eigen::Vector3d origin = deformations[0].center_of_mass;
  for (std::size_t k = 0; k < clusters.size(); ++k) {
    mass += clusters[k].total_weight_kg;
    sum += clusters[k].total_weight_kg * (deformations[k].center_of_mass - origin);
  }
  return origin + sum / mass;
}

/// The rigid motion of the whole object, which damping keeps, from the clusters' sums.
RigidMotion objectRigidMotion(const std::vector<Cluster>& clusters,
                              const std::vector<ClusterDeformation>& deformations,
                              const std::vector<ClusterSums>& cluster_sums) {
  RigidMotion object;
  double mass = 0.0;
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < clusters.size(); ++k) {
    mass += clusters[k].total_weight_kg;
    momentum += cluster_sums[k].momentum;
  }
  object.center = objectCenterOfMass(clusters, deformations);
  object.velocity = momentum / mass;
  Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d& inertia = object.inertia;
  for (std::size_t k = 0; k < clusters.size(); ++k) {
    const ClusterSums& sums = cluster_sums[k];
    const double cluster_mass = clusters[k].total_weight_kg;
    const Eigen::Vector3d shift = sums.offset / cluster_mass;
    const Eigen::Vector3d velocity = sums.momentum / cluster_mass;
    const Eigen::Matrix3d second = sums.second_moment - cluster_mass * shift * shift.transpose();
    // Parallel-axis sums of the clusters about the object's centre.
    const Eigen::Vector3d arm = deformations[k].center_of_mass - object.center;
    angular_momentum +=
        sums.angular_momentum - cluster_mass * shift.cross(velocity) + arm.cross(sums.momentum);
    inertia +=
        second.trace() * Eigen::Matrix3d::Identity() - second +
        cluster_mass * (arm.squaredNorm() * Eigen::Matrix3d::Identity() - arm * arm.transpose());
  }
  object.spin = pseudoInverseSymmetric<3>(inertia).inverse * angular_momentum;
  return object;
}

StepMotion stepMotion(double dt_s, const Eigen::Vector3d& acceleration_mps2,
                      const ShapeMatchingConfig& config, const RigidMotion& object) {
  StepMotion motion;
  motion.dt_s = dt_s;
  motion.pull = config.stiffness / dt_s;
  motion.damping = config.damping;
  for (int r = 0; r < 3; ++r) {
    motion.kick[r] = dt_s * acceleration_mps2[r];
    motion.object_center[r] = object.center[r];
    motion.object_velocity[r] = object.velocity[r];
    motion.object_spin[r] = object.spin[r];
  }
  return motion;
}

/// Moves the cluster's exclusive points towards their goals and sums the moved points
/// about `reference`, unweighted.
template <int K, bool Damped>
PartialMoments<K> moveExclusivePoints(const GoalKernel<K> kernel, const Cluster& cluster,
                                      const StepMotion motion, const Eigen::Vector3d reference,
                                      std::vector<Eigen::Vector3d>& positions,
                                      std::vector<Eigen::Vector3d>& velocities,
                                      [[maybe_unused]] VectorWidth width) {
  PartialMoments<K> moments;
  std::size_t j = 0;
#if defined(__GNUC__) && defined(__x86_64__)
  if (width == VectorWidth::kAvx512) {
    j = detail::moveExclusiveAvx512<K, Damped>(kernel, cluster, motion, positions.data(),
                                               velocities.data(), reference, moments);
  } else if (width == VectorWidth::kAvx2) {
    j = detail::moveExclusiveAvx2<K, Damped>(kernel, cluster, motion, positions.data(),
                                             velocities.data(), reference, moments);
  }
#endif
  // The wide vectors took whole blocks of eight, so slot j + n goes to part n.
  for (; j < cluster.exclusive_count; j += kParts) {
    const int lanes = static_cast<int>(std::min<std::size_t>(kParts, cluster.exclusive_count - j));
    SlotLanes<K> slots;
    for (int n = 0; n < lanes; ++n) {
      const std::uint32_t i = cluster.points[j + n];
      double features[K];
      featureArray<K>(cluster.rest_offsets[j + n], features);
      double goal[3];
      kernel.goalFromFeatures(features, goal);
      double* x = positions[i].data();
      double* u = velocities[i].data();
      motion.move<Damped>(goal, x, u);
      slots.set(n, features, x, u, reference);
    }
    moments.template addLanes<false, kStepTerms<Damped>>(lanes, slots);
  }
  return moments;
}

/// Adds the goals of the cluster's shared points to `goal_sums`.
template <int K>
void addSharedGoals(const GoalKernel<K> kernel, const Cluster& cluster,
                    std::vector<Eigen::Vector3d>& goal_sums, [[maybe_unused]] VectorWidth width) {
  std::size_t j = cluster.exclusive_count;
#if defined(__GNUC__) && defined(__x86_64__)
  if (width == VectorWidth::kAvx512) {
    j = detail::addSharedGoalsAvx512<K>(kernel, cluster, goal_sums.data());
  } else if (width == VectorWidth::kAvx2) {
    j = detail::addSharedGoalsAvx2<K>(kernel, cluster, goal_sums.data());
  }
#endif
  for (; j < cluster.points.size(); ++j) {
    double goal[3];
    kernel.goal(cluster.rest_offsets[j], goal);
    goal_sums[cluster.points[j]] += Eigen::Vector3d(goal[0], goal[1], goal[2]);
  }
}

/// How far rounding can move a point of the cluster, or its fit's translation, when a vector
/// of norm at most `added_norm_m` is added to it: half an ulp of each coordinate of the sum,
/// at most u (|x| + |added|), taken as eps = 2u for slack over this bound's own rounding.
/// |x| is bounded from the fit, |x_i| <= |t| + |T| |q~_i| + d, without visiting the points;
/// that bound is at least |t|, so it covers the translation as well.
double additionRoundingBound(const Cluster& cluster, const ClusterDeformation& deformation,
                             double added_norm_m) {
  const double largest_norm = deformation.translation.norm() +
                              deformation.transform.norm() * cluster.max_feature_norm +
                              deformation.goal_deviation_bound_m;
  return std::sqrt(3.0) * std::numeric_limits<double>::epsilon() * (largest_norm + added_norm_m);
}

// Adds `added` to every vector, as a flat array of coordinates: two points are six
// coordinates, three pairs that the compiler adds two at a time with the baseline
// instruction set, where one point at a time is three scalar additions and their loads.
// A whole object's response move is most of the points a coarse level's response visits.
void addToEveryPoint(const Eigen::Vector3d& added, std::vector<Eigen::Vector3d>& points) {
  if (added.isZero(0.0) || points.empty()) return;
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double),
                "points are packed triples of coordinates");
  const double pattern[6] = {added.x(), added.y(), added.z(), added.x(), added.y(), added.z()};
  double* coordinates = points.data()->data();
  const std::size_t count = 3 * points.size();
  std::size_t i = 0;
  for (; i + 6 <= count; i += 6) {
    for (int j = 0; j < 6; ++j) coordinates[i + j] += pattern[j];
  }
  for (; i < count; ++i) coordinates[i] += pattern[i % 3];
}

}  // namespace

void ShapeMatchingBody::step(double dt_s, const Eigen::Vector3d& acceleration_mps2) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) {
    throw std::invalid_argument("time step dt_s = " + std::to_string(dt_s) +
                                " must be finite and > 0");
  }
  if (!acceleration_mps2.allFinite()) {
    throw std::invalid_argument("external acceleration is not finite");
  }
  const bool damped = config_.damping > 0.0;
  // The AVX-512 kernels take no deferred move: the points make it first.
  if (vector_width_ == VectorWidth::kAvx512) makeDeferredMove();
  stopped_ = false;
  detail::withMode(config_.mode, [&](auto mode) {
    constexpr DeformationMode kMode = decltype(mode)::value;
    damped ? simulate<kMode, true>(dt_s, acceleration_mps2)
           : simulate<kMode, false>(dt_s, acceleration_mps2);
  });
}

template <DeformationMode Mode, bool Damped>
void ShapeMatchingBody::simulate(double dt_s, const Eigen::Vector3d& acceleration_mps2) {
  constexpr int K = kFeatureCount<Mode>;
  // Goals come from the registration of the current positions (kept from the last step or
  // registration), before any point moves.
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    detail::stepGoal<Mode>(rest_->clusters[k], deformations_[k], config_.beta,
                           config_.preserve_volume, goal_transforms_[k], goal_translations_[k]);
  }
  // Damping keeps the rigid motion of the whole object, not of each cluster: clusters
  // turning against each other (bending) are non-rigid motion and must decay too.
  StepMotion motion = stepMotion(
      dt_s, acceleration_mps2, config_,
      Damped ? objectRigidMotion(rest_->clusters, deformations_, cluster_sums_) : RigidMotion{});
  // Every point is moved once below, exclusive in its cluster or shared: each makes the
  // deferred move as it is loaded.
  motion.deferred = deferred_move_;
  deferred_move_ = detail::DeferredMove{};

  // Move the points; the same pass sums the moved points for the next fit.
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    const Cluster& cluster = rest_->clusters[k];
    const GoalKernel<K> kernel(goal_transforms_[k], goal_translations_[k]);
    const Eigen::Vector3d reference = deformations_[k].center_of_mass;
    const PartialMoments<K> next = moveExclusivePoints<K, Damped>(
        kernel, cluster, motion, reference, positions_, velocities_, vector_width_);
    addSharedGoals<K>(kernel, cluster, goal_sums_, vector_width_);
    ClusterSums& sums = cluster_sums_[k];
    sums = ClusterSums{};
    sums.reference = reference;
    detail::addScaled(next.total(), point_mass_kg_, sums);
  }

  // A shared point takes the mean of its clusters' goals; the rigid velocity it is damped
  // towards is the whole object's, the same in every cluster.
  for (const std::uint32_t i : rest_->shared_points) {
    const double share = 1.0 / rest_->membership_counts[i];
    double goal[3];
    for (int r = 0; r < 3; ++r) goal[r] = share * goal_sums_[i][r];
    motion.move<Damped>(goal, positions_[i].data(), velocities_[i].data());
    goal_sums_[i].setZero();
  }

  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    const Cluster& cluster = rest_->clusters[k];
    if (cluster.exclusive_count < cluster.points.size()) {
      detail::addScaled(detail::accumulate<K, kStepTerms<Damped>>(
                            cluster, cluster.exclusive_count, cluster.points.size(),
                            cluster.shared_weights_kg.data(), positions_, velocities_,
                            cluster_sums_[k].reference, vector_width_),
                        1.0, cluster_sums_[k]);
    }
    detail::registerCluster<Mode>(cluster, cluster_sums_[k], deformations_[k]);
  }
  detail::measureFitResiduals<Mode>(rest_->clusters, positions_, vector_width_, deformations_);
}

void ShapeMatchingBody::moveRigidly(const Eigen::Vector3d& offset_m,
                                    const Eigen::Vector3d& velocity_change_mps) {
  moveRigidly(offset_m, velocity_change_mps, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
}

void ShapeMatchingBody::moveRigidly(const Eigen::Vector3d& offset_m,
                                    const Eigen::Vector3d& velocity_change_mps,
                                    const Eigen::Vector3d& spin_change_radps,
                                    const Eigen::Vector3d& center_m) {
  if (!offset_m.allFinite()) throw std::invalid_argument("translation is not finite");
  if (!velocity_change_mps.allFinite() || !spin_change_radps.allFinite() || !center_m.allFinite()) {
    throw std::invalid_argument("velocity change, spin or centre is not finite");
  }
  makeDeferredMove();
  stopped_ = false;
  if (spin_change_radps.isZero(0.0)) {
    addToEveryPoint(offset_m, positions_);
    addToEveryPoint(velocity_change_mps, velocities_);
  } else {
    // Local pointers and copies: written through one vector's data, the other's pointer and
    // the arguments would otherwise be read again for every point.
    Eigen::Vector3d* positions = positions_.data();
    Eigen::Vector3d* velocities = velocities_.data();
    const Eigen::Vector3d offset = offset_m;
    const Eigen::Vector3d change = velocity_change_mps;
    const Eigen::Vector3d spin = spin_change_radps;
    const Eigen::Vector3d center = center_m;
    for (std::size_t i = 0, count = positions_.size(); i < count; ++i) {
      positions[i] += offset;
      velocities[i] += change + spin.cross(positions[i] - center);
    }
  }
  followRigidMove(offset_m, velocity_change_mps, spin_change_radps, center_m);
}

void ShapeMatchingBody::deferRigidMove(const Eigen::Vector3d& offset_m,
                                       const Eigen::Vector3d& velocity_change_mps) {
  if (!offset_m.allFinite()) throw std::invalid_argument("translation is not finite");
  if (!velocity_change_mps.allFinite()) {
    throw std::invalid_argument("velocity change is not finite");
  }
  // Two moves in a row are made one after the other, as moveRigidly would make them.
  makeDeferredMove();
  stopped_ = false;
  for (int r = 0; r < 3; ++r) {
    deferred_move_.offset[r] = offset_m[r];
    deferred_move_.velocity_change[r] = velocity_change_mps[r];
  }
  deferred_move_.moves_positions = !offset_m.isZero(0.0);
  deferred_move_.moves_velocities = !velocity_change_mps.isZero(0.0);
  followRigidMove(offset_m, velocity_change_mps, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
}

void ShapeMatchingBody::makeDeferredMove() const {
  if (!deferred_move_.waiting()) return;
  const detail::DeferredMove move = deferred_move_;
  deferred_move_ = detail::DeferredMove{};
  if (move.moves_positions) addToEveryPoint(Eigen::Vector3d(move.offset), positions_);
  if (move.moves_velocities) addToEveryPoint(Eigen::Vector3d(move.velocity_change), velocities_);
}

Eigen::Vector3d ShapeMatchingBody::meanPosition() const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  if (deferred_move_.moves_positions) {
    const Eigen::Vector3d offset(deferred_move_.offset);
    for (const auto& point : positions_) sum += point + offset;
  } else {
    for (const auto& point : positions_) sum += point;
  }
  return sum / static_cast<double>(positions_.size());
}

void ShapeMatchingBody::followRigidMove(const Eigen::Vector3d& offset_m,
                                        const Eigen::Vector3d& velocity_change_mps,
                                        const Eigen::Vector3d& spin_change_radps,
                                        const Eigen::Vector3d& center_m) {
  const double offset_norm = offset_m.norm();
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    const Cluster& cluster = rest_->clusters[k];
    ClusterSums& sums = cluster_sums_[k];
    ClusterDeformation& deformation = deformations_[k];
    const double mass = cluster.total_weight_kg;
    // The points and the translation are each rounded as they move: over many moves with no
    // step in between, the rounding alone would carry the points out of the bound.
    deformation.goal_deviation_bound_m +=
        2.0 * additionRoundingBound(cluster, deformation, offset_norm);
    // Moved first, then pushed: the move's angular momentum takes the momentum before the
    // push, and the push's the offset after the move.
    sums.second_moment += sums.offset * offset_m.transpose() + offset_m * sums.offset.transpose() +
                          mass * offset_m * offset_m.transpose();
    sums.angular_momentum += offset_m.cross(sums.momentum);
    sums.offset_features += (mass * offset_m) * cluster.mean_features.transpose();
    sums.offset += mass * offset_m;
    deformation.center_of_mass += offset_m;
    deformation.translation += offset_m;
    sums.momentum += mass * velocity_change_mps;
    sums.angular_momentum += sums.offset.cross(velocity_change_mps);
    // The turn: sum w (x - center) = offset + mass (reference - center), and about the
    // reference sum w r x (spin x r) is the second moment's inertia times the spin.
    const Eigen::Vector3d reference_from_center = sums.reference - center_m;
    sums.momentum += spin_change_radps.cross(sums.offset + mass * reference_from_center);
    sums.angular_momentum +=
        (sums.second_moment.trace() * Eigen::Matrix3d::Identity() - sums.second_moment) *
            spin_change_radps +
        sums.offset.cross(spin_change_radps.cross(reference_from_center));
  }
}

RigidMotion ShapeMatchingBody::rigidMotion() const {
  return objectRigidMotion(rest_->clusters, deformations_, cluster_sums_);
}

Eigen::Vector3d ShapeMatchingBody::centerOfMass() const {
  return objectCenterOfMass(rest_->clusters, deformations_);
}

void ShapeMatchingBody::displacePoints(const std::vector<PointDisplacement>& displacements) {
  makeDeferredMove();
  const bool repeats = validateDisplacements(displacements);
  const std::vector<PointDisplacement>& applied =
      repeats ? mergeRepeatedPoints(displacements) : displacements;
  stopped_ = false;
  detail::withMode(config_.mode,
                   [&](auto mode) { applyDisplacements<decltype(mode)::value>(applied); });
}

/// @return whether a point is listed more than once.
bool ShapeMatchingBody::validateDisplacements(const std::vector<PointDisplacement>& displacements) {
  beginDisplacementMarks();
  bool repeats = false;
  for (const auto& d : displacements) {
    if (d.point >= positions_.size()) {
      throw std::invalid_argument("displaced point " + std::to_string(d.point) +
                                  " is out of range (" + std::to_string(positions_.size()) +
                                  " points)");
    }
    if (!d.displacement_m.allFinite() || !d.velocity_change_mps.allFinite()) {
      throw std::invalid_argument("displacement or velocity change of point " +
                                  std::to_string(d.point) + " is not finite");
    }
    DisplacementMark& mark = displacement_marks_[d.point];
    repeats = repeats || mark.pass == displacement_pass_;
    mark.pass = displacement_pass_;
  }
  return repeats;
}

// The residual bound grows by each listed displacement: a point listed twice would move by
// the sum and its clusters' bounds by one displacement only, so its entries are summed first.
const std::vector<PointDisplacement>& ShapeMatchingBody::mergeRepeatedPoints(
    const std::vector<PointDisplacement>& displacements) {
  beginDisplacementMarks();
  merged_displacements_.clear();
  for (const auto& d : displacements) {
    DisplacementMark& mark = displacement_marks_[d.point];
    if (mark.pass != displacement_pass_) {
      mark = {displacement_pass_, static_cast<std::uint32_t>(merged_displacements_.size())};
      merged_displacements_.push_back(d);
    } else {
      PointDisplacement& merged = merged_displacements_[mark.merged_index];
      merged.displacement_m += d.displacement_m;
      merged.velocity_change_mps += d.velocity_change_mps;
    }
  }
  return merged_displacements_;
}

/// A new pass over a displacement list: every point's mark is stale. Marks are cleared only
/// when the pass counter wraps.
void ShapeMatchingBody::beginDisplacementMarks() {
  if (++displacement_pass_ == 0) {
    std::fill(displacement_marks_.begin(), displacement_marks_.end(), DisplacementMark{});
    displacement_pass_ = 1;
  }
}

// With p = x - reference, a point moved by dx with its velocity changed by dv adds to the
// sums w dx, w dx q~^T, w dv, w ((p + dx) x dv + dx x v) and
// w ((p + dx)(p + dx)^T - p p^T) = w (h dx^T + dx h^T) with h = p + dx / 2.
// The points a contact dents come one after the other with the same dx: over such a run
// (in one cluster) the terms in dx need only the sums of w, w p, w v and w q~, and their
// products with dx are formed once per run.
template <int K>
struct ShapeMatchingBody::DisplacementRun {
  static constexpr std::size_t kNoCluster = std::numeric_limits<std::size_t>::max();
  std::size_t cluster = kNoCluster;
  double dx[3] = {};
  double weight = 0.0;
  double weighted_offset[3] = {};
  double weighted_velocity[3] = {};
  double weighted_features[K] = {};
  double momentum[3] = {};
  double angular_momentum[3] = {};  ///< The terms in dv: w (p + dx) x dv.

  bool continues(std::size_t k, const double (&d)[3]) const {
    return k == cluster && d[0] == dx[0] && d[1] == dx[1] && d[2] == dx[2];
  }

  /// A slot of weight w whose point sits at `position` with `velocity`, features f.
  void add(double w, const Eigen::Vector3d& position, const Eigen::Vector3d& velocity,
           const Eigen::Vector3d& reference, const double (&f)[K], const double (&dv)[3]) {
    double moved[3];
    weight += w;
    for (int r = 0; r < 3; ++r) {
      const double p = position[r] - reference[r];
      moved[r] = p + dx[r];
      weighted_offset[r] += w * p;
      weighted_velocity[r] += w * velocity[r];
      momentum[r] += w * dv[r];
    }
    for (int c = 0; c < K; ++c) weighted_features[c] += w * f[c];
    angular_momentum[0] += w * (moved[1] * dv[2] - moved[2] * dv[1]);
    angular_momentum[1] += w * (moved[2] * dv[0] - moved[0] * dv[2]);
    angular_momentum[2] += w * (moved[0] * dv[1] - moved[1] * dv[0]);
  }

  /// Adds the run's terms to its cluster's `added` moments.
  void closeInto(DisplacedMoments& added) const {
    const double* wv = weighted_velocity;
    for (int r = 0; r < 3; ++r) {
      added.offset[r] += weight * dx[r];
      added.momentum[r] += momentum[r];
      for (int c = 0; c < K; ++c) added.offset_features[r][c] += dx[r] * weighted_features[c];
      const double half = weighted_offset[r] + 0.5 * weight * dx[r];
      for (int c = 0; c < 3; ++c) added.half_second_moment[r][c] += half * dx[c];
    }
    added.angular_momentum[0] += angular_momentum[0] + dx[1] * wv[2] - dx[2] * wv[1];
    added.angular_momentum[1] += angular_momentum[1] + dx[2] * wv[0] - dx[0] * wv[2];
    added.angular_momentum[2] += angular_momentum[2] + dx[0] * wv[1] - dx[1] * wv[0];
    added.largest_squared_m2 =
        std::max(added.largest_squared_m2, dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
    added.touched = true;
  }
};

template <DeformationMode Mode>
void ShapeMatchingBody::applyDisplacements(const std::vector<PointDisplacement>& displacements) {
  constexpr int K = kFeatureCount<Mode>;
  DisplacementRun<K> run;
  const auto close_run = [&] {
    if (run.cluster != DisplacementRun<K>::kNoCluster) {
      run.closeInto(displaced_moments_scratch_[run.cluster]);
    }
    run = DisplacementRun<K>{};
  };
  for (const auto& d : displacements) {
    const double dx[3] = {d.displacement_m.x(), d.displacement_m.y(), d.displacement_m.z()};
    const double dv[3] = {d.velocity_change_mps.x(), d.velocity_change_mps.y(),
                          d.velocity_change_mps.z()};
    Eigen::Vector3d& position = positions_[d.point];
    Eigen::Vector3d& velocity = velocities_[d.point];
    const auto& offsets = rest_->point_slot_offsets;
    for (std::uint32_t m = offsets[d.point]; m < offsets[d.point + 1]; ++m) {
      const auto [k, slot] = rest_->point_slots[m];
      if (!run.continues(k, dx)) {
        close_run();
        run.cluster = k;
        for (int r = 0; r < 3; ++r) run.dx[r] = dx[r];
      }
      double f[K];
      featureArray<K>(rest_->clusters[k].rest_offsets[slot], f);
      run.add(detail::slotWeightKg(rest_->clusters[k], slot, point_mass_kg_), position, velocity,
              cluster_sums_[k].reference, f, dv);
    }
    position += d.displacement_m;
    velocity += d.velocity_change_mps;
  }
  close_run();
  refitDisplacedClusters<Mode>();
}

template <DeformationMode Mode>
void ShapeMatchingBody::refitDisplacedClusters() {
  constexpr int K = kFeatureCount<Mode>;
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    DisplacedMoments& added = displaced_moments_scratch_[k];
    if (!added.touched) continue;
    ClusterSums& sums = cluster_sums_[k];
    for (int r = 0; r < 3; ++r) {
      sums.offset[r] += added.offset[r];
      sums.momentum[r] += added.momentum[r];
      sums.angular_momentum[r] += added.angular_momentum[r];
      for (int c = 0; c < K; ++c) sums.offset_features(r, c) += added.offset_features[r][c];
      for (int c = 0; c < 3; ++c) {
        sums.second_moment(r, c) += added.half_second_moment[r][c] + added.half_second_moment[c][r];
      }
    }
    ClusterDeformation& deformation = deformations_[k];
    const double largest_displacement = std::sqrt(added.largest_squared_m2);
    const double rounding =
        additionRoundingBound(rest_->clusters[k], deformation, largest_displacement);
    const Eigen::Matrix<double, 3, K> old_transform = deformation.transform.template leftCols<K>();
    const Eigen::Vector3d old_translation = deformation.translation;
    detail::registerCluster<Mode>(rest_->clusters[k], sums, deformation);
    // Every fitted point moves by at most |dT| |q~| + |dt| with the refit, and a displaced
    // point by its displacement, rounded, too: the residual stays bounded without visiting
    // the cluster.
    const double refit_motion =
        (deformation.transform.template leftCols<K>() - old_transform).norm() *
            rest_->clusters[k].max_feature_norm +
        (deformation.translation - old_translation).norm();
    deformation.goal_deviation_bound_m += largest_displacement + refit_motion + rounding;
    added = DisplacedMoments{};
  }
}

}  // namespace deformable_collision
