#include "deformable_collision/core/common/linear_algebra.h"

#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <cmath>
#include <limits>
#include <random>

namespace deformable_collision {
namespace {

constexpr double kPi = 3.14159265358979323846;

void expectProperRotation(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.toRotationMatrix();
  ASSERT_TRUE(r.allFinite());
  EXPECT_TRUE((r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(PseudoInverse, FullRankIsTheInverse) {
  Eigen::Matrix3d m;
  m << 4, 1, 0.5, 1, 3, 0.2, 0.5, 0.2, 2;
  const auto result = pseudoInverseSymmetric<3>(m);
  EXPECT_EQ(result.rank, 3);
  EXPECT_TRUE((result.inverse * m).isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_LT(result.null_projector.norm(), 1e-12);
}

TEST(PseudoInverse, PlanarMomentKeepsTheNormalAsNullSpace) {
  const Eigen::Matrix3d m = Eigen::Vector3d(2.0, 5.0, 0.0).asDiagonal();
  const auto result = pseudoInverseSymmetric<3>(m);
  EXPECT_EQ(result.rank, 2);
  EXPECT_TRUE(
      result.inverse.isApprox(Eigen::Vector3d(0.5, 0.2, 0.0).asDiagonal().toDenseMatrix(), 1e-12));
  EXPECT_TRUE(result.null_projector.isApprox(
      Eigen::Vector3d(0.0, 0.0, 1.0).asDiagonal().toDenseMatrix(), 1e-12));
}

TEST(PseudoInverse, ZeroMatrixIsAllNullSpace) {
  const auto result = pseudoInverseSymmetric<9>(Eigen::Matrix<double, 9, 9>::Zero());
  EXPECT_EQ(result.rank, 0);
  EXPECT_EQ(result.inverse.norm(), 0.0);
  EXPECT_TRUE(result.null_projector.isApprox(Eigen::Matrix<double, 9, 9>::Identity()));
}

struct RotationCase {
  const char* name;
  double angle_rad;
  Eigen::Vector3d axis;
  Eigen::Vector3d stretch;  // symmetric positive factor applied after the rotation
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const RotationCase& c, std::ostream* os) { *os << c.name; }

class ExtractRotationTest : public ::testing::TestWithParam<RotationCase> {};

TEST_P(ExtractRotationTest, RecoversTheRotationOfRotationTimesStretch) {
  const auto& c = GetParam();
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(c.angle_rad, c.axis.normalized()).matrix();
  const Eigen::Matrix3d matrix = rotation * c.stretch.asDiagonal();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  extractRotation(matrix, q, 100);
  expectProperRotation(q);
  EXPECT_TRUE(q.toRotationMatrix().isApprox(rotation, 1e-9))
      << q.toRotationMatrix() << "\nexpected\n"
      << rotation;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ExtractRotationTest,
    ::testing::Values(RotationCase{"identity", 0.0, {1, 0, 0}, {1, 1, 1}},
                      RotationCase{"quarter_turn_z", kPi / 2, {0, 0, 1}, {1, 1, 1}},
                      RotationCase{
                          "oblique_120deg_stretched", 2 * kPi / 3, {1, 2, 3}, {2.0, 0.5, 1.0}},
                      RotationCase{"near_half_turn", 0.95 * kPi, {0, 1, 1}, {1, 1, 1}},
                      RotationCase{"tiny_scale", 0.3, {1, 0, 1}, {1e-8, 2e-8, 3e-8}},
                      RotationCase{"huge_scale", 0.3, {1, 1, 0}, {1e8, 2e8, 3e8}}),
    [](const auto& info) { return std::string(info.param.name); });

struct NamedMatrix {
  const char* name;
  Eigen::Matrix3d matrix;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const NamedMatrix& c, std::ostream* os) { *os << c.name; }

class DegenerateRotationTest : public ::testing::TestWithParam<NamedMatrix> {};

TEST_P(DegenerateRotationTest, StaysAProperRotation) {
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 0)));
  extractRotation(GetParam().matrix, q);
  expectProperRotation(q);
}

Eigen::Matrix3d rankOne() {
  return Eigen::Vector3d(1, 2, 3) * Eigen::Vector3d(0.5, -1, 2).transpose();
}

INSTANTIATE_TEST_SUITE_P(
    Cases, DegenerateRotationTest,
    ::testing::Values(
        NamedMatrix{"zero", Eigen::Matrix3d::Zero()}, NamedMatrix{"rank_one", rankOne()},
        NamedMatrix{"rank_two", Eigen::Vector3d(1, 2, 0).asDiagonal().toDenseMatrix()},
        NamedMatrix{"reflection", Eigen::Vector3d(-1, 1, 1).asDiagonal().toDenseMatrix()},
        NamedMatrix{"point_inversion", -Eigen::Matrix3d::Identity()},
        NamedMatrix{"nan", Eigen::Matrix3d::Constant(std::nan(""))}),
    [](const auto& info) { return std::string(info.param.name); });

class SpectralNormTest : public ::testing::TestWithParam<NamedMatrix> {};

// The sphere radii scale by this norm: it may exceed the largest singular value by rounding
// but never fall short of it by more than the relative margin the radii add (1e-12).
TEST_P(SpectralNormTest, IsTheLargestSingularValue) {
  const Eigen::Matrix3d& m = GetParam().matrix;
  const double largest = Eigen::JacobiSVD<Eigen::Matrix3d>(m).singularValues()(0);
  const double norm = spectralNorm(m);
  EXPECT_GE(norm, largest * (1.0 - 1e-14)) << m;
  EXPECT_LE(norm, largest * (1.0 + 1e-12)) << m;
}

Eigen::Matrix3d turned(const Eigen::Vector3d& stretch) {
  return Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).matrix() *
         stretch.asDiagonal() *
         Eigen::AngleAxisd(-1.9, Eigen::Vector3d(0.3, 1, 1).normalized()).matrix();
}

INSTANTIATE_TEST_SUITE_P(
    Cases, SpectralNormTest,
    ::testing::Values(NamedMatrix{"zero", Eigen::Matrix3d::Zero()},
                      NamedMatrix{"identity", Eigen::Matrix3d::Identity()},
                      NamedMatrix{"rotation", turned({1, 1, 1})},
                      NamedMatrix{"stretched", turned({3, 2, 1})},
                      NamedMatrix{"inverted", turned({-3, 2, 1})},
                      NamedMatrix{"rank_one", rankOne()}, NamedMatrix{"flat", turned({2, 1, 0})},
                      NamedMatrix{"two_equal_largest", turned({2, 2, 0.5})},
                      NamedMatrix{"nearly_equal", turned({1, 1 - 1e-15, 1 - 2e-15})},
                      NamedMatrix{"anisotropic", turned({1e6, 1, 1e-6})},
                      NamedMatrix{"huge", turned({3e300, 2e300, 1e300})},
                      NamedMatrix{"tiny", turned({3e-300, 2e-300, 1e-300})}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(SpectralNorm, RandomMatricesOfEveryScale) {
  std::mt19937_64 engine(11);
  std::uniform_real_distribution<double> entry(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-100, 100);
  for (int trial = 0; trial < 2000; ++trial) {
    Eigen::Matrix3d m = Eigen::Matrix3d::NullaryExpr([&] { return entry(engine); });
    m *= std::pow(10.0, exponent(engine));
    const double largest = Eigen::JacobiSVD<Eigen::Matrix3d>(m).singularValues()(0);
    const double norm = spectralNorm(m);
    ASSERT_GE(norm, largest * (1.0 - 1e-14)) << "trial " << trial << "\n" << m;
    ASSERT_LE(norm, largest * (1.0 + 1e-12)) << "trial " << trial << "\n" << m;
  }
}

TEST(SpectralNorm, NonFiniteIsInfinite) {
  EXPECT_EQ(spectralNorm(Eigen::Matrix3d::Constant(std::nan(""))),
            std::numeric_limits<double>::infinity());
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m(1, 2) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(spectralNorm(m), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace deformable_collision
