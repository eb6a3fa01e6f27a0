// RegistrationFitter: clouds registered apart from the scene give the states registerCloud()
// gives, with the same points of other objects left out; pointsNearObject() gathers exactly
// the other objects' points within the registration's reach.
#include "deformable_collision/core/scene/registration_fitter.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace test {
namespace {

using Points = std::vector<Eigen::Vector3d>;

constexpr double kContactDistanceM = 0.01;

/// A vertical plate of 9 x 9 points 1 cm apart, in the plane x = `x_m`.
Points plate(double x_m) {
  Points points;
  for (int i = -4; i <= 4; ++i) {
    for (int j = -4; j <= 4; ++j) points.emplace_back(x_m, 0.01 * i, 0.01 * j);
  }
  return points;
}

/// A scene of a tracked egg (named "egg") beside a static plate that touches its +x end,
/// as jaws touch what they hold; the egg's index is 1.
std::unique_ptr<Scene> eggBesidePlate(const Points& egg, DeformationMode mode) {
  SceneConfig config;
  config.contact_distance_m = kContactDistanceM;
  auto scene = std::make_unique<Scene>(config);
  ObjectConfig jaw;
  jaw.name = "jaw";
  jaw.kind = ObjectKind::kStatic;
  scene->addObject(jaw, plate(0.065));
  ObjectConfig tracked;
  tracked.name = "egg";
  tracked.kind = ObjectKind::kTracked;
  tracked.shape.mode = mode;
  tracked.shape.clusters = 4;
  scene->addObject(tracked, egg);
  return scene;
}

/// Cloud `k` as a camera above sees the egg and the plate: the egg's upper half squeezed
/// along x and moved, the plate whole, shuffled, with noise. Cloud 5 is of the plate alone
/// (the egg out of view), so the registration holds.
Points cloud(const Points& egg, int k, std::mt19937& random) {
  std::normal_distribution<double> noise(0.0, 0.0005);
  const Eigen::Isometry3d motion = Eigen::Translation3d(0.001 * k, -0.001 * k, 0.0005 * k) *
                                   Eigen::AngleAxisd(0.02 * k, Eigen::Vector3d::UnitZ());
  Points points = plate(0.065);
  if (k != 5) {
    for (const auto& p : egg) {
      if (p.z() < 0.0) continue;
      Eigen::Vector3d q = p;
      q.x() *= 1.0 - 0.01 * k;
      points.push_back(motion * q);
    }
  }
  for (auto& p : points) p += Eigen::Vector3d(noise(random), noise(random), noise(random));
  std::shuffle(points.begin(), points.end(), random);
  return points;
}

void expectSameReport(const RegistrationReport& a, const RegistrationReport& b) {
  EXPECT_EQ(a.held, b.held);
  EXPECT_EQ(a.cloud_points, b.cloud_points);
  EXPECT_EQ(a.used_points, b.used_points);
  EXPECT_EQ(a.rejected_points, b.rejected_points);
  EXPECT_EQ(a.excluded_points, b.excluded_points);
  EXPECT_EQ(a.mean_residual_m, b.mean_residual_m);
  EXPECT_EQ(a.max_residual_m, b.max_residual_m);
}

class RegistrationFitterTest : public ::testing::TestWithParam<DeformationMode> {};

// As the node does it: the cycle gathers the points near the egg, the reader registers the
// cloud on its copy without them, and the cycle takes the fit over.
TEST_P(RegistrationFitterTest, GivesTheStatesRegisterCloudGives) {
  const Points egg = sampleNoisySurface(1500, {0.06, 0.05, 0.04}, 0.0, 3);
  auto registered = eggBesidePlate(egg, GetParam());
  auto fitted = eggBesidePlate(egg, GetParam());
  RegistrationFitter fitter = fitted->registrationFitter(1);
  const std::optional<Eigen::Vector3d> viewpoint = Eigen::Vector3d(0.0, 0.0, 0.5);
  std::mt19937 random(5);
  TrackedFit fit;
  Points near;
  Points read;
  std::size_t excluded = 0;
  std::size_t held = 0;
  for (int k = 0; k < 10; ++k) {
    SCOPED_TRACE("cloud " + std::to_string(k));
    const Points points = cloud(egg, k, random);
    const RegistrationReport expected = registered->registerCloud(1, points, viewpoint);
    fitted->pointsNearObject(1, near);
    fitter.setPointsNearObject(near);
    read = points;
    const RegistrationReport report = fitter.fit(read, viewpoint, fit);
    expectSameReport(report, expected);
    if (report.held) {
      EXPECT_EQ(read, points) << "a held cloud is left as it came";
    } else {
      fitted->observeRegistered(1, read, fit, report.surface_error);
    }
    excluded += report.excluded_points;
    held += report.held ? 1 : 0;
    ASSERT_EQ(fitted->body(1).positions(), registered->body(1).positions());
    for (std::size_t c = 0; c < registered->body(1).clusterCount(); ++c) {
      EXPECT_EQ(fitted->body(1).deformation(c).transform,
                registered->body(1).deformation(c).transform);
    }
    registered->cycle();
    fitted->cycle();
    ASSERT_EQ(fitted->contacts().size(), registered->contacts().size());
    for (std::size_t c = 0; c < registered->contacts().size(); ++c) {
      EXPECT_EQ(fitted->contacts()[c].force_error_n, registered->contacts()[c].force_error_n);
    }
  }
  EXPECT_GT(excluded, 0u) << "the plate's points by the egg must be left out";
  EXPECT_EQ(held, 1u) << "the cloud without the egg holds it";
}

INSTANTIATE_TEST_SUITE_P(Modes, RegistrationFitterTest,
                         ::testing::Values(DeformationMode::kRigid, DeformationMode::kLinear,
                                           DeformationMode::kQuadratic),
                         [](const auto& info) { return std::string(toString(info.param)); });

// Objects near and far, one of them posed since the last cycle: exactly the points within
// the egg's root sphere grown by the registration's reach, none of the egg's own.
TEST(Scene, PointsNearObjectAreThoseWithinTheRegistrationsReach) {
  const Points egg = sampleNoisySurface(800, {0.06, 0.05, 0.04}, 0.0, 4);
  auto scene = eggBesidePlate(egg, DeformationMode::kLinear);
  ObjectConfig gripper;
  gripper.name = "finger";
  gripper.kind = ObjectKind::kKinematic;
  const std::size_t finger =
      scene->addObject(gripper, sampleBox(400, Eigen::Vector3d(0.01, 0.01, 0.1), 6));
  ObjectConfig far_box;
  far_box.name = "far";
  far_box.kind = ObjectKind::kStatic;
  const Points far_points = sampleBox(300, Eigen::Vector3d(0.05, 0.05, 0.05), 7);
  Points far_placed;
  for (const auto& p : far_points) far_placed.push_back(p + Eigen::Vector3d(1.0, 0.0, 0.0));
  scene->addObject(far_box, far_placed);
  scene->cycle();
  scene->setPose(finger, Eigen::Isometry3d(Eigen::Translation3d(-0.1, 0.0, 0.0)));

  Points near;
  scene->pointsNearObject(1, near);
  const Sphere root = scene->currentSphere(1, 0);
  const RegistrationConfig& registration = scene->config().registration;
  const double reach = root.radius + registration.iterations * registration.max_correspondence_m +
                       scene->config().contact_distance_m;
  Points expected;
  for (std::size_t o = 0; o < scene->objectCount(); ++o) {
    if (o == 1) continue;
    for (const auto& p : scene->body(o).positions()) {
      if ((p - root.center).norm() <= reach) expected.push_back(p);
    }
  }
  const auto order = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  };
  std::sort(near.begin(), near.end(), order);
  std::sort(expected.begin(), expected.end(), order);
  EXPECT_EQ(near, expected);
  EXPECT_GT(near.size(), 81u) << "the plate and the finger posed beside the egg";
  EXPECT_LT(near.size(), 81u + 400u) << "not the far box";

  SceneConfig alone_config;
  Scene alone(alone_config);
  ObjectConfig tracked;
  tracked.name = "egg";
  tracked.kind = ObjectKind::kTracked;
  alone.addObject(tracked, egg);
  alone.pointsNearObject(0, near);
  EXPECT_TRUE(near.empty()) << "an object alone has nothing to leave out";
  alone_config.registration.exclude_near_other_objects = false;
  auto unfiltered = std::make_unique<Scene>(alone_config);
  unfiltered->addObject(tracked, egg);
  ObjectConfig jaw;
  jaw.name = "jaw";
  jaw.kind = ObjectKind::kStatic;
  unfiltered->addObject(jaw, plate(0.065));
  unfiltered->pointsNearObject(0, near);
  EXPECT_TRUE(near.empty()) << "exclude_near_other_objects: false leaves nothing out";
  EXPECT_THROW(unfiltered->pointsNearObject(2, near), std::out_of_range);
}

// Clouds no camera should send, between good ones: each way holds or registers alike, and
// nothing becomes non-finite.
TEST(RegistrationFitter, AbsurdCloudsGiveTheStatesRegisterCloudGives) {
  const Points egg = sampleNoisySurface(600, {0.06, 0.05, 0.04}, 0.0, 10);
  auto registered = eggBesidePlate(egg, DeformationMode::kQuadratic);
  auto fitted = eggBesidePlate(egg, DeformationMode::kQuadratic);
  RegistrationFitter fitter = fitted->registrationFitter(1);
  std::mt19937 random(11);
  const double nan = std::nan("");
  const std::vector<Points> clouds = {cloud(egg, 1, random),
                                      {},
                                      Points(50, Eigen::Vector3d(nan, 0.0, 0.0)),
                                      {Eigen::Vector3d(0.06, 0.0, 0.0)},
                                      Points(50, Eigen::Vector3d(1e300, -1e300, 1e300)),
                                      Points(50, Eigen::Vector3d(0.06, 0.0, 0.0)),
                                      cloud(egg, 2, random)};
  TrackedFit fit;
  Points near;
  Points read;
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    SCOPED_TRACE("cloud " + std::to_string(k));
    const RegistrationReport expected = registered->registerCloud(1, clouds[k], std::nullopt);
    fitted->pointsNearObject(1, near);
    fitter.setPointsNearObject(near);
    read = clouds[k];
    const RegistrationReport report = fitter.fit(read, std::nullopt, fit);
    expectSameReport(report, expected);
    if (!report.held) fitted->observeRegistered(1, read, fit, report.surface_error);
    ASSERT_EQ(fitted->body(1).positions(), registered->body(1).positions());
    for (const auto& p : fitted->body(1).positions()) ASSERT_TRUE(p.allFinite());
    fitted->cycle();
    registered->cycle();
  }
}

TEST(Scene, RegisteredFitsAreTakenOnlyByTheRestShapeTheyFit) {
  const Points egg = sampleNoisySurface(500, {0.06, 0.05, 0.04}, 0.0, 8);
  auto scene = eggBesidePlate(egg, DeformationMode::kLinear);
  EXPECT_THROW(scene->registrationFitter(0), std::invalid_argument) << "the static plate";
  ObjectConfig other;
  other.name = "other";
  other.kind = ObjectKind::kTracked;
  const std::size_t second = scene->addObject(other, egg);
  RegistrationFitter fitter = scene->registrationFitter(1);
  std::mt19937 random(9);
  Points read = cloud(egg, 1, random);
  TrackedFit fit;
  const RegistrationReport report = fitter.fit(read, std::nullopt, fit);
  ASSERT_FALSE(report.held);
  const Points before = scene->body(second).positions();
  EXPECT_THROW(scene->observeRegistered(second, read, fit, report.surface_error),
               std::invalid_argument);
  EXPECT_EQ(scene->body(second).positions(), before);
  EXPECT_THROW(scene->observeRegistered(0, read, fit, report.surface_error), std::invalid_argument);
  scene->observeRegistered(1, read, fit, report.surface_error);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
