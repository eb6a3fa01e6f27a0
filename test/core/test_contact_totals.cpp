// Pair summaries and wrenches of contacts (contact_totals.h), against hand-made contacts.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <vector>

#include "deformable_collision/core/response/contact_totals.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace test {
namespace {

constexpr double kPi = 3.14159265358979323846;

SceneContact contactAt(std::uint32_t a, std::uint32_t b, const Eigen::Vector3d& position,
                       const Eigen::Vector3d& force = Eigen::Vector3d::Zero(),
                       double depth = 0.001) {
  SceneContact c;
  c.object_a = a;
  c.object_b = b;
  c.contact.position = position;
  c.contact.normal = Eigen::Vector3d::UnitZ();
  c.contact.depth_m = depth;
  c.force_n = force;
  c.force_error_n = 0.1;
  c.indentation_error_n = 0.05;
  return c;
}

/// Contacts on a grid in the plane z = 0.3 (0.5 mm spacing) kept where `inside` holds.
template <typename Inside>
std::vector<SceneContact> patch(const Inside& inside) {
  std::vector<SceneContact> contacts;
  for (int i = -100; i <= 100; ++i) {
    for (int j = -100; j <= 100; ++j) {
      const Eigen::Vector2d p(0.0005 * i, 0.0005 * j);
      if (inside(p)) contacts.push_back(contactAt(0, 1, {p.x(), p.y(), 0.3}));
    }
  }
  return contacts;
}

struct AreaCase {
  std::string name;
  std::vector<SceneContact> contacts;
  double area_m2;
  double tolerance;  ///< Relative.
};

TEST(SummarizePairsTest, AreaOfTheContactPatch) {
  const std::vector<AreaCase> cases{
      {"disc r 4 cm", patch([](const Eigen::Vector2d& p) { return p.norm() <= 0.04; }),
       kPi * 0.04 * 0.04, 0.03},
      {"square 6 cm",
       patch([](const Eigen::Vector2d& p) { return p.cwiseAbs().maxCoeff() <= 0.03; }), 0.06 * 0.06,
       0.08},
      {"ellipse 4 x 1 cm", patch([](const Eigen::Vector2d& p) {
         return std::hypot(p.x() / 0.04, p.y() / 0.01) <= 1.0;
       }),
       kPi * 0.04 * 0.01, 0.03},
      {"one contact", {contactAt(0, 1, {0.0, 0.0, 0.3})}, 0.0, 0.0},
  };
  for (const AreaCase& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<PairSummary> summaries;
    summarizePairs(c.contacts, summaries);
    ASSERT_EQ(summaries.size(), 1u);
    EXPECT_NEAR(summaries[0].area_m2, c.area_m2, c.tolerance * c.area_m2 + 1e-12);
    EXPECT_EQ(summaries[0].contacts, c.contacts.size());
    EXPECT_NEAR(summaries[0].centroid_m.z(), 0.3, 1e-12);
  }
}

TEST(SummarizePairsTest, OneSummaryPerPairWithItsTotals) {
  const std::vector<SceneContact> contacts{
      contactAt(0, 1, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 0.001),
      contactAt(0, 1, {0.2, 0.0, 0.0}, {0.0, 0.0, 3.0}, 0.003),
      contactAt(2, 1, {1.0, 1.0, 1.0}, {1.0, 0.0, 0.0}, 0.002),
  };
  std::vector<PairSummary> summaries;
  summarizePairs(contacts, summaries);
  ASSERT_EQ(summaries.size(), 2u);
  EXPECT_EQ(summaries[0].object_a, 0u);
  EXPECT_EQ(summaries[0].contacts, 2u);
  EXPECT_TRUE(summaries[0].centroid_m.isApprox(Eigen::Vector3d(0.1, 0.0, 0.0)));
  EXPECT_TRUE(summaries[0].force_n.isApprox(Eigen::Vector3d(0.0, 0.0, 4.0)));
  EXPECT_DOUBLE_EQ(summaries[0].largest_depth_m, 0.003);
  EXPECT_DOUBLE_EQ(summaries[0].force_error_n, 0.1);  // the indentation's, not the split's
  EXPECT_TRUE(summaries[0].normal.isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_EQ(summaries[1].object_a, 2u);
  EXPECT_DOUBLE_EQ(summaries[1].area_m2, 0.0);
}

TEST(WrenchOnTest, SumsForcesAndMomentsInTheFrame) {
  // Object 1 is b of both contacts: it gets the opposite of their forces.
  const std::vector<SceneContact> contacts{
      contactAt(0, 1, {1.0, 0.0, 0.0}, {0.0, 0.0, -2.0}),
      contactAt(0, 1, {-1.0, 0.0, 0.0}, {0.0, 0.0, -2.0}),
      contactAt(0, 2, {0.0, 5.0, 0.0}, {0.0, 0.0, -7.0}),
  };
  const Wrench centred = wrenchOn(contacts, 1, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(centred.force_n.isApprox(Eigen::Vector3d(0.0, 0.0, 4.0)));
  EXPECT_NEAR(centred.torque_nm.norm(), 0.0, 1e-12);
  // About x = 1: the contact at x = -1 pushes up 2 m away: (-2, 0, 0) x (0, 0, 2), 4 N m about y.
  Eigen::Isometry3d frame = Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.0, 0.0));
  Wrench offset = wrenchOn(contacts, 1, frame);
  EXPECT_TRUE(offset.torque_nm.isApprox(Eigen::Vector3d(0.0, 4.0, 0.0)));
  // A frame turned 90 degrees about z reads the same vectors in its own axes.
  frame.rotate(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()));
  const Wrench turned = wrenchOn(contacts, 1, frame);
  EXPECT_TRUE(turned.force_n.isApprox(Eigen::Vector3d(0.0, 0.0, 4.0)));
  EXPECT_TRUE(turned.torque_nm.isApprox(Eigen::Vector3d(4.0, 0.0, 0.0), 1e-12));
  EXPECT_TRUE(wrenchOn(contacts, 3, frame).force_n.isZero());
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
