// TrackedFitter: clouds fitted apart from the scene give the states observe() gives, and a
// fit is taken only by the rest shape it fits.
#include "deformable_collision/core/scene/tracked_fitter.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

// A tracked object whose clouds a fitter fits apart (as the node's reader thread does) goes
// through the states observe() gives it, to the bit: clouds that turn, stretch, bend, have
// holes, and one so far away that the fit starts afresh.
struct FittedCloudCase {
  const char* name;
  DeformationMode mode;
  int clusters;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const FittedCloudCase& c, std::ostream* os) { *os << c.name; }

class FittedCloudTest : public ::testing::TestWithParam<FittedCloudCase> {};

/// Cloud `k` of a box of `rest` points, deformed in a way of its own and with holes in every
/// third cloud; cloud 7 lies 1000 km away.
Points deformedCloud(const Points& rest, int k) {
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(0.15 * k, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  const Eigen::Vector3d shift = k == 7 ? Eigen::Vector3d(1e6, 0.0, 0.0)
                                       : Eigen::Vector3d(0.01 * k, -0.02 * k, 0.3 + 0.005 * k);
  Points cloud;
  for (const auto& p : rest) {
    Eigen::Vector3d q = p;
    q.x() *= 1.0 + 0.03 * (k % 4);
    q.z() += 2.0 * (k % 3) * q.x() * q.x();
    cloud.push_back(turn * q + shift);
  }
  if (k % 3 == 2) {
    for (std::size_t i = k; i < cloud.size(); i += 11) cloud[i].y() = std::nan("");
  }
  return cloud;
}

TEST_P(FittedCloudTest, GivesTheStatesObserveGives) {
  auto observed = sceneOnFloor(-1);
  auto fitted = sceneOnFloor(-1);
  ObjectConfig box;
  box.name = "box";
  box.kind = ObjectKind::kTracked;
  box.shape.mode = GetParam().mode;
  box.shape.clusters = GetParam().clusters;
  const Points rest = sampleBox(240, {0.05, 0.04, 0.03}, 9);
  const std::size_t o = observed->addObject(box, rest);
  Scene::PreparedObject prepared = fitted->prepareObject(box, rest);
  TrackedFitter fitter = prepared.trackedFitter();
  const std::size_t f = fitted->addObject(std::move(prepared));
  ASSERT_EQ(fitter.pointCount(), rest.size());

  // Three buffers (the cloud read, which carries its fitted points to the object, the
  // fitter's points and the body's) only change places: nothing is allocated after the
  // first cloud, and the fit holds no points of its own.
  TrackedFit fit;
  Points read(rest.size());
  std::set<const Eigen::Vector3d*> buffers;
  for (int k = 0; k < 16; ++k) {
    SCOPED_TRACE("cloud " + std::to_string(k));
    const Points cloud = deformedCloud(rest, k);
    const std::size_t holes = observed->observe(o, cloud);
    std::copy(cloud.begin(), cloud.end(), read.begin());
    EXPECT_EQ(fitter.fit(read, fit), holes);
    fitted->observeFitted(f, read, fit);
    buffers.insert({read.data(), fitted->body(f).positions().data()});
    EXPECT_EQ(fitted->body(f).positions(), observed->body(o).positions());
    for (std::size_t c = 0; c < observed->body(o).clusterCount(); ++c) {
      EXPECT_EQ(fitted->body(f).deformation(c).transform,
                observed->body(o).deformation(c).transform);
      EXPECT_EQ(fitted->body(f).deformation(c).goal_deviation_bound_m,
                observed->body(o).deformation(c).goal_deviation_bound_m);
    }
    EXPECT_EQ(fitted->body(f).centerOfMass(), observed->body(o).centerOfMass());
    observed->cycle();
    fitted->cycle();
    EXPECT_EQ(fitted->contacts().size(), observed->contacts().size());
  }
  EXPECT_LE(buffers.size(), 3u);
}

INSTANTIATE_TEST_SUITE_P(
    Modes, FittedCloudTest,
    ::testing::Values(FittedCloudCase{"rigid", DeformationMode::kRigid, 1},
                      FittedCloudCase{"linear_three_clusters", DeformationMode::kLinear, 3},
                      FittedCloudCase{"quadratic_two_clusters", DeformationMode::kQuadratic, 2}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Scene, FitsAreTakenOnlyByTheRestShapeTheyFit) {
  Scene scene(SceneConfig{});
  ObjectConfig tracked;
  tracked.name = "a";
  tracked.kind = ObjectKind::kTracked;
  const Points rest = sampleBox(100, {0.05, 0.05, 0.05}, 2);
  const std::size_t a = scene.addObject(tracked, rest);
  tracked.name = "b";
  const std::size_t b = scene.addObject(tracked, rest);
  ObjectConfig dynamic;
  dynamic.name = "ball";
  const std::size_t ball = scene.addObject(dynamic, rest);
  EXPECT_THROW(scene.trackedFitter(ball), std::invalid_argument);
  EXPECT_THROW(scene.prepareObject(dynamic, rest).trackedFitter(), std::invalid_argument);
  EXPECT_THROW(Scene::PreparedObject().trackedFitter(), std::invalid_argument);
  EXPECT_THROW(scene.trackedFitter(9), std::out_of_range);

  TrackedFitter fitter_a = scene.trackedFitter(a);
  Points cloud = rest;
  for (auto& p : cloud) p.z() += 0.1;
  Points short_cloud(rest.size() - 1, Eigen::Vector3d::Zero());
  TrackedFit fit;
  EXPECT_THROW(fitter_a.fit(short_cloud, fit), std::invalid_argument);
  EXPECT_EQ(short_cloud.size(), rest.size() - 1);
  Points read = cloud;
  fitter_a.fit(read, fit);
  EXPECT_EQ(read, cloud);

  // Object b has a's points and clusters but another rest shape; a dynamic one takes none,
  // and points of another size than the object's are refused.
  const Points b_before = scene.body(b).positions();
  const Points a_before = scene.body(a).positions();
  EXPECT_THROW(scene.observeFitted(b, read, fit), std::invalid_argument);
  EXPECT_THROW(scene.observeFitted(ball, read, fit), std::invalid_argument);
  EXPECT_THROW(scene.observeFitted(a, short_cloud, fit), std::invalid_argument);
  EXPECT_EQ(scene.body(b).positions(), b_before);
  EXPECT_EQ(scene.body(a).positions(), a_before);
  EXPECT_EQ(read, cloud);
  scene.observeFitted(a, read, fit);
  EXPECT_EQ(read, a_before);
  EXPECT_NEAR(meanPosition(scene.body(a)).z() - meanPosition(scene.body(b)).z(), 0.1, 1e-12);

  // After a reset the object's fitter is one of its new rest shape.
  read = cloud;
  fitter_a.fit(read, fit);
  scene.resetRestShape(a, rest);
  EXPECT_THROW(scene.observeFitted(a, read, fit), std::invalid_argument);
  TrackedFitter renewed = scene.trackedFitter(a);
  read = cloud;
  renewed.fit(read, fit);
  scene.observeFitted(a, read, fit);
  EXPECT_EQ(scene.body(a).positions(), cloud);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
