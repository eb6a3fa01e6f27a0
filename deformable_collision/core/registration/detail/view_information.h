#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

namespace deformable_collision {
namespace detail {

/// A small rigid motion of a whole object: p -> rotation (p - center) + center + translation.
struct RigidMotion {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    return rotation * (p - center) + center + translation;
  }
};

/// What one view's point-to-plane matches say about an object's rigid motion: the 6 x 6
/// information of the rows [n; (a x n) / L] (a match's normal n at arm a from the centre,
/// L the object's RMS radius), one per match, averaged. A direction whose information is
/// small is one the view does not see: a round fruit's turn about its axis, a plate's slide
/// in its plane.
class ViewInformation {
 public:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  /// The information of `count` matches about `center`, from the sum of their rows' outer
  /// products as a point-to-plane step sums them: rows [(p - rows_center) x n; n], the turn
  /// first. O(1): the rows about another point are a fixed linear map of these.
  void set(const Eigen::Vector3d& center, const Eigen::Vector3d& rows_center,
           const Matrix6d& moment, std::size_t count);

  /// The net rigid motion that takes `from` onto `to` (the same points, least squares),
  /// about the centre, and the part of it in the directions the matches leave unseen: each
  /// eigendirection of the information weighted by max(0, 1 - eigenvalue / unseen_below).
  /// L is the RMS radius of `to`. Identity without matches. Allocation-free.
  RigidMotion unseenPart(const std::vector<Eigen::Vector3d>& from,
                         const std::vector<Eigen::Vector3d>& to, double unseen_below) const;

 private:
  Eigen::Vector3d center_ = Eigen::Vector3d::Zero();
  /// Sum of the rows [n; a x n] times their transposes; scaled by L when used.
  Matrix6d moment_ = Matrix6d::Zero();
  std::size_t count_ = 0;
};

}  // namespace detail
}  // namespace deformable_collision
