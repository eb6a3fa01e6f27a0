// Internal to CloudRegistration: one cluster's fit while a cloud is registered, and the
// least-squares sums it is solved from.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace deformable_collision {
namespace detail {

using Features = Eigen::Matrix<double, 9, 1>;

/// One cluster's transform while a cloud is registered: goal = transform q~ + translation.
struct ClusterFit {
  Eigen::Matrix<double, 3, 9> transform = Eigen::Matrix<double, 3, 9>::Zero();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d goal(const Features& features) const {
    return transform * features + translation;
  }
  /// The goal of a linear or rigid fit, whose quadratic columns are zero, at rest offset q.
  Eigen::Vector3d linearGoal(const Eigen::Vector3d& q) const {
    return transform.leftCols<3>() * q + translation;
  }
};

/// Weighted least-squares sums of one cluster's fit: pairs of features q~ and targets y,
/// the targets taken about a reference near the object.
struct FitSums {
  double weight = 0.0;
  Features features = Features::Zero();
  Eigen::Vector3d targets = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 3, 9> target_features = Eigen::Matrix<double, 3, 9>::Zero();
  Eigen::Matrix<double, 9, 9> feature_moment = Eigen::Matrix<double, 9, 9>::Zero();

  /// Adds a pair to the sums of the first K features, which a fit with K features reads.
  template <int K>
  void add(double w, const Features& f, const Eigen::Vector3d& y) {
    const auto head = f.head<K>();
    weight += w;
    features.head<K>() += w * head;
    targets += w * y;
    target_features.leftCols<K>().noalias() += (w * y) * head.transpose();
    feature_moment.topLeftCorner<K, K>().noalias() += (w * head) * head.transpose();
  }
};

/// A matching point's place in one cluster.
struct Membership {
  std::uint32_t cluster = 0;
  Features features = Features::Zero();  ///< q~ of its rest offset in that cluster.
};

}  // namespace detail
}  // namespace deformable_collision
