#include "deformable_collision/core/shape_matching/shape_matching.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "deformable_collision/core/shape_matching/clustering.h"
#include "deformable_collision/core/shape_matching/detail/kernels.h"
#include "deformable_collision/core/shape_matching/detail/wide.h"
#include "deformable_collision/core/shape_matching/fit.h"

namespace deformable_collision {
namespace {

using detail::GoalKernel;
using detail::kFeatureCount;
using detail::slotWeightKg;
using detail::withMode;

/// Whether x, y and z are finite, in fewer instructions than Eigen's allFinite: v - v is 0
/// for a finite v and NaN for an infinite or NaN one, and a NaN carries through the sum.
bool isFinitePoint(const Eigen::Vector3d& p) {
  return (p.x() - p.x()) + (p.y() - p.y()) + (p.z() - p.z()) == 0.0;
}

/// rebase_distance_m_ in rest extents (the largest distance of a rest point from the first).
constexpr double kRebaseDistanceInExtents = 1e3;

/// @throw std::invalid_argument unless `values` has one finite vector per point.
void requireOnePerPoint(const std::vector<Eigen::Vector3d>& values, std::size_t points,
                        const char* what, const char* plural) {
  if (values.size() != points) {
    throw std::invalid_argument("got " + std::to_string(values.size()) + " " + plural +
                                " for an object of " + std::to_string(points) + " points");
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i].allFinite()) {
      throw std::invalid_argument(std::string(what) + " " + std::to_string(i) + " is not finite");
    }
  }
}

std::string describe(const char* field, double value, const char* requirement) {
  std::ostringstream out;
  out << "ShapeMatchingConfig." << field << " = " << value << " " << requirement;
  return out.str();
}

void validateRestPoints(const std::vector<Eigen::Vector3d>& rest_points) {
  if (rest_points.empty()) throw std::invalid_argument("rest shape has no points");
  for (std::size_t i = 0; i < rest_points.size(); ++i) {
    if (!rest_points[i].allFinite()) {
      std::ostringstream out;
      out << "rest point " << i << " = (" << rest_points[i].transpose() << ") is not finite";
      throw std::invalid_argument(out.str());
    }
  }
}

void validate(const std::vector<Eigen::Vector3d>& rest_points, const ShapeMatchingConfig& c) {
  validateRestPoints(rest_points);
  // A mode outside the enum (a cast of another number) would fit nothing, and the spheres
  // built on its fits would not enclose the points.
  if (!parseDeformationMode(toString(c.mode))) {
    throw std::invalid_argument(
        "ShapeMatchingConfig.mode = " + std::to_string(static_cast<int>(c.mode)) + " must be " +
        enumNameList(kDeformationModeNames));
  }
  const auto in_unit_interval = [](double v) { return v >= 0.0 && v <= 1.0; };
  if (!(c.mass_kg > 0.0) || !std::isfinite(c.mass_kg)) {
    throw std::invalid_argument(describe("mass_kg", c.mass_kg, "must be finite and > 0"));
  }
  if (!in_unit_interval(c.stiffness)) {
    throw std::invalid_argument(describe("stiffness", c.stiffness, "is outside [0, 1]"));
  }
  if (!in_unit_interval(c.beta)) {
    throw std::invalid_argument(describe("beta", c.beta, "is outside [0, 1]"));
  }
  if (!in_unit_interval(c.damping)) {
    throw std::invalid_argument(describe("damping", c.damping, "is outside [0, 1]"));
  }
  if (c.clusters < 1 || static_cast<std::size_t>(c.clusters) > rest_points.size()) {
    std::ostringstream out;
    out << "ShapeMatchingConfig.clusters = " << c.clusters << " must be in [1, "
        << rest_points.size() << "] (the number of points)";
    throw std::invalid_argument(out.str());
  }
  if (!(c.cluster_overlap_ratio >= 0.0) || !std::isfinite(c.cluster_overlap_ratio)) {
    throw std::invalid_argument(
        describe("cluster_overlap_ratio", c.cluster_overlap_ratio, "must be finite and >= 0"));
  }
}

/// The rest-shape data of the cluster of `members` (sorted point indices).
Cluster makeCluster(const std::vector<std::uint32_t>& members,
                    const std::vector<std::uint32_t>& membership_counts,
                    const std::vector<Eigen::Vector3d>& rest_positions, double point_mass_kg,
                    DeformationMode mode) {
  Cluster cluster;
  for (const auto i : members) {
    if (membership_counts[i] == 1) cluster.points.push_back(i);
  }
  cluster.exclusive_count = cluster.points.size();
  for (const auto i : members) {
    if (membership_counts[i] > 1) {
      cluster.points.push_back(i);
      cluster.shared_weights_kg.push_back(point_mass_kg / membership_counts[i]);
    }
  }
  const std::size_t size = cluster.points.size();
  // Summing offsets from one of the cluster's points keeps x_cm^0 exact far from the origin.
  const Eigen::Vector3d anchor = rest_positions[cluster.points.front()];
  Eigen::Vector3d weighted_offset_sum = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < size; ++j) {
    const double weight = slotWeightKg(cluster, j, point_mass_kg);
    cluster.total_weight_kg += weight;
    weighted_offset_sum += weight * (rest_positions[cluster.points[j]] - anchor);
  }
  cluster.rest_center_of_mass = anchor + weighted_offset_sum / cluster.total_weight_kg;
  cluster.rest_offsets.resize(size);
  for (std::size_t j = 0; j < size; ++j) {
    cluster.rest_offsets[j] = rest_positions[cluster.points[j]] - cluster.rest_center_of_mass;
  }
  detail::precomputeMoments(cluster, mode, point_mass_kg);
  return cluster;
}

/// The clusters and slots holding each point: those of point i are
/// slots[offsets[i] .. offsets[i + 1]).
void indexPointSlots(const std::vector<Cluster>& clusters, std::size_t points,
                     std::vector<std::uint32_t>& offsets,
                     std::vector<std::pair<std::uint32_t, std::uint32_t>>& slots) {
  offsets.assign(points + 1, 0);
  for (const auto& cluster : clusters) {
    for (const auto i : cluster.points) ++offsets[i + 1];
  }
  for (std::size_t i = 0; i < points; ++i) offsets[i + 1] += offsets[i];
  slots.resize(offsets[points]);
  std::vector<std::uint32_t> filled(offsets.begin(), offsets.end() - 1);
  for (std::uint32_t k = 0; k < clusters.size(); ++k) {
    for (std::uint32_t slot = 0; slot < clusters[k].points.size(); ++slot) {
      slots[filled[clusters[k].points[slot]]++] = {k, slot};
    }
  }
}

}  // namespace

ShapeMatchingBody::ShapeMatchingBody(std::vector<Eigen::Vector3d> rest_points,
                                     const ShapeMatchingConfig& config, VectorWidth vectors)
    : config_(config) {
  validate(rest_points, config);
  vector_width_ = rest_points.size() <= detail::kMostWidePoints ? std::min(vectors, widestVectors())
                                                                : VectorWidth::kPortable;
  const std::size_t n = rest_points.size();
  point_mass_kg_ = config.mass_kg / static_cast<double>(n);
  auto rest = std::make_shared<RestShape>();
  rest->positions = std::move(rest_points);
  positions_ = rest->positions;
  velocities_.assign(n, Eigen::Vector3d::Zero());
  goal_sums_.assign(n, Eigen::Vector3d::Zero());

  const auto memberships =
      partitionIntoClusters(rest->positions, config.clusters, config.cluster_overlap_ratio);
  rest->membership_counts.assign(n, 0);
  for (const auto& members : memberships) {
    for (const auto i : members) ++rest->membership_counts[i];
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    if (rest->membership_counts[i] > 1) rest->shared_points.push_back(i);
  }
  for (const auto& members : memberships) {
    rest->clusters.push_back(makeCluster(members, rest->membership_counts, rest->positions,
                                         point_mass_kg_, config.mode));
  }
  indexPointSlots(rest->clusters, n, rest->point_slot_offsets, rest->point_slots);
  rest_ = std::move(rest);
  displaced_moments_scratch_.assign(rest_->clusters.size(), DisplacedMoments{});
  displacement_marks_.assign(n, DisplacementMark{});

  deformations_.resize(rest_->clusters.size());
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    deformations_[k].center_of_mass = rest_->clusters[k].rest_center_of_mass;
  }
  double rest_extent_m = 0.0;
  for (const auto& p : rest_->positions) {
    rest_extent_m = std::max(rest_extent_m, (p - rest_->positions.front()).norm());
  }
  rebase_distance_m_ = kRebaseDistanceInExtents * rest_extent_m;
  // The rest shape is registered about its own centres, so this registration never starts
  // afresh and needs fresh_deformations_ only to exist.
  fresh_deformations_ = deformations_;
  cluster_sums_.resize(rest_->clusters.size());
  goal_transforms_.assign(rest_->clusters.size(), Eigen::Matrix<double, 3, 9>::Zero());
  goal_translations_.assign(rest_->clusters.size(), Eigen::Vector3d::Zero());
  setPositions(positions_);
  fresh_deformations_ = deformations_;
}

std::size_t ShapeMatchingBody::track(const std::vector<Eigen::Vector3d>& observed_points) {
  makeDeferredMove();
  const std::size_t unobserved = countUnobserved(observed_points);
  copyObserved(observed_points, unobserved);
  registerObserved(observed_points, unobserved);
  return unobserved;
}

std::size_t ShapeMatchingBody::trackSwapping(std::vector<Eigen::Vector3d>& observed_points) {
  makeDeferredMove();
  const std::size_t unobserved = countUnobserved(observed_points);
  if (unobserved == 0) {
    positions_.swap(observed_points);
  } else {
    copyObserved(observed_points, unobserved);
  }
  registerObserved(observed_points, unobserved);
  return unobserved;
}

void ShapeMatchingBody::takeTrackedState(std::vector<Eigen::Vector3d>& positions,
                                         const TrackedState& state) {
  if (positions.size() != positions_.size() || state.sums.size() != rest_->clusters.size() ||
      state.deformations.size() != rest_->clusters.size()) {
    throw std::invalid_argument("tracked state of " + std::to_string(positions.size()) +
                                " points and " + std::to_string(state.deformations.size()) +
                                " clusters, the body has " + std::to_string(positions_.size()) +
                                " and " + std::to_string(rest_->clusters.size()));
  }
  // As track() does: a waiting move is made before the points are replaced.
  makeDeferredMove();
  if (!stopped_) {
    for (auto& v : velocities_) v.setZero();
    stopped_ = true;
  }
  positions_.swap(positions);
  cluster_sums_ = state.sums;
  deformations_ = state.deformations;
}

ShapeMatchingBody ShapeMatchingBody::trackingCopy() const {
  ShapeMatchingBody copy(*this);
  copy.makeDeferredMove();
  // Moved from empty vectors, so that their buffers go (assigning {} would keep them).
  copy.velocities_ = std::vector<Eigen::Vector3d>();
  copy.stopped_ = true;
  copy.displacement_marks_ = std::vector<DisplacementMark>();
  return copy;
}

void ShapeMatchingBody::giveTrackedState(std::vector<Eigen::Vector3d>& positions,
                                         TrackedState& state) {
  positions_.swap(positions);
  state.sums = cluster_sums_;
  state.deformations = deformations_;
}

std::size_t ShapeMatchingBody::countUnobserved(
    const std::vector<Eigen::Vector3d>& observed_points) const {
  if (observed_points.size() != positions_.size()) {
    throw std::invalid_argument("tracked cloud has " + std::to_string(observed_points.size()) +
                                " points, the object has " + std::to_string(positions_.size()));
  }
  return static_cast<std::size_t>(
      std::count_if(observed_points.begin(), observed_points.end(),
                    [](const Eigen::Vector3d& p) { return !isFinitePoint(p); }));
}

void ShapeMatchingBody::copyObserved(const std::vector<Eigen::Vector3d>& observed_points,
                                     std::size_t unobserved) {
  // A camera's cloud is mostly whole: counted first, it is copied without a branch per point.
  if (unobserved == 0) {
    std::copy(observed_points.begin(), observed_points.end(), positions_.begin());
    return;
  }
  for (std::size_t i = 0; i < positions_.size(); ++i) {
    if (isFinitePoint(observed_points[i])) positions_[i] = observed_points[i];
  }
}

void ShapeMatchingBody::registerObserved(const std::vector<Eigen::Vector3d>& observed_points,
                                         std::size_t unobserved) {
  const auto* fill_in = unobserved > 0 ? &observed_points : nullptr;
  withMode(config_.mode, [&](auto mode) { registerPositions<decltype(mode)::value>(fill_in); });
}

void ShapeMatchingBody::setPositions(const std::vector<Eigen::Vector3d>& positions) {
  requireOnePerPoint(positions, positions_.size(), "position", "positions");
  track(positions);
}

void ShapeMatchingBody::setVelocities(const std::vector<Eigen::Vector3d>& velocities) {
  requireOnePerPoint(velocities, velocities_.size(), "velocity", "velocities");
  makeDeferredMove();
  velocities_ = velocities;
  stopped_ = false;
  withMode(config_.mode, [&](auto mode) { sumCurrentState<decltype(mode)::value>(); });
}

Eigen::Vector3d ShapeMatchingBody::meanVelocity() const {
  // Each cluster holds a share of its points' masses; the shares add up to the object.
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
  for (const auto& sums : cluster_sums_) momentum += sums.momentum;
  return momentum / config_.mass_kg;
}

// Rigid, whatever the mode: a linear or quadratic fit follows a local dent part of the way,
// and by a share that grows with it, so that the dent would not read in proportion.
void ShapeMatchingBody::restPoseTransforms(std::vector<Eigen::Matrix<double, 3, 9>>& transforms,
                                           std::vector<Eigen::Vector3d>& translations) const {
  transforms.assign(rest_->clusters.size(), Eigen::Matrix<double, 3, 9>::Zero());
  translations.resize(rest_->clusters.size());
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    detail::stepGoal<DeformationMode::kRigid>(rest_->clusters[k], deformations_[k], 0.0, false,
                                              transforms[k], translations[k]);
  }
}

Eigen::Vector3d ShapeMatchingBody::goalPosition(
    std::size_t point, const std::vector<Eigen::Matrix<double, 3, 9>>& transforms,
    const std::vector<Eigen::Vector3d>& translations) const {
  if (point >= positions_.size() || transforms.size() != rest_->clusters.size() ||
      translations.size() != transforms.size()) {
    throw std::out_of_range("goalPosition: point " + std::to_string(point) + " of " +
                            std::to_string(positions_.size()) + ", or transforms of another body");
  }
  const std::uint32_t begin = rest_->point_slot_offsets[point];
  const std::uint32_t end = rest_->point_slot_offsets[point + 1];
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::uint32_t m = begin; m < end; ++m) {
    const auto [k, slot] = rest_->point_slots[m];
    sum +=
        transforms[k] * quadraticFeatures(rest_->clusters[k].rest_offsets[slot]) + translations[k];
  }
  return sum / static_cast<double>(end - begin);
}

template <DeformationMode Mode>
void ShapeMatchingBody::sumCurrentState() {
  constexpr auto kAll = detail::MomentTerms::kMomentumAndSpin;
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    cluster_sums_[k] = detail::clusterSums<kFeatureCount<Mode>, kAll>(
        rest_->clusters[k], point_mass_kg_, positions_, velocities_,
        deformations_[k].center_of_mass, vector_width_);
  }
}

template <DeformationMode Mode>
void ShapeMatchingBody::sumStoppedState() {
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    cluster_sums_[k] = detail::clusterSums<kFeatureCount<Mode>, detail::MomentTerms::kAtRest>(
        rest_->clusters[k], point_mass_kg_, positions_, velocities_,
        deformations_[k].center_of_mass, vector_width_);
  }
}

template <DeformationMode Mode>
void ShapeMatchingBody::registerPositions(const std::vector<Eigen::Vector3d>* observed) {
  constexpr int K = kFeatureCount<Mode>;
  const auto seen = [observed](std::uint32_t i) {
    return observed == nullptr || isFinitePoint((*observed)[i]);
  };
  if (!stopped_) {
    for (auto& v : velocities_) v.setZero();
    stopped_ = true;
  }
  sumStoppedState<Mode>();
  for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
    const Cluster& cluster = rest_->clusters[k];
    if (observed == nullptr || std::all_of(cluster.points.begin(), cluster.points.end(), seen)) {
      // After absurd input the carried state would pass its damage on: start as fresh.
      const Eigen::Vector3d shift = cluster_sums_[k].offset / cluster.total_weight_kg;
      if (!detail::carriedStateFits(deformations_[k], shift, rebase_distance_m_)) {
        deformations_[k] = fresh_deformations_[k];
        cluster_sums_[k] = detail::clusterSums<K, detail::MomentTerms::kAtRest>(
            cluster, point_mass_kg_, positions_, velocities_, deformations_[k].center_of_mass,
            vector_width_);
      }
      detail::registerCluster<Mode>(cluster, cluster_sums_[k], deformations_[k]);
    } else {
      detail::registerObservedSubset<Mode>(cluster, point_mass_kg_, positions_, *observed,
                                           fresh_deformations_[k], rebase_distance_m_,
                                           deformations_[k]);
    }
  }
  if (observed != nullptr) {
    // Unobserved points move to the mean of their clusters' goals.
    double goal[3];
    for (std::size_t k = 0; k < rest_->clusters.size(); ++k) {
      const Cluster& cluster = rest_->clusters[k];
      const GoalKernel<K> kernel(deformations_[k]);
      for (std::size_t j = 0; j < cluster.points.size(); ++j) {
        const std::uint32_t i = cluster.points[j];
        if (seen(i)) continue;
        kernel.goal(cluster.rest_offsets[j], goal);
        goal_sums_[i] += Eigen::Vector3d(goal[0], goal[1], goal[2]);
      }
    }
    for (std::size_t i = 0; i < positions_.size(); ++i) {
      if (seen(static_cast<std::uint32_t>(i))) continue;
      positions_[i] = goal_sums_[i] / rest_->membership_counts[i];
      goal_sums_[i].setZero();
    }
    // The filled-in points moved: the sums must describe the positions now held.
    sumStoppedState<Mode>();
  }
  detail::measureFitResiduals<Mode>(rest_->clusters, positions_, vector_width_, deformations_);
}

void ShapeMatchingBody::setMaterial(double stiffness, double damping) {
  for (const auto& [name, value] : {std::pair{"stiffness", stiffness}, {"damping", damping}}) {
    if (!(value >= 0.0 && value <= 1.0))
      throw std::invalid_argument(describe(name, value, "is outside [0, 1]"));
  }
  config_.stiffness = stiffness;
  config_.damping = damping;
}

}  // namespace deformable_collision
