#include "deformable_collision/core/registration/detail/view_information.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "deformable_collision/core/common/linear_algebra.h"

namespace deformable_collision {
namespace detail {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

/// The rigid motion p -> rotation (p - centre of from) + centre of to that takes `from`
/// nearest to `to`, as its rotation and the two centres; the RMS radius of `to`.
struct NetMotion {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d from_center = Eigen::Vector3d::Zero(), to_center = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};

NetMotion netMotion(const std::vector<Eigen::Vector3d>& from,
                    const std::vector<Eigen::Vector3d>& to) {
  NetMotion net;
  const double n = static_cast<double>(from.size());
  for (std::size_t i = 0; i < from.size(); ++i) {
    net.from_center += from[i] / n;
    net.to_center += to[i] / n;
  }
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector3d arm = to[i] - net.to_center;
    cross.noalias() += arm * (from[i] - net.from_center).transpose();
    net.radius_m += arm.squaredNorm() / n;
  }
  net.radius_m = std::sqrt(net.radius_m);
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  extractRotation(cross, rotation);
  net.rotation = rotation.toRotationMatrix();
  return net;
}

}  // namespace

// With d = rows_center - center, a match's row about the centre is [n; a x n + d x n]: the
// given row [a x n; n] reordered, its turn part gaining d x n.
void ViewInformation::set(const Eigen::Vector3d& center, const Eigen::Vector3d& rows_center,
                          const Matrix6d& moment, std::size_t count) {
  const Eigen::Vector3d d = rows_center - center;
  Matrix6d map = Matrix6d::Zero();
  map.topRightCorner<3, 3>().setIdentity();
  map.bottomLeftCorner<3, 3>().setIdentity();
  map.bottomRightCorner<3, 3>() << 0.0, -d.z(), d.y(), d.z(), 0.0, -d.x(), -d.y(), d.x(), 0.0;
  center_ = center;
  moment_ = map * moment * map.transpose();
  count_ = count;
}

RigidMotion ViewInformation::unseenPart(const std::vector<Eigen::Vector3d>& from,
                                        const std::vector<Eigen::Vector3d>& to,
                                        double unseen_below) const {
  RigidMotion unseen;
  unseen.center = center_;
  if (count_ == 0 || from.empty() || from.size() != to.size()) return unseen;
  const NetMotion net = netMotion(from, to);
  const double radius = net.radius_m;
  if (!(radius > 0.0) || !std::isfinite(radius)) return unseen;
  // The motion about the view's centre, its turn as the arc it moves a point at L: metres
  // in all six components, as the scaled rows measure them.
  const Eigen::AngleAxisd turn(net.rotation);
  Vector6d motion;
  motion << net.rotation * (center_ - net.from_center) + net.to_center - center_,
      radius * turn.angle() * turn.axis();
  Vector6d scale;
  scale << 1.0, 1.0, 1.0, 1.0 / radius, 1.0 / radius, 1.0 / radius;
  const Matrix6d information =
      scale.asDiagonal() * moment_ * scale.asDiagonal() / static_cast<double>(count_);
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(information);
  Vector6d part = Vector6d::Zero();
  for (int k = 0; k < 6; ++k) {
    const double weight = std::max(0.0, 1.0 - solver.eigenvalues()(k) / unseen_below);
    const auto direction = solver.eigenvectors().col(k);
    part += weight * direction.dot(motion) * direction;
  }
  if (!part.allFinite()) return unseen;
  unseen.translation = part.head<3>();
  const Eigen::Vector3d rotation = part.tail<3>() / radius;
  const double angle = rotation.norm();
  if (angle > 0.0) unseen.rotation = Eigen::AngleAxisd(angle, rotation / angle).toRotationMatrix();
  return unseen;
}

}  // namespace detail
}  // namespace deformable_collision
