#include "deformable_collision/core/registration/detail/view_information.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace deformable_collision {
namespace detail {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// A view of a shape: its points, and the outward normals of the half the camera (at -y)
/// sees.
struct View {
  Points points;
  Points seen, normals;
};

/// A ball of radius 0.05 m, centred at the origin.
View ball() {
  View view;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 80; ++j) {
      const double polar = M_PI * (i + 0.5) / 40.0;
      const double azimuth = 2.0 * M_PI * j / 80.0;
      const Eigen::Vector3d normal(std::sin(polar) * std::cos(azimuth),
                                   std::sin(polar) * std::sin(azimuth), std::cos(polar));
      view.points.push_back(0.05 * normal);
      if (normal.y() < 0.0) {
        view.seen.push_back(0.05 * normal);
        view.normals.push_back(normal);
      }
    }
  }
  return view;
}

/// A box of 0.1 x 0.06 x 0.04 m seen on three faces: -y, +z and +x.
View box() {
  View view;
  const Eigen::Vector3d half(0.05, 0.03, 0.02);
  for (int axis = 0; axis < 3; ++axis) {
    for (const double side : {-1.0, 1.0}) {
      Eigen::Vector3d normal = Eigen::Vector3d::Zero();
      normal[axis] = side;
      const bool seen =
          (axis == 1 && side < 0) || (axis == 2 && side > 0) || (axis == 0 && side > 0);
      for (int u = 0; u <= 10; ++u) {
        for (int v = 0; v <= 10; ++v) {
          Eigen::Vector3d p;
          p[axis] = side * half[axis];
          p[(axis + 1) % 3] = (u / 5.0 - 1.0) * half[(axis + 1) % 3];
          p[(axis + 2) % 3] = (v / 5.0 - 1.0) * half[(axis + 2) % 3];
          view.points.push_back(p);
          if (!seen) continue;
          view.seen.push_back(p);
          view.normals.push_back(normal);
        }
      }
    }
  }
  return view;
}

Points moved(const Points& points, const RigidMotion& motion) {
  Points result;
  for (const auto& p : points) result.push_back(motion.apply(p));
  return result;
}

RigidMotion turn(const Eigen::Vector3d& axis, double angle_rad) {
  RigidMotion motion;
  motion.rotation = Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
  return motion;
}

RigidMotion shift(const Eigen::Vector3d& translation_m) {
  RigidMotion motion;
  motion.translation = translation_m;
  return motion;
}

struct Case {
  std::string name;
  View view;
  RigidMotion motion;
  bool unseen;  ///< The whole motion is unseen, else none of it.
};

// A ball's turn about its centre leaves its surface where it was: no view sees it, and it is
// all taken for unseen; its shift, and every motion of a box seen on three faces, are seen.
/// The information of the first `count` seen points of `view` about the origin, given as a
/// point-to-plane step sums its rows: about `rows_center`, the turn first.
ViewInformation informationOf(const View& view, std::size_t count,
                              const Eigen::Vector3d& rows_center) {
  ViewInformation::Matrix6d moment = ViewInformation::Matrix6d::Zero();
  for (std::size_t i = 0; i < count; ++i) {
    Eigen::Matrix<double, 6, 1> row;
    row << (view.seen[i] - rows_center).cross(view.normals[i]), view.normals[i];
    moment += row * row.transpose();
  }
  ViewInformation information;
  information.set(Eigen::Vector3d::Zero(), rows_center, moment, count);
  return information;
}

// Whatever point the step's rows are taken about, the information is about the shape's
// centre: the same unseen part.
TEST(ViewInformation, TakesForUnseenWhatTheMatchesCannotSee) {
  const std::vector<Case> cases = {
      {"ball turned about z", ball(), turn({0, 0, 1}, 0.02), true},
      {"ball turned about x and y", ball(), turn({1, 1, 0}, 0.03), true},
      {"ball shifted", ball(), shift({0.001, -0.002, 0.001}), false},
      {"box turned", box(), turn({0, 0, 1}, 0.02), false},
      {"box shifted", box(), shift({0.002, 0.001, -0.001}), false},
  };
  for (const Case& c : cases) {
    for (const Eigen::Vector3d& rows_center :
         {Eigen::Vector3d::Zero().eval(), Eigen::Vector3d(0.03, -0.02, 0.01)}) {
      const ViewInformation information = informationOf(c.view, c.view.seen.size(), rows_center);
      const RigidMotion unseen =
          information.unseenPart(c.view.points, moved(c.view.points, c.motion), 0.005);
      const RigidMotion expected = c.unseen ? c.motion : RigidMotion();
      EXPECT_TRUE(unseen.rotation.isApprox(expected.rotation, 1e-6)) << c.name;
      EXPECT_LT((unseen.translation - expected.translation).norm(), 1e-6) << c.name;
    }
  }
}

TEST(ViewInformation, WithoutMatchesOrPointsNothingIsUnseen) {
  const View view = ball();
  const Points turned = moved(view.points, turn({0, 0, 1}, 0.1));
  RigidMotion unseen =
      informationOf(view, 0, Eigen::Vector3d::Zero()).unseenPart(view.points, turned, 0.005);
  EXPECT_TRUE(unseen.rotation.isIdentity()) << "no matches";
  const ViewInformation information = informationOf(view, 1, Eigen::Vector3d::Zero());
  unseen = information.unseenPart({}, {}, 0.005);
  EXPECT_TRUE(unseen.rotation.isIdentity() && unseen.translation.isZero()) << "no points";
  const Points same(3, Eigen::Vector3d(0.1, 0.2, 0.3));
  unseen = information.unseenPart(same, same, 0.005);
  EXPECT_TRUE(unseen.translation.allFinite() && unseen.rotation.allFinite()) << "one place";
}

}  // namespace
}  // namespace detail
}  // namespace deformable_collision
