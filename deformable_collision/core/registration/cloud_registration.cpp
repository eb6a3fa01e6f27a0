// Correspondence-free registration of a shape-matching model to a depth camera's cloud:
// non-rigid ICP whose deformation model is the body's own clustered shape matching
// (docs/design.md, registration).
#include "deformable_collision/core/registration/cloud_registration.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/common/nearest_point_index.h"
#include "deformable_collision/core/registration/detail/cluster_fit.h"
#include "deformable_collision/core/registration/detail/rest_normals.h"
#include "deformable_collision/core/registration/detail/spread_points.h"
#include "deformable_collision/core/registration/detail/view_information.h"

namespace deformable_collision {
namespace {

using detail::ClusterFit;
using detail::Features;
using detail::FitSums;
using detail::Membership;

using Clock = std::chrono::steady_clock;

/// A match below this multiple of the round's median distance is kept: well above the
/// spread of noise about a surface, well below a table or a hand a few centimetres off.
constexpr double kMedianMultiple = 3.0;
/// ... and whatever the median, a quarter of max_correspondence_m is kept: noise-free data
/// has a median near zero, which must not reject good matches.
constexpr double kThresholdFloorRatio = 0.25;

/// The hidden side's estimated error is the seen side's plus this multiple of the clusters'
/// disagreement there (SurfaceError): the clusters' extrapolations spread about the truth
/// as they spread about their mean. Chosen on bench_registration_zoo.
constexpr double kDisagreementMultiple = 2.0;

/// Weight of the prior (the cluster's shape-matching goal moved with the object) per
/// matching point of the cluster, against 1 per matched point: it fills in what the camera
/// does not constrain (a cluster seen on one face, or not at all) and damps noise, at the
/// price of a round's fit going only part of the way. Chosen on bench_registration.
constexpr double kPriorWeight = 0.3;

/// The share of kPriorWeight that holds the object's rigid step (per match): enough to stop
/// noise from sliding the model along a face seen edge-on, little enough to follow a box
/// turning a degree and sliding 1.7 mm between clouds within the rounds of one cloud.
constexpr double kRigidStepPriorShare = 0.1;
/// ... and that holds its turn (per match, times the squared arm): ten times more, since a
/// turn is what one view of a round object shows least (a fruit's surface barely changes as
/// it turns), and noise turned a still fruit by degrees. Chosen on bench_registration_zoo.
constexpr double kRigidTurnPriorShare = 1.0;

/// A direction of the object's rigid motion whose information per match (rows [n; (a x n)
/// / L], about the whole model's centre; about 1/3 where a view sees it fully) is below this
/// is not seen: the motion a cloud's fits make in it is taken back in proportion, or the
/// model drifts where nothing holds it (a round fruit turns as it is squeezed). Higher, a
/// round object carried and turned lags its turn. Chosen on bench_registration_zoo.
constexpr double kUnseenInformation = 0.005;

}  // namespace

struct CloudRegistration::Workspace {
  /// The body this workspace was laid out for (its rest shape's storage and size): a new
  /// body, or a new rest shape, lays it out again.
  const Eigen::Vector3d* laid_out_for = nullptr;
  std::size_t laid_out_size = 0;
  DeformationMode mode = DeformationMode::kLinear;

  std::vector<std::uint32_t> matching_points;  ///< Model indices of the matching points.
  /// Clusters holding matching point m: memberships[membership_offsets[m] .. [m + 1]).
  std::vector<std::uint32_t> membership_offsets;
  std::vector<Membership> memberships;
  /// Per cluster, the sums of its matching points' features with weight 1: with the
  /// cluster's transform they give the sums of the prior without visiting the points.
  std::vector<FitSums> prior_sums;
  std::vector<Features> mean_features;           ///< Per cluster, as its features are taken here.
  double shape_beta = 0.5;                       ///< The body's beta.
  std::vector<std::uint32_t> clusters_of_point;  ///< Per model point.
  std::vector<Eigen::Vector3d> positions;        ///< Of the matching points, this round.
  std::vector<Eigen::Vector3d> start_positions;  ///< ... as the cloud's first round began.
  detail::ViewInformation view;                  ///< Of the last round's matches.
  /// The matching points that may be seen (all, without a viewpoint): the tree's points.
  std::vector<Eigen::Vector3d> tree_positions;
  std::vector<std::uint32_t> tree_members;  ///< Matching point of each tree point.
  NearestPointIndex tree;
  /// Surface normal of each matching point on the rest shape, turned with its first
  /// cluster: matches pull along it only, so the model slides freely along the surface it
  /// already lies on (point-to-plane ICP).
  detail::RestNormals rest_normals;
  std::vector<Eigen::Vector3d> current_normals;  ///< This round's, outward.

  std::vector<Eigen::Vector3d> samples;        ///< The thinned finite cloud.
  std::vector<std::uint32_t> match_of_sample;  ///< Matching point nearest to each sample.
  std::vector<double> distance_of_sample;      ///< Its distance.
  std::vector<double> sorted_distances;        ///< Scratch for the median.
  std::vector<Eigen::Vector3d> target_sums;    ///< Per matching point.
  std::vector<std::uint32_t> target_counts;    ///< Per matching point.
  std::vector<ClusterFit> fits;                ///< Per cluster.
  std::vector<FitSums> sums;                   ///< Per cluster, this round.
  std::vector<Eigen::Vector3d> goals;          ///< Per model point, once the fits are done.

  void layOut(const ShapeMatchingBody& body, std::size_t max_model_points);
  /// The thinned finite cloud into `samples`, without what `filter` excludes.
  void sampleCloud(const std::vector<Eigen::Vector3d>& cloud, std::size_t max_samples,
                   CloudPointFilter* filter, RegistrationReport& report);
  /// Places the matching points by the clusters' fits and builds the tree over those that
  /// face `viewpoint` (all of them without one).
  void placeMatchingPoints(const std::optional<Eigen::Vector3d>& viewpoint);
  /// Places the matching points and their normals by the clusters' fits.
  void placePositions();
  /// Cluster k's goal at a point of these features (only the first three unless quadratic).
  Eigen::Vector3d goal(std::uint32_t k, const Features& features) const {
    return mode == DeformationMode::kQuadratic ? fits[k].goal(features)
                                               : fits[k].linearGoal(features.head<3>());
  }
  /// Matches each sample to its nearest matching point within `max_distance_m`; the
  /// median distance.
  double matchSamples(double max_distance_m);
  /// Sums each matched point's targets and finds the object's rigid step; the matches.
  std::size_t gatherTargets(double threshold, detail::RigidMotion& step);
  /// Refits every cluster: the matches' targets against the cluster's last transform moved
  /// by the rigid step, weighted by prior_weight per matching point.
  void fitClusters(const detail::RigidMotion& step, double prior_weight);
  template <int K>
  void solveCluster(std::size_t k, const Eigen::Matrix3d& step_rotation);
  /// Takes back the part of the cloud's net rigid motion that its matches do not see.
  void holdUnseenMotion();
  /// Moves the body's points to the mean of their clusters' goals.
  void applyFits(ShapeMatchingBody& body);
  /// The last round's matches against the model where it ended: their distance to its
  /// surface, along the normal.
  void measureResiduals(double threshold, RegistrationReport& report) const;
  /// The RMS disagreement of the clusters' goals at the matching points that do not face
  /// `viewpoint` (all of them without one).
  double hiddenDisagreement(const std::optional<Eigen::Vector3d>& viewpoint) const;
};

void CloudRegistration::Workspace::layOut(const ShapeMatchingBody& body,
                                          std::size_t max_model_points) {
  const auto& rest = body.restPositions();
  mode = body.config().mode;
  matching_points = detail::spreadPoints(rest, max_model_points);
  constexpr auto kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> index_of_point(rest.size(), kNone);
  for (std::uint32_t m = 0; m < matching_points.size(); ++m) index_of_point[matching_points[m]] = m;
  std::vector<std::vector<Membership>> held(matching_points.size());
  prior_sums.assign(body.clusterCount(), FitSums{});
  shape_beta = body.config().beta;
  mean_features.resize(body.clusterCount());
  clusters_of_point.assign(rest.size(), 0);
  for (std::uint32_t k = 0; k < body.clusterCount(); ++k) {
    const Cluster& cluster = body.cluster(k);
    mean_features[k] = cluster.mean_features;
    if (mode != DeformationMode::kQuadratic) mean_features[k].tail<6>().setZero();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const std::uint32_t i = cluster.points[j];
      ++clusters_of_point[i];
      if (index_of_point[i] == kNone) continue;
      Features features = quadraticFeatures(cluster.rest_offsets[j]);
      if (mode != DeformationMode::kQuadratic) features.tail<6>().setZero();
      held[index_of_point[i]].push_back({k, features});
      prior_sums[k].add<9>(1.0, features, Eigen::Vector3d::Zero());
    }
  }
  membership_offsets.assign(1, 0);
  memberships.clear();
  for (const auto& entries : held) {
    memberships.insert(memberships.end(), entries.begin(), entries.end());
    membership_offsets.push_back(static_cast<std::uint32_t>(memberships.size()));
  }
  rest_normals = detail::restNormals(rest, matching_points);
  current_normals.resize(matching_points.size());
  positions.resize(matching_points.size());
  start_positions.resize(matching_points.size());
  tree_positions.reserve(matching_points.size());
  tree_members.reserve(matching_points.size());
  target_sums.assign(matching_points.size(), Eigen::Vector3d::Zero());
  target_counts.assign(matching_points.size(), 0);
  fits.resize(body.clusterCount());
  sums.resize(body.clusterCount());
  goals.assign(rest.size(), Eigen::Vector3d::Zero());
  laid_out_for = rest.data();
  laid_out_size = rest.size();
}

void CloudRegistration::Workspace::sampleCloud(const std::vector<Eigen::Vector3d>& cloud,
                                               std::size_t max_samples, CloudPointFilter* filter,
                                               RegistrationReport& report) {
  std::size_t& finite_count = report.cloud_points;
  finite_count = 0;
  for (const auto& p : cloud) finite_count += p.allFinite() ? 1 : 0;
  // Every stride-th finite point: evenly over the cloud's order, which for a camera's cloud
  // is evenly over the image.
  const std::size_t stride =
      std::max<std::size_t>(1, (finite_count + max_samples - 1) / max_samples);
  samples.clear();
  std::size_t seen = 0;
  for (const auto& p : cloud) {
    if (!p.allFinite()) continue;
    if (seen++ % stride != 0) continue;
    if (filter && filter->excludes(p)) {
      ++report.excluded_points;
    } else {
      samples.push_back(p);
    }
  }
  match_of_sample.resize(samples.size());
  distance_of_sample.resize(samples.size());
}

void CloudRegistration::Workspace::placePositions() {
  for (std::uint32_t m = 0; m < matching_points.size(); ++m) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::uint32_t e = membership_offsets[m]; e < membership_offsets[m + 1]; ++e) {
      sum += goal(memberships[e].cluster, memberships[e].features);
    }
    positions[m] = sum / static_cast<double>(membership_offsets[m + 1] - membership_offsets[m]);
    current_normals[m] =
        fits[memberships[membership_offsets[m]].cluster].rotation * rest_normals.outward[m];
  }
}

void CloudRegistration::Workspace::holdUnseenMotion() {
  placePositions();
  const detail::RigidMotion unseen =
      view.unseenPart(start_positions, positions, kUnseenInformation);
  const Eigen::Matrix3d back = unseen.rotation.transpose();
  const Eigen::Quaterniond back_turn(back);
  for (ClusterFit& fit : fits) {
    fit.transform = back * fit.transform;
    fit.translation = back * (fit.translation - unseen.center - unseen.translation) + unseen.center;
    fit.rotation = (back_turn * fit.rotation).normalized();
  }
}

void CloudRegistration::Workspace::placeMatchingPoints(
    const std::optional<Eigen::Vector3d>& viewpoint) {
  placePositions();
  tree_positions.clear();
  tree_members.clear();
  for (std::uint32_t m = 0; m < matching_points.size(); ++m) {
    // A point whose surface faces away from the camera cannot be what it sees, however
    // near: the far side of a thin object, the hidden face next to a seen edge. A point
    // on an edge would be pulled off it by the seen face's points on one side alone.
    if (!rest_normals.flat[m]) continue;
    if (viewpoint && current_normals[m].dot(*viewpoint - positions[m]) < 0.0) continue;
    tree_positions.push_back(positions[m]);
    tree_members.push_back(m);
  }
  tree.build(tree_positions);
}

double CloudRegistration::Workspace::matchSamples(double max_distance_m) {
  sorted_distances.clear();
  if (tree_positions.empty()) {
    std::fill(distance_of_sample.begin(), distance_of_sample.end(),
              std::numeric_limits<double>::infinity());
    return 0.0;
  }
  // A sample beyond max_distance_m is never matched, and its distance only has to stay
  // above the median's reach: the search stops at the bound (a hair over it, so that no
  // distance that rounds to it is lost), and the sample counts as infinitely far.
  const double bound = max_distance_m * (1.0 + 1e-9);
  for (std::size_t j = 0; j < samples.size(); ++j) {
    NearestPointIndex::Nearest nearest;
    const bool found = tree.nearestWithin(samples[j], bound * bound, nearest);
    match_of_sample[j] = found ? tree_members[nearest.index] : 0;
    distance_of_sample[j] =
        found ? std::sqrt(nearest.squared_distance_m2) : std::numeric_limits<double>::infinity();
    sorted_distances.push_back(distance_of_sample[j]);
  }
  if (sorted_distances.empty()) return 0.0;
  auto middle = sorted_distances.begin() + static_cast<std::ptrdiff_t>(sorted_distances.size() / 2);
  std::nth_element(sorted_distances.begin(), middle, sorted_distances.end());
  return *middle;
}

std::size_t CloudRegistration::Workspace::gatherTargets(double threshold,
                                                        detail::RigidMotion& step) {
  std::size_t used = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < samples.size(); ++j) {
    if (!(distance_of_sample[j] <= threshold)) continue;
    const std::uint32_t m = match_of_sample[j];
    target_sums[m] += samples[j];
    ++target_counts[m];
    center += positions[m];
    ++used;
  }
  if (used == 0) return 0;
  center /= static_cast<double>(used);
  Eigen::Vector3d object_center = Eigen::Vector3d::Zero();
  for (const auto& p : positions) object_center += p / static_cast<double>(positions.size());
  // One Gauss-Newton step of point-to-plane ICP for the whole object (rotation w about
  // `center` and translation v, linearised): a match on a flat patch constrains only the
  // distance along its normal, so the model slides along the surface in one step instead
  // of being held by the matches' sideways pulls.
  Eigen::Matrix<double, 6, 6> normal_matrix = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> right_side = Eigen::Matrix<double, 6, 1>::Zero();
  const auto addRow = [&](const Eigen::Vector3d& arm, const Eigen::Vector3d& normal, double gap) {
    Eigen::Matrix<double, 6, 1> row;
    row << arm.cross(normal), normal;
    normal_matrix.noalias() += row * row.transpose();
    right_side += row * gap;
  };
  for (std::size_t j = 0; j < samples.size(); ++j) {
    if (!(distance_of_sample[j] <= threshold)) continue;
    const std::uint32_t m = match_of_sample[j];
    const Eigen::Vector3d& normal = current_normals[m];
    addRow(positions[m] - center, normal, normal.dot(samples[j] - positions[m]));
  }
  view.set(object_center, center, normal_matrix, used);
  // A share of the clusters' prior holds the step: a direction the matches constrain only
  // weakly (a face seen edge-on) moves about as far as they outweigh it, not as far as their
  // noise says, while a well-seen motion is followed within a round or two.
  double arm_squared = 0.0;
  for (std::size_t j = 0; j < samples.size(); ++j) {
    if (distance_of_sample[j] <= threshold)
      arm_squared += (positions[match_of_sample[j]] - center).squaredNorm();
  }
  normal_matrix.diagonal().head<3>().array() +=
      kRigidTurnPriorShare * kPriorWeight * arm_squared + 1e-300;
  normal_matrix.diagonal().tail<3>().array() +=
      kRigidStepPriorShare * kPriorWeight * static_cast<double>(used);
  const Eigen::Matrix<double, 6, 1> motion = normal_matrix.ldlt().solve(right_side);
  step.center = center;
  step.translation =
      motion.tail<3>().allFinite() ? Eigen::Vector3d(motion.tail<3>()) : Eigen::Vector3d::Zero();
  const double angle = motion.head<3>().norm();
  step.rotation = angle > 0.0 && std::isfinite(angle)
                      ? Eigen::AngleAxisd(angle, motion.head<3>() / angle).toRotationMatrix()
                      : Eigen::Matrix3d::Identity();
  return used;
}

void CloudRegistration::Workspace::fitClusters(const detail::RigidMotion& step,
                                               double prior_weight) {
  // The prior: the cluster's shape-matching goal moved by the rigid step, y = B q~ + b,
  // summed in closed form from the cluster's feature sums. Pulling towards the goal rather
  // than the last fit keeps what the camera cannot tell (a slide along a smooth surface, a
  // stretch of a face seen from one side) from accumulating cloud after cloud.
  const double beta = mode == DeformationMode::kRigid ? 0.0 : shape_beta;
  for (std::size_t k = 0; k < fits.size(); ++k) {
    // The shape-matching goal of the cluster's last fit, about its centre: what a step
    // would pull it towards (beta blends the fit with its rotation).
    Eigen::Matrix<double, 3, 9> goal = beta * fits[k].transform;
    goal.leftCols<3>() += (1.0 - beta) * fits[k].rotation.toRotationMatrix();
    const Eigen::Vector3d centre = fits[k].goal(mean_features[k]);
    const Eigen::Matrix<double, 3, 9> moved = step.rotation * goal;
    const Eigen::Vector3d offset = step.apply(centre - goal * mean_features[k]) - step.center;
    const FitSums& prior = prior_sums[k];
    FitSums& s = sums[k];
    s.weight = prior_weight * prior.weight;
    s.features = prior_weight * prior.features;
    s.feature_moment = prior_weight * prior.feature_moment;
    s.targets = prior_weight * (moved * prior.features + offset * prior.weight);
    s.target_features =
        prior_weight * (moved * prior.feature_moment + offset * prior.features.transpose());
  }
  for (std::size_t m = 0; m < matching_points.size(); ++m) {
    if (target_counts[m] == 0) continue;
    // From where the rigid step takes the point, the matches pull it along the surface
    // normal only: sideways, a surface sampled no denser than the model pulls at random,
    // and inwards wherever the view of a face ends.
    const Eigen::Vector3d moved = step.apply(positions[m]);
    const Eigen::Vector3d normal = step.rotation * current_normals[m];
    const Eigen::Vector3d pull = target_sums[m] / target_counts[m] - moved;
    const Eigen::Vector3d target = moved + normal * normal.dot(pull) - step.center;
    for (std::uint32_t e = membership_offsets[m]; e < membership_offsets[m + 1]; ++e) {
      FitSums& s = sums[memberships[e].cluster];
      if (mode == DeformationMode::kQuadratic) {
        s.add<9>(1.0, memberships[e].features, target);
      } else {
        s.add<3>(1.0, memberships[e].features, target);
      }
    }
    target_sums[m].setZero();
    target_counts[m] = 0;
  }
  for (std::size_t k = 0; k < fits.size(); ++k) {
    if (mode == DeformationMode::kQuadratic) {
      solveCluster<9>(k, step.rotation);
    } else {
      solveCluster<3>(k, step.rotation);
    }
    fits[k].translation += step.center;
  }
}

template <int K>
void CloudRegistration::Workspace::solveCluster(std::size_t k,
                                                const Eigen::Matrix3d& step_rotation) {
  const FitSums& s = sums[k];
  ClusterFit& fit = fits[k];
  const Eigen::Matrix<double, K, 1> mean_features = s.features.template head<K>() / s.weight;
  const Eigen::Vector3d mean_target = s.targets / s.weight;
  const Eigen::Matrix<double, 3, K> cross =
      s.target_features.template leftCols<K>() - s.weight * mean_target * mean_features.transpose();
  const Eigen::Matrix<double, K, K> moment = s.feature_moment.template topLeftCorner<K, K>() -
                                             s.weight * mean_features * mean_features.transpose();
  Eigen::Quaterniond rotation(step_rotation * fit.rotation.toRotationMatrix());
  Eigen::Matrix<double, 3, K> transform;
  if (mode == DeformationMode::kRigid) {
    extractRotation(cross.template leftCols<3>(), rotation);
    transform.template leftCols<3>() = rotation.toRotationMatrix();
  } else {
    transform = cross * pseudoInverseSymmetric<K>(moment).inverse;
    extractRotation(transform.template leftCols<3>(), rotation);
  }
  if (!transform.allFinite() || !rotation.coeffs().allFinite()) return;
  fit.transform.setZero();
  fit.transform.template leftCols<K>() = transform;
  fit.translation = mean_target - transform * mean_features;
  fit.rotation = rotation;
}

void CloudRegistration::Workspace::applyFits(ShapeMatchingBody& body) {
  for (auto& goal : goals) goal.setZero();
  for (std::size_t k = 0; k < fits.size(); ++k) {
    const Cluster& cluster = body.cluster(k);
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Vector3d& q = cluster.rest_offsets[j];
      goals[cluster.points[j]] += mode == DeformationMode::kQuadratic
                                      ? fits[k].goal(quadraticFeatures(q))
                                      : fits[k].linearGoal(q);
    }
  }
  for (std::size_t i = 0; i < goals.size(); ++i)
    goals[i] /= static_cast<double>(clusters_of_point[i]);
  body.track(goals);
}

void validateRegistrationConfig(const RegistrationConfig& config) {
  std::ostringstream problem;
  if (config.iterations < 1) {
    problem << "RegistrationConfig.iterations = " << config.iterations << " must be >= 1";
  } else if (!(config.max_correspondence_m > 0.0) || !std::isfinite(config.max_correspondence_m)) {
    problem << "RegistrationConfig.max_correspondence_m = " << config.max_correspondence_m
            << " must be finite and > 0";
  } else if (config.max_cloud_points < 1 || config.max_model_points < 1) {
    problem << "RegistrationConfig.max_cloud_points = " << config.max_cloud_points
            << " and max_model_points = " << config.max_model_points << " must be >= 1";
  } else if (!(config.min_match_ratio >= 0.0 && config.min_match_ratio <= 1.0)) {
    problem << "RegistrationConfig.min_match_ratio = " << config.min_match_ratio
            << " must be in [0, 1]";
  }
  if (!problem.str().empty()) throw std::invalid_argument(problem.str());
}

CloudRegistration::CloudRegistration(const RegistrationConfig& config) : config_(config) {
  validateRegistrationConfig(config);
  workspace_ = std::make_unique<Workspace>();
}

CloudRegistration::~CloudRegistration() = default;

void CloudRegistration::setWorkPerCloud(int iterations, std::size_t max_cloud_points) {
  RegistrationConfig changed = config_;
  changed.iterations = iterations;
  changed.max_cloud_points = max_cloud_points;
  validateRegistrationConfig(changed);
  config_ = changed;
}
CloudRegistration::CloudRegistration(CloudRegistration&&) noexcept = default;
CloudRegistration& CloudRegistration::operator=(CloudRegistration&&) noexcept = default;

void CloudRegistration::Workspace::measureResiduals(double threshold,
                                                    RegistrationReport& report) const {
  for (std::size_t j = 0; j < samples.size(); ++j) {
    if (!(distance_of_sample[j] <= threshold)) {
      ++report.rejected_points;
      continue;
    }
    const std::uint32_t m = match_of_sample[j];
    const double residual = std::abs(current_normals[m].dot(samples[j] - positions[m]));
    report.surface_error.seen_m += residual * residual;
    report.mean_residual_m += residual;
    report.max_residual_m = std::max(report.max_residual_m, residual);
    ++report.used_points;
  }
  if (report.used_points == 0) return;
  report.mean_residual_m /= static_cast<double>(report.used_points);
  report.surface_error.seen_m =
      std::sqrt(report.surface_error.seen_m / static_cast<double>(report.used_points));
}

double CloudRegistration::Workspace::hiddenDisagreement(
    const std::optional<Eigen::Vector3d>& viewpoint) const {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::uint32_t m = 0; m < matching_points.size(); ++m) {
    if (viewpoint && current_normals[m].dot(*viewpoint - positions[m]) > 0.0) continue;
    const std::uint32_t begin = membership_offsets[m], end = membership_offsets[m + 1];
    for (std::uint32_t e = begin; e < end; ++e) {
      const Eigen::Vector3d g = goal(memberships[e].cluster, memberships[e].features);
      sum += (g - positions[m]).squaredNorm() / static_cast<double>(end - begin);
    }
    ++count;
  }
  return count == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(count));
}

RegistrationReport CloudRegistration::registerCloud(
    ShapeMatchingBody& body, const std::vector<Eigen::Vector3d>& cloud_m,
    const std::optional<Eigen::Vector3d>& viewpoint_m, CloudPointFilter* filter) {
  const auto start = Clock::now();
  Workspace& w = *workspace_;
  if (w.laid_out_for != body.restPositions().data() || w.laid_out_size != body.pointCount()) {
    w.layOut(body, config_.max_model_points);
  }
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const ClusterDeformation& deformation = body.deformation(k);
    w.fits[k] = {deformation.transform, deformation.translation, deformation.rotation};
  }
  RegistrationReport report;
  w.sampleCloud(cloud_m, config_.max_cloud_points, filter, report);
  const double needed =
      std::max(1.0, config_.min_match_ratio * static_cast<double>(w.samples.size()));
  double threshold = 0.0;
  int rounds_done = 0;
  for (int round = 0; round < config_.iterations; ++round) {
    w.placeMatchingPoints(viewpoint_m);
    if (round == 0) w.start_positions = w.positions;
    const double median = w.matchSamples(config_.max_correspondence_m);
    threshold = std::min(
        config_.max_correspondence_m,
        std::max(kMedianMultiple * median, kThresholdFloorRatio * config_.max_correspondence_m));
    detail::RigidMotion step;
    const std::size_t used = w.gatherTargets(threshold, step);
    if (static_cast<double>(used) < needed) {
      // Not the object (another one, the table alone, nothing): leave the model be.
      std::fill(w.target_sums.begin(), w.target_sums.end(), Eigen::Vector3d::Zero());
      std::fill(w.target_counts.begin(), w.target_counts.end(), 0);
      break;
    }
    w.fitClusters(step, kPriorWeight);
    ++rounds_done;
  }
  if (rounds_done == 0) {
    report.held = true;
    report.rejected_points = w.samples.size();
  } else {
    w.holdUnseenMotion();
    w.applyFits(body);
    w.placeMatchingPoints(viewpoint_m);
    w.measureResiduals(threshold, report);
    SurfaceError& error = report.surface_error;
    error.hidden_m = error.seen_m + kDisagreementMultiple * w.hiddenDisagreement(viewpoint_m);
    error.viewpoint_m = viewpoint_m;
    if (!viewpoint_m) error.seen_m = error.hidden_m;
  }
  report.time_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return report;
}

}  // namespace deformable_collision
