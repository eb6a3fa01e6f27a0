// Steady-state cycles and registrations allocate nothing. This binary replaces the global
// allocation functions to count, so it holds these tests alone: every other test keeps the
// standard ones.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"

namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  if (counting) ++allocations;
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

// Libraries may call malloc directly (a kd-tree's node pool, say): with glibc the binary's
// own malloc, calloc and realloc take every such call. Under AddressSanitizer, which owns
// them, only operator new is counted.
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DEFORMABLE_COLLISION_SANITIZED_MALLOC
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define DEFORMABLE_COLLISION_SANITIZED_MALLOC
#endif
#if defined(__GLIBC__) && !defined(DEFORMABLE_COLLISION_SANITIZED_MALLOC)
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* malloc(std::size_t size) {
  if (counting) ++allocations;
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  if (counting) ++allocations;
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) {
  if (counting) ++allocations;
  return __libc_realloc(p, size);
}
}
#endif

namespace deformable_collision {
namespace {

/// A tracked box of `mode` in `clusters` clusters.
ObjectConfig trackedBox(DeformationMode mode, int clusters) {
  ObjectConfig box;
  box.name = "box";
  box.kind = ObjectKind::kTracked;
  box.shape.mode = mode;
  box.shape.clusters = clusters;
  return box;
}

/// The gripper scene, driven cycle by cycle.
struct DrivenGripper {
  std::unique_ptr<Scene> scene = makeDemoScene(DemoScene::kGripper, 3000);
  int cycle = 0;
  void step() {
    driveDemoScene(DemoScene::kGripper, *scene, cycle++ * scene->config().dt_s);
    scene->cycle();
  }
};

// A steady state with every kind of work: a fruit held by two kinematic jaws (posed each
// cycle) on a static floor. (In three_objects the bar balanced on the ball may fall off
// late, a new contact whose scratch grows once.)
TEST(Scene, SteadyStateCyclesAllocateNothing) {
  DrivenGripper gripper;
  while (gripper.cycle < 300) gripper.step();  // the jaws closed at 2 s
  allocations = 0;
  counting = true;
  for (int steady = 0; steady < 20; ++steady) gripper.step();
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_GT(gripper.scene->stats().contacts, 0u) << "the jaws must hold the fruit";
}

// A node that applies clouds while its cycle waits detects them then: the detection ahead
// and the cycle that keeps its contacts allocate nothing either.
TEST(Scene, SteadyCyclesDetectedAheadAllocateNothing) {
  DrivenGripper gripper;
  while (gripper.cycle < 300) gripper.step();
  Scene& scene = *gripper.scene;
  const auto step_detected_ahead = [&] {
    driveDemoScene(DemoScene::kGripper, scene, gripper.cycle++ * scene.config().dt_s);
    scene.detectAhead();
    scene.cycle();
  };
  for (int warm = 0; warm < 20; ++warm) step_detected_ahead();
  allocations = 0;
  counting = true;
  for (int steady = 0; steady < 20; ++steady) step_detected_ahead();
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_GT(scene.stats().detection_ahead_ms, 0.0);
  EXPECT_GT(scene.stats().contacts, 0u) << "the jaws must hold the fruit";
}

// In budget mode each cycle also takes its cost into the level's estimate and picks the next
// level: steady cycles still allocate nothing. (Changing levels is not a steady state: the
// contacts of the squeezed fruit grow at some levels, and their scratch with them.)
TEST(Scene, SteadyCyclesInBudgetModeAllocateNothing) {
  DrivenGripper gripper;
  while (gripper.cycle < 300) gripper.step();
  Scene& scene = *gripper.scene;
  scene.setCycleBudget(1e4);  // nothing overruns it: the cycles climb to the finest level
  const int finest = scene.maxLevel();
  for (int climb = 0; climb <= finest + 20; ++climb) gripper.step();
  ASSERT_EQ(scene.stats().level, finest);
  allocations = 0;
  counting = true;
  for (int steady = 0; steady < 20; ++steady) gripper.step();
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_TRUE(scene.stats().level_auto);
}

// A tracked box registered to clouds of its moving surface, of changing size (at most the
// first one's) and order, with noise: after the first clouds, a registration (matching,
// the kd-tree's rebuilds, the fits) and the cycle after it allocate nothing.
TEST(Scene, SteadyStateRegistrationsAllocateNothing) {
  Scene scene(SceneConfig{});
  const auto rest = sampleBox(2000, {0.05, 0.04, 0.03}, 7);
  const std::size_t object = scene.addObject(trackedBox(DeformationMode::kLinear, 4), rest);
  std::mt19937 random(11);
  std::normal_distribution<double> noise(0.0, 0.001);
  std::vector<std::vector<Eigen::Vector3d>> clouds;
  for (int frame = 0; frame < 30; ++frame) {
    const Eigen::Isometry3d motion = Eigen::Translation3d(0.002 * frame, 0.0, 0.001 * frame) *
                                     Eigen::AngleAxisd(0.01 * frame, Eigen::Vector3d::UnitZ());
    std::vector<Eigen::Vector3d> cloud;
    for (std::size_t i = frame % 3; i < rest.size(); i += 1 + frame % 3) {
      cloud.push_back(motion * rest[i] +
                      Eigen::Vector3d(noise(random), noise(random), noise(random)));
    }
    std::shuffle(cloud.begin(), cloud.end(), random);
    clouds.push_back(std::move(cloud));
  }
  for (int frame = 0; frame < 10; ++frame) {
    scene.registerCloud(object, clouds[frame]);
    scene.cycle();
  }
  int held_clouds = 0;
  allocations = 0;
  counting = true;
  for (int frame = 10; frame < 30; ++frame) {
    held_clouds += scene.registerCloud(object, clouds[frame]).held ? 1 : 0;
    scene.cycle();
  }
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_EQ(held_clouds, 0) << "every cloud shows the box: each must be registered";
}

// A tracked box whose clouds, some with holes, a fitter fits apart and the scene takes over,
// as the node's reader and cycle do: after the first clouds the fits, the takes and the
// cycles allocate nothing.
TEST(Scene, SteadyStateFittedCloudsAllocateNothing) {
  Scene scene(SceneConfig{});
  const auto rest = sampleBox(1000, {0.05, 0.04, 0.03}, 8);
  Scene::PreparedObject prepared =
      scene.prepareObject(trackedBox(DeformationMode::kQuadratic, 3), rest);
  TrackedFitter fitter = prepared.trackedFitter();
  const std::size_t object = scene.addObject(std::move(prepared));
  std::vector<std::vector<Eigen::Vector3d>> clouds;
  for (int frame = 0; frame < 30; ++frame) {
    const Eigen::Isometry3d motion = Eigen::Translation3d(0.002 * frame, 0.0, 0.001 * frame) *
                                     Eigen::AngleAxisd(0.01 * frame, Eigen::Vector3d::UnitZ());
    std::vector<Eigen::Vector3d> cloud;
    for (const auto& p : rest) cloud.push_back(motion * p);
    if (frame % 2 == 1) {
      for (std::size_t i = frame; i < cloud.size(); i += 13) cloud[i].z() = std::nan("");
    }
    clouds.push_back(std::move(cloud));
  }
  TrackedFit fit;
  std::vector<Eigen::Vector3d> read(rest.size());
  const auto fit_and_cycle = [&](int frame) {
    std::copy(clouds[frame].begin(), clouds[frame].end(), read.begin());
    fitter.fit(read, fit);
    scene.observeFitted(object, read, fit);
    scene.cycle();
  };
  for (int frame = 0; frame < 10; ++frame) fit_and_cycle(frame);
  allocations = 0;
  counting = true;
  for (int frame = 10; frame < 30; ++frame) fit_and_cycle(frame);
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_NEAR(scene.body(object).positions()[0].x(), (clouds[29][0]).x(), 1e-9);
}

}  // namespace
}  // namespace deformable_collision
