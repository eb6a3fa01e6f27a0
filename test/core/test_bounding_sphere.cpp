#include "deformable_collision/core/hierarchy/bounding_sphere.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <functional>
#include <random>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

bool encloses(const Sphere& s, const Points& points, double tolerance) {
  for (const auto& p : points) {
    if ((p - s.center).norm() > s.radius + tolerance) return false;
  }
  return true;
}

/// The smallest of all spheres through 1 to 4 of the points that encloses them all.
double bruteForceRadius(const Points& p) {
  double best = std::numeric_limits<double>::infinity();
  const auto consider = [&](const Eigen::Vector3d& center) {
    if (!center.allFinite()) return;
    double r = 0.0;
    for (const auto& q : p) r = std::max(r, (q - center).norm());
    best = std::min(best, r);
  };
  const auto circumcenter3 = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                const Eigen::Vector3d& c, Eigen::Vector3d& out) {
    const Eigen::Vector3d ab = b - a, ac = c - a, n = ab.cross(ac);
    if (n.squaredNorm() < 1e-24) return false;
    out = a + (ab.squaredNorm() * ac - ac.squaredNorm() * ab).cross(n) / (2 * n.squaredNorm());
    return true;
  };
  const std::size_t n = p.size();
  for (std::size_t i = 0; i < n; ++i) {
    consider(p[i]);
    for (std::size_t j = i + 1; j < n; ++j) {
      consider(0.5 * (p[i] + p[j]));
      for (std::size_t k = j + 1; k < n; ++k) {
        Eigen::Vector3d c;
        if (circumcenter3(p[i], p[j], p[k], c)) consider(c);
        for (std::size_t l = k + 1; l < n; ++l) {
          Eigen::Matrix3d m;
          m.row(0) = p[j] - p[i];
          m.row(1) = p[k] - p[i];
          m.row(2) = p[l] - p[i];
          if (std::abs(m.determinant()) <
              1e-9 * m.row(0).norm() * m.row(1).norm() * m.row(2).norm()) {
            continue;
          }
          const Eigen::Vector3d rhs(0.5 * m.row(0).squaredNorm(), 0.5 * m.row(1).squaredNorm(),
                                    0.5 * m.row(2).squaredNorm());
          consider(p[i] + m.partialPivLu().solve(rhs));
        }
      }
    }
  }
  return best;
}

TEST(SmallestEnclosingSphere, MatchesBruteForceOnSmallRandomSets) {
  std::mt19937_64 engine(31);
  std::uniform_int_distribution<int> size(1, 9);
  for (int trial = 0; trial < 300; ++trial) {
    Points points = sampleBox(size(engine), {1.0, 0.7, 0.4}, 100 + trial);
    if (trial % 5 == 0 && points.size() > 2) {
      const Eigen::Vector3d duplicate = points[1];
      points.push_back(duplicate);
    }
    const Sphere s = smallestEnclosingSphere(points);
    EXPECT_TRUE(encloses(s, points, 1e-12)) << "trial " << trial;
    EXPECT_NEAR(s.radius, bruteForceRadius(points), 1e-9) << "trial " << trial;
  }
}

struct DegenerateCase {
  const char* name;
  std::function<Points()> make;
  double expected_radius;  // < 0: compare with brute force
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const DegenerateCase& c, std::ostream* os) { *os << c.name; }

Points collinear(std::size_t n, const Eigen::Vector3d& offset, double spacing) {
  Points p;
  for (std::size_t i = 0; i < n; ++i) {
    p.push_back(offset + spacing * static_cast<double>(i) * Eigen::Vector3d(1, 2, 2) / 3.0);
  }
  return p;
}

class DegenerateSphereTest : public ::testing::TestWithParam<DegenerateCase> {};

TEST_P(DegenerateSphereTest, EnclosesWithTheSmallestRadius) {
  const auto& c = GetParam();
  const Points points = c.make();
  const Sphere s = smallestEnclosingSphere(points);
  double scale = 0.0;
  for (const auto& p : points) scale = std::max(scale, p.cwiseAbs().maxCoeff());
  EXPECT_TRUE(encloses(s, points, 0.0));
  const double expected = c.expected_radius >= 0.0 ? c.expected_radius : bruteForceRadius(points);
  EXPECT_NEAR(s.radius, expected, 1e-9 * (expected + 1e-12) + 1e-14 * scale);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, DegenerateSphereTest,
    ::testing::Values(DegenerateCase{"single_point",
                                     [] {
                                       return Points{{3, -2, 1}};
                                     },
                                     0.0},
                      DegenerateCase{"all_coincident",
                                     [] { return Points(50, Eigen::Vector3d(1, 1, 1)); }, 0.0},
                      DegenerateCase{"collinear_1000",
                                     [] {
                                       return collinear(1000, {1, 2, 3}, 0.01);
                                     },
                                     4.995},
                      DegenerateCase{"collinear_far_1e5",
                                     [] {
                                       return collinear(200, {1e5, -1e5, 1e5}, 0.01);
                                     },
                                     0.995},
                      DegenerateCase{"coplanar_square",
                                     [] {
                                       Points p;
                                       for (int i = 0; i <= 20; ++i)
                                         for (int j = 0; j <= 20; ++j)
                                           p.emplace_back(0.1 * i, 0.1 * j, 5.0);
                                       return p;
                                     },
                                     std::sqrt(2.0)},
                      DegenerateCase{"cube_corners_repeated",
                                     [] {
                                       Points p;
                                       for (int r = 0; r < 5; ++r)
                                         for (int i = 0; i < 8; ++i)
                                           p.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1,
                                                          i & 4 ? 1 : -1);
                                       return p;
                                     },
                                     std::sqrt(3.0)},
                      DegenerateCase{"tiny_1e_minus4",
                                     [] {
                                       Points p = sampleBox(8, {1e-4, 1e-4, 1e-4}, 5);
                                       return p;
                                     },
                                     -1.0},
                      DegenerateCase{"huge_1e4_far",
                                     [] {
                                       Points p = sampleBox(8, {1e4, 1e4, 1e4}, 6);
                                       for (auto& x : p) x += Eigen::Vector3d(1e5, 1e5, -1e5);
                                       return p;
                                     },
                                     -1.0}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(SmallestEnclosingSphere, EnclosesLargeSetsAtAnyScale) {
  for (const double scale : {1e-4, 1.0, 1e4}) {
    const Points points = sampleEllipsoid(20000, {scale, 0.5 * scale, 0.2 * scale}, 9);
    const Sphere s = smallestEnclosingSphere(points);
    EXPECT_TRUE(encloses(s, points, 0.0)) << scale;
    EXPECT_LE(s.radius, scale * (1.0 + 1e-9)) << scale;
    EXPECT_GE(s.radius, 0.99 * scale) << scale;
  }
}

TEST(EnclosingSphereOfSpheres, EnclosesEverySphere) {
  const Sphere spheres[3] = {{{0, 0, 0}, 1.0}, {{3, 0, 0}, 0.5}, {{0, 4, 1}, 0.0}};
  const Sphere s = enclosingSphereOfSpheres(spheres, 3);
  for (const auto& inner : spheres) {
    EXPECT_LE((inner.center - s.center).norm() + inner.radius, s.radius * (1 + 1e-15));
  }
}

}  // namespace
}  // namespace deformable_collision
