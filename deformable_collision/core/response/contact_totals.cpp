// Per pair and per object totals of the contacts' forces, for controllers.
#include "deformable_collision/core/response/contact_totals.h"

#include <algorithm>
#include <cmath>

#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// pi (2 s1)(2 s2) of the positions' spread across `normal`.
double spreadArea(const std::vector<SceneContact>& contacts, std::size_t begin, std::size_t end,
                  const Eigen::Vector3d& centroid, const Eigen::Vector3d& normal) {
  const std::size_t count = end - begin;
  if (count < 2) return 0.0;
  const Eigen::Vector3d u = normal.unitOrthogonal();
  const Eigen::Vector3d v = normal.cross(u);
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  for (std::size_t k = begin; k < end; ++k) {
    const Eigen::Vector3d d = contacts[k].contact.position - centroid;
    const Eigen::Vector2d across(d.dot(u), d.dot(v));
    covariance += across * across.transpose();
  }
  covariance /= static_cast<double>(count);
  const double determinant = std::max(0.0, covariance.determinant());
  return 4.0 * kPi * std::sqrt(determinant);
}

PairSummary summarizePair(const std::vector<SceneContact>& contacts, std::size_t begin,
                          std::size_t end) {
  PairSummary summary;
  summary.object_a = contacts[begin].object_a;
  summary.object_b = contacts[begin].object_b;
  summary.contacts = end - begin;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (std::size_t k = begin; k < end; ++k) {
    const SceneContact& c = contacts[k];
    summary.centroid_m += c.contact.position;
    normal_sum += c.contact.depth_m * c.contact.normal;
    summary.largest_depth_m = std::max(summary.largest_depth_m, c.contact.depth_m);
    summary.force_n += c.force_n;
    summary.force_error_n += c.indentation_error_n;
    summary.registration_error_m = std::max(summary.registration_error_m, c.registration_error_m);
  }
  summary.centroid_m /= static_cast<double>(summary.contacts);
  const double length = normal_sum.norm();
  summary.normal = length > 0.0 ? Eigen::Vector3d(normal_sum / length)
                                : Eigen::Vector3d(contacts[begin].contact.normal);
  summary.area_m2 = spreadArea(contacts, begin, end, summary.centroid_m, summary.normal);
  return summary;
}

}  // namespace

void summarizePairs(const std::vector<SceneContact>& contacts,
                    std::vector<PairSummary>& summaries) {
  summaries.clear();
  for (std::size_t begin = 0; begin < contacts.size();) {
    const std::size_t end = pairRunEnd(contacts, begin);
    summaries.push_back(summarizePair(contacts, begin, end));
    begin = end;
  }
}

Wrench wrenchOn(const std::vector<SceneContact>& contacts, std::uint32_t object,
                const Eigen::Isometry3d& frame) {
  Wrench wrench;
  for (const SceneContact& c : contacts) {
    if (c.object_a != object && c.object_b != object) continue;
    const Eigen::Vector3d force = c.object_a == object ? c.force_n : Eigen::Vector3d(-c.force_n);
    wrench.force_n += force;
    wrench.torque_nm += (c.contact.position - frame.translation()).cross(force);
  }
  const Eigen::Matrix3d to_frame = frame.linear().transpose();
  wrench.force_n = to_frame * wrench.force_n;
  wrench.torque_nm = to_frame * wrench.torque_nm;
  return wrench;
}

}  // namespace deformable_collision
