#include "deformable_collision/core/shape_matching/fit.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <tuple>

#include "deformable_collision/core/common/linear_algebra.h"
#include "deformable_collision/core/shape_matching/detail/kernels.h"
#include "deformable_collision/core/shape_matching/detail/wide.h"

namespace deformable_collision::detail {
namespace {

/// Pseudo-inverse of a feature moment matrix into the top-left block of `inverse`, and the
/// completion N that lets unspanned directions follow the rotation (see Cluster).
template <int K>
void invertFeatureMoment(const Eigen::Matrix<double, K, K>& moment, double radius_m,
                         Eigen::Matrix<double, 9, 9>& inverse,
                         Eigen::Matrix<double, 3, 9>& completion) {
  inverse.setZero();
  completion.setZero();
  if constexpr (K == 3) {
    const auto result = pseudoInverseSymmetric<3>(moment);
    inverse.topLeftCorner<3, 3>() = result.inverse;
    completion.leftCols<3>() = result.null_projector;
  } else {
    // Linear and quadratic features differ in units by a length; scaling them by the
    // cluster radius keeps the eigenvalue cut-off meaningful from 1e-4 m to 1e4 m.
    const double s = radius_m > 0.0 ? radius_m : 1.0;
    Eigen::Matrix<double, 9, 1> unscale;
    unscale << 1 / s, 1 / s, 1 / s, 1 / (s * s), 1 / (s * s), 1 / (s * s), 1 / (s * s), 1 / (s * s),
        1 / (s * s);
    const Eigen::Matrix<double, 9, 9> scaled = unscale.asDiagonal() * moment * unscale.asDiagonal();
    const auto result = pseudoInverseSymmetric<9>(scaled);
    inverse = unscale.asDiagonal() * result.inverse * unscale.asDiagonal();
    completion = s * result.null_projector.topRows<3>() * unscale.asDiagonal();
  }
}

/// The weighted moment of the cluster's centred features, sum w (q~ - mean)(q~ - mean)^T.
template <int K>
Eigen::Matrix<double, K, K> centredFeatureMoment(const Cluster& cluster, double point_mass_kg) {
  Eigen::Matrix<double, K, K> moment = Eigen::Matrix<double, K, K>::Zero();
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    const Eigen::Matrix<double, K, 1> f =
        featuresOf<K>(cluster.rest_offsets[j]) - cluster.mean_features.template head<K>();
    moment.noalias() += slotWeightKg(cluster, j, point_mass_kg) * f * f.transpose();
  }
  return moment;
}

/// The transform fitted to the centred moment A_pq: R, or A_pq A_qq^+ + R N.
template <DeformationMode Mode, int K>
Eigen::Matrix<double, 3, K> fittedTransform(const Eigen::Matrix<double, 3, K>& moment_pq,
                                            const Eigen::Matrix<double, 9, 9>& moment_inverse,
                                            const Eigen::Matrix<double, 3, 9>& null_completion,
                                            const Eigen::Matrix3d& rotation) {
  if constexpr (Mode == DeformationMode::kRigid) {
    return rotation;
  } else {
    return moment_pq * moment_inverse.template topLeftCorner<K, K>() +
           rotation * null_completion.template leftCols<K>();
  }
}

/// What the observed slots of a cluster add up to: mass, mean features and centre of mass.
template <int K>
struct ObservedMean {
  double mass = 0.0;
  Eigen::Matrix<double, K, 1> features = Eigen::Matrix<double, K, 1>::Zero();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};

/// Of the slots with finite `observed` positions; zero mass if there are none.
template <int K>
ObservedMean<K> observedMean(const Cluster& cluster, double point_mass_kg,
                             const std::vector<Eigen::Vector3d>& positions,
                             const std::vector<Eigen::Vector3d>& observed,
                             const Eigen::Vector3d& reference) {
  ObservedMean<K> mean;
  Eigen::Vector3d offset_sum = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    if (!observed[cluster.points[j]].allFinite()) continue;
    const double w = slotWeightKg(cluster, j, point_mass_kg);
    mean.mass += w;
    mean.features += w * featuresOf<K>(cluster.rest_offsets[j]);
    offset_sum += w * (positions[cluster.points[j]] - reference);
  }
  if (!(mean.mass > 0.0)) return mean;
  mean.features /= mean.mass;
  mean.center = reference + offset_sum / mean.mass;
  return mean;
}

/// The centred moments of the observed slots of a cluster: A_pq, A_qq and the mean squared
/// linear feature (the square of the subset's radius).
template <int K>
struct ObservedMoments {
  Eigen::Matrix<double, 3, K> pq = Eigen::Matrix<double, 3, K>::Zero();
  Eigen::Matrix<double, K, K> qq = Eigen::Matrix<double, K, K>::Zero();
  double second_moment = 0.0;
};

template <int K>
ObservedMoments<K> observedMoments(const Cluster& cluster, double point_mass_kg,
                                   const std::vector<Eigen::Vector3d>& positions,
                                   const std::vector<Eigen::Vector3d>& observed,
                                   const ObservedMean<K>& mean) {
  ObservedMoments<K> moments;
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    if (!observed[cluster.points[j]].allFinite()) continue;
    const double w = slotWeightKg(cluster, j, point_mass_kg);
    const Eigen::Matrix<double, K, 1> f = featuresOf<K>(cluster.rest_offsets[j]) - mean.features;
    moments.pq.noalias() += w * (positions[cluster.points[j]] - mean.center) * f.transpose();
    moments.qq.noalias() += w * f * f.transpose();
    moments.second_moment += w * f.template head<3>().squaredNorm();
  }
  return moments;
}

/// Linear transform to a goal: the (volume-preserving) fit blended with the rotation.
/// The fit is taken as R S (polar form), and the eigenvalues of the stretch S are clamped
/// from below at a tenth of the largest before the volume is normalised: a flattened or
/// inverted fit then yields a proper, bounded goal that varies continuously with the
/// points. Dividing by cbrt(det A) instead would let an overshooting object pass through
/// flat into inversion, where the goal jumps and feeds energy in.
Eigen::Matrix3d linearGoalTransform(const Eigen::Matrix3d& fit, const Eigen::Quaterniond& rotation,
                                    double beta, bool preserve_volume) {
  const Eigen::Matrix3d r = rotation.toRotationMatrix();
  if (!preserve_volume) return beta * fit + (1.0 - beta) * r;
  // R rotates A_pq = A A_qq; the stretch of A itself needs A's own polar rotation, which is
  // close to R, so R is the warm start.
  Eigen::Quaterniond fit_rotation = rotation;
  extractRotation(fit, fit_rotation);
  const Eigen::Matrix3d fit_r = fit_rotation.toRotationMatrix();
  const Eigen::Matrix3d unsymmetric_stretch = fit_r.transpose() * fit;
  const Eigen::Matrix3d stretch = 0.5 * (unsymmetric_stretch + unsymmetric_stretch.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(stretch);
  Eigen::Vector3d principal = solver.eigenvalues();
  const double largest = principal.cwiseAbs().maxCoeff();
  Eigen::Matrix3d volume_preserving = r;
  if (largest > 0.0 && std::isfinite(largest)) {
    principal = principal.cwiseMax(0.1 * largest);
    principal /= std::cbrt(principal.prod());
    volume_preserving =
        fit_r * solver.eigenvectors() * principal.asDiagonal() * solver.eigenvectors().transpose();
  }
  return beta * volume_preserving + (1.0 - beta) * r;
}

/// Residual d of one cluster, eight slots at a time with the wide vectors if asked.
template <int K>
double fitResidual(const Cluster& cluster, const ClusterDeformation& deformation,
                   const std::vector<Eigen::Vector3d>& positions,
                   [[maybe_unused]] VectorWidth width) {
  const GoalKernel<K> kernel(deformation);
  double deviation_squared = 0.0;
  std::size_t j = 0;
#if defined(__GNUC__) && defined(__x86_64__)
  if (width == VectorWidth::kAvx512) {
    std::tie(deviation_squared, j) =
        largestSquaredGoalDistanceAvx512<K>(kernel, cluster, positions.data());
  } else if (width == VectorWidth::kAvx2) {
    std::tie(deviation_squared, j) =
        largestSquaredGoalDistanceAvx2<K>(kernel, cluster, positions.data());
  }
#endif
  for (; j < cluster.points.size(); ++j) {
    deviation_squared = std::max(
        deviation_squared,
        squaredGoalDistance<K>(kernel, cluster.rest_offsets[j], positions[cluster.points[j]]));
  }
  return std::sqrt(deviation_squared);
}

}  // namespace

void precomputeMoments(Cluster& cluster, DeformationMode mode, double point_mass_kg) {
  double second_moment = 0.0;
  Eigen::Matrix<double, 9, 1> feature_sum = Eigen::Matrix<double, 9, 1>::Zero();
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    feature_sum +=
        slotWeightKg(cluster, j, point_mass_kg) * quadraticFeatures(cluster.rest_offsets[j]);
    second_moment +=
        slotWeightKg(cluster, j, point_mass_kg) * cluster.rest_offsets[j].squaredNorm();
  }
  cluster.mean_features = feature_sum / cluster.total_weight_kg;
  for (const auto& q : cluster.rest_offsets) {
    const double norm =
        mode == DeformationMode::kQuadratic ? quadraticFeatures(q).norm() : q.norm();
    cluster.max_feature_norm = std::max(cluster.max_feature_norm, norm);
  }
  if (mode == DeformationMode::kLinear) {
    invertFeatureMoment<3>(centredFeatureMoment<3>(cluster, point_mass_kg), 1.0,
                           cluster.moment_inverse, cluster.null_completion);
  } else if (mode == DeformationMode::kQuadratic) {
    invertFeatureMoment<9>(centredFeatureMoment<9>(cluster, point_mass_kg),
                           std::sqrt(second_moment / cluster.total_weight_kg),
                           cluster.moment_inverse, cluster.null_completion);
  }
}

template <DeformationMode Mode>
void registerCluster(const Cluster& cluster, const ClusterSums& sums,
                     ClusterDeformation& deformation) {
  constexpr int K = kFeatureCount<Mode>;
  const double mass = cluster.total_weight_kg;
  const Eigen::Vector3d shift = sums.offset / mass;
  const Eigen::Matrix<double, 3, K> moment_pq =
      sums.offset_features.template leftCols<K>() -
      mass * shift * cluster.mean_features.template head<K>().transpose();
  extractRotation(moment_pq.template leftCols<3>(), deformation.rotation);
  deformation.center_of_mass = sums.reference + shift;
  const Eigen::Matrix<double, 3, K> transform =
      fittedTransform<Mode, K>(moment_pq, cluster.moment_inverse, cluster.null_completion,
                               deformation.rotation.toRotationMatrix());
  deformation.transform.setZero();
  deformation.transform.template leftCols<K>() = transform;
  deformation.translation =
      deformation.center_of_mass - transform * cluster.mean_features.template head<K>();
}

bool carriedStateFits(const ClusterDeformation& deformation, const Eigen::Vector3d& shift,
                      double rebase_distance_m) {
  return deformation.rotation.coeffs().allFinite() && shift.norm() <= rebase_distance_m;
}

template <DeformationMode Mode>
void registerObservedSubset(const Cluster& cluster, double point_mass_kg,
                            const std::vector<Eigen::Vector3d>& positions,
                            const std::vector<Eigen::Vector3d>& observed,
                            const ClusterDeformation& fresh, double rebase_distance_m,
                            ClusterDeformation& deformation) {
  constexpr int K = kFeatureCount<Mode>;
  ObservedMean<K> mean =
      observedMean<K>(cluster, point_mass_kg, positions, observed, deformation.center_of_mass);
  if (!(mean.mass > 0.0)) {
    const bool finite = deformation.transform.allFinite() && deformation.translation.allFinite() &&
                        deformation.rotation.coeffs().allFinite();
    if (!finite) deformation = fresh;
    return;
  }
  if (!carriedStateFits(deformation, mean.center - deformation.center_of_mass, rebase_distance_m)) {
    deformation = fresh;
    mean = observedMean<K>(cluster, point_mass_kg, positions, observed, deformation.center_of_mass);
  }
  const ObservedMoments<K> moments =
      observedMoments<K>(cluster, point_mass_kg, positions, observed, mean);
  extractRotation(moments.pq.template leftCols<3>(), deformation.rotation);
  Eigen::Matrix<double, 9, 9> inverse = Eigen::Matrix<double, 9, 9>::Zero();
  Eigen::Matrix<double, 3, 9> completion = Eigen::Matrix<double, 3, 9>::Zero();
  if constexpr (Mode != DeformationMode::kRigid) {
    invertFeatureMoment<K>(moments.qq, std::sqrt(moments.second_moment / mean.mass), inverse,
                           completion);
  }
  const Eigen::Matrix<double, 3, K> transform = fittedTransform<Mode, K>(
      moments.pq, inverse, completion, deformation.rotation.toRotationMatrix());
  deformation.transform.setZero();
  deformation.transform.template leftCols<K>() = transform;
  deformation.translation = mean.center - transform * mean.features;
  deformation.center_of_mass =
      deformation.translation + transform * cluster.mean_features.template head<K>();
}

template <DeformationMode Mode>
void stepGoal(const Cluster& cluster, const ClusterDeformation& deformation, double beta,
              bool preserve_volume, Eigen::Matrix<double, 3, 9>& transform,
              Eigen::Vector3d& translation) {
  constexpr int K = kFeatureCount<Mode>;
  const Eigen::Matrix3d rotation = deformation.rotation.toRotationMatrix();
  const Eigen::Matrix<double, 3, K> fit = deformation.transform.template leftCols<K>();
  Eigen::Matrix<double, 3, K> goal;
  if constexpr (Mode == DeformationMode::kRigid) {
    goal = rotation;
  } else if constexpr (Mode == DeformationMode::kLinear) {
    goal = linearGoalTransform(fit, deformation.rotation, beta, preserve_volume);
  } else {
    goal = beta * fit;
    goal.template leftCols<3>() += (1.0 - beta) * rotation;
  }
  transform.template leftCols<K>() = goal;
  translation = deformation.center_of_mass - goal * cluster.mean_features.template head<K>();
}

template <DeformationMode Mode>
void measureFitResiduals(const std::vector<Cluster>& clusters,
                         const std::vector<Eigen::Vector3d>& positions, VectorWidth width,
                         std::vector<ClusterDeformation>& deformations) {
  for (std::size_t k = 0; k < clusters.size(); ++k) {
    deformations[k].goal_deviation_bound_m =
        fitResidual<kFeatureCount<Mode>>(clusters[k], deformations[k], positions, width);
  }
}

// The fit for every deformation mode.
#define DEFORMABLE_COLLISION_SHAPE_MATCHING_FIT(MODE)                                           \
  template void registerCluster<MODE>(const Cluster&, const ClusterSums&, ClusterDeformation&); \
  template void registerObservedSubset<MODE>(                                                   \
      const Cluster&, double, const std::vector<Eigen::Vector3d>&,                              \
      const std::vector<Eigen::Vector3d>&, const ClusterDeformation&, double,                   \
      ClusterDeformation&);                                                                     \
  template void stepGoal<MODE>(const Cluster&, const ClusterDeformation&, double, bool,         \
                               Eigen::Matrix<double, 3, 9>&, Eigen::Vector3d&);                 \
  template void measureFitResiduals<MODE>(const std::vector<Cluster>&,                          \
                                          const std::vector<Eigen::Vector3d>&, VectorWidth,     \
                                          std::vector<ClusterDeformation>&);
DEFORMABLE_COLLISION_SHAPE_MATCHING_FIT(DeformationMode::kRigid)
DEFORMABLE_COLLISION_SHAPE_MATCHING_FIT(DeformationMode::kLinear)
DEFORMABLE_COLLISION_SHAPE_MATCHING_FIT(DeformationMode::kQuadratic)
#undef DEFORMABLE_COLLISION_SHAPE_MATCHING_FIT

}  // namespace deformable_collision::detail
