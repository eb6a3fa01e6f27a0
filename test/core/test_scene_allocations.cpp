// Steady-state cycles and registrations allocate nothing. This binary replaces the global
// allocation functions to count, so it holds these tests alone: every other test keeps the
// standard ones.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <new>
#include <random>
#include <string>
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

/// Clouds of `rest` moved a little further each frame (back to the start every `period`
/// frames), of every first, second or third point in turn with 1 mm of noise, after the
/// points of `extra`, shuffled.
std::vector<std::vector<Eigen::Vector3d>> movingClouds(const std::vector<Eigen::Vector3d>& rest,
                                                       int frames, int period, unsigned seed,
                                                       const std::vector<Eigen::Vector3d>& extra) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0.0, 0.001);
  std::vector<std::vector<Eigen::Vector3d>> clouds;
  for (int frame = 0; frame < frames; ++frame) {
    const int pose = frame % period;
    const Eigen::Isometry3d motion = Eigen::Translation3d(0.002 * pose, 0.0, 0.001 * pose) *
                                     Eigen::AngleAxisd(0.01 * pose, Eigen::Vector3d::UnitZ());
    std::vector<Eigen::Vector3d> cloud = extra;
    for (std::size_t i = frame % 3; i < rest.size(); i += 1 + frame % 3) {
      cloud.push_back(motion * rest[i] +
                      Eigen::Vector3d(noise(random), noise(random), noise(random)));
    }
    std::shuffle(cloud.begin(), cloud.end(), random);
    clouds.push_back(std::move(cloud));
  }
  return clouds;
}

/// The allocations step(k) makes for k from `warm_up` to `end`, once step(k) for k below
/// `warm_up` has grown what it needs.
long allocationsAfterWarmUp(int warm_up, int end, const std::function<void(int)>& step) {
  for (int k = 0; k < warm_up; ++k) step(k);
  allocations = 0;
  counting = true;
  for (int k = warm_up; k < end; ++k) step(k);
  counting = false;
  return allocations.load();
}

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

// A soft U pressing its arms together: the self-collision query and response.
TEST(Scene, SteadySelfContactCyclesAllocateNothing) {
  SceneConfig config;
  config.gravity_mps2.setZero();
  Scene scene(config);
  ObjectConfig u;
  u.name = "u";
  u.shape.clusters = 6;
  u.shape.stiffness = 0.001;
  u.self_collision = true;
  const std::size_t index =
      scene.addObject(u, bentIntoU(gridBox(61, 4, 4, 0.005), 0.5 * (0.025 + 0.015)));
  std::vector<Eigen::Vector3d> velocities;
  for (const auto& p : scene.body(index).restPositions()) {
    velocities.emplace_back(0.0, p.x() < -0.01 ? (p.y() > 0.0 ? -0.2 : 0.2) : 0.0, 0.0);
  }
  scene.setVelocities(index, velocities);
  // The arms meet in cycle 7, most contacts then; they press on each other until cycle 29.
  for (int warm = 0; warm < 9; ++warm) scene.cycle();
  std::size_t contacts = 0;
  allocations = 0;
  counting = true;
  for (int steady = 0; steady < 20; ++steady) {
    scene.cycle();
    contacts += scene.stats().contacts;
  }
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_GT(contacts, 20u) << "the arms must press on each other";
}

// The same on two threads: a fruit of 40k points steps on the pool (Scene::kPointsWorthSharing),
// whose loops allocate nothing.
TEST(Scene, SteadyStateCyclesOnTwoThreadsAllocateNothing) {
  SceneConfig config;
  config.threads = 2;
  std::unique_ptr<Scene> scene = makeDemoScene(DemoScene::kGripper, 40000, config);
  int cycle = 0;
  const auto step = [&](int) {
    driveDemoScene(DemoScene::kGripper, *scene, cycle++ * scene->config().dt_s);
    scene->cycle();
  };
  EXPECT_EQ(allocationsAfterWarmUp(300, 320, step), 0);
  EXPECT_GT(scene->stats().contacts, 0u) << "the jaws must hold the fruit";
}

// Thirty-six soft boxes side by side on a floor, without gravity, on two threads: their pairs
// are queried (Scene::kPairsWorthSharing), their pairs with the floor resolved and those
// between boxes given their normals (from 32 of each), and the boxes dented (ContactResponse::
// kObjectsWorthSharing) on the pool, each thread with its own lists. Pushed half a contact
// distance apart, the boxes rest, in contact: a steady state that any compiler reaches (a
// pile still settling may grow a list at any cycle).
TEST(Scene, SteadyGridCyclesOnTwoThreadsAllocateNothing) {
  SceneConfig config;
  config.threads = 2;
  config.gravity_mps2.setZero();
  config.contact_distance_m = 0.01;
  Scene scene(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  scene.addObject(floor, gridLayers(40, 2, 0.01));
  ObjectConfig box;
  box.shape.stiffness = 0.5;
  for (int i = 0; i < 36; ++i) {
    box.name = "box_" + std::to_string(i);
    std::vector<Eigen::Vector3d> points =
        sampleBox(200, {0.02, 0.02, 0.02}, 60 + static_cast<std::uint64_t>(i));
    const Eigen::Vector3d at(0.045 * (i % 6 - 2.5), 0.045 * (i / 6 - 2.5), 0.024);
    for (auto& p : points) p += at;
    scene.addObject(box, points);
  }
  EXPECT_EQ(allocationsAfterWarmUp(200, 220, [&](int) { scene.cycle(); }), 0);
  EXPECT_GT(scene.stats().object_pairs_tested, 32u);
  EXPECT_GT(scene.stats().contacts, 0u);
}

// A ball sliding over a static floor reaches new nodes of the floor every cycle, whose slabs
// and planes are measured then: that allocates nothing either.
TEST(Scene, SlabsAndPlanesMeasuredInACycleAllocateNothing) {
  SceneConfig config;
  config.gravity_mps2 = Eigen::Vector3d(3.0, 0.0, -9.81);
  config.friction = 0.0;
  config.contact_distance_m = 0.01;
  Scene scene(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  floor.shape.mode = DeformationMode::kRigid;
  scene.addObject(floor, gridLayers(200, 2, 0.01));
  ObjectConfig ball;
  ball.name = "ball";
  std::vector<Eigen::Vector3d> points = sampleEllipsoid(2000, {0.05, 0.05, 0.05}, 3);
  for (auto& p : points) p += Eigen::Vector3d(-0.8, 0.0, 0.055);
  scene.addObject(ball, points);
  std::size_t touching_cycles = 0;
  const long made = allocationsAfterWarmUp(40, 80, [&](int) {
    scene.cycle();
    touching_cycles += scene.stats().contacts > 0;
  });
  EXPECT_EQ(made, 0);
  EXPECT_GE(touching_cycles, 70u) << "the ball must slide on the floor";
  EXPECT_GT(scene.body(1).positions()[0].x(), -0.5) << "the ball must have slid";
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
  const auto clouds = movingClouds(rest, 30, 30, 11, {});
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
  EXPECT_EQ(allocationsAfterWarmUp(10, 30, fit_and_cycle), 0);
  EXPECT_NEAR(scene.body(object).positions()[0].x(), (clouds[29][0]).x(), 1e-9);
}

// A tracked box on a floor whose clouds (of changing size and order, with noise and the
// floor under it) a fitter registers apart, as the node's reader does, with the floor's
// points near the box that the cycle gathers after each cycle left out: after the first
// clouds, the gathering, the registrations, the takes and the cycles allocate nothing.
TEST(Scene, SteadyStateRegistrationFitsAllocateNothing) {
  SceneConfig config;
  config.contact_distance_m = 0.01;
  Scene scene(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  const auto floor_points = gridLayers(41, 1, 0.01);
  scene.addObject(floor, floor_points);
  std::vector<Eigen::Vector3d> rest;
  for (const auto& p : sampleBox(2000, {0.05, 0.04, 0.03}, 9)) {
    rest.push_back(p + Eigen::Vector3d(0.0, 0.0, 0.035));
  }
  const std::size_t object = scene.addObject(trackedBox(DeformationMode::kLinear, 4), rest);
  RegistrationFitter fitter = scene.registrationFitter(object);
  // Ten poses, each seen twice more after the warm-up, so that every buffer has grown to them.
  const auto clouds =
      movingClouds(rest, 30, 10, 12, {floor_points.begin(), floor_points.begin() + 200});
  std::vector<Eigen::Vector3d> near;
  std::vector<Eigen::Vector3d> read;
  read.reserve(clouds[0].size());
  TrackedFit fit;
  int held_clouds = 0;
  std::size_t excluded = 0;
  const auto register_and_cycle = [&](int frame) {
    scene.pointsNearObject(object, near);
    fitter.setPointsNearObject(near);
    read.assign(clouds[frame].begin(), clouds[frame].end());
    const RegistrationReport report = fitter.fit(read, std::nullopt, fit);
    if (report.held) {
      ++held_clouds;
    } else {
      scene.observeRegistered(object, read, fit, report.surface_error);
    }
    excluded += report.excluded_points;
    scene.cycle();
  };
  EXPECT_EQ(allocationsAfterWarmUp(10, 30, register_and_cycle), 0);
  EXPECT_EQ(held_clouds, 0) << "every cloud shows the box: each must be registered";
  EXPECT_GT(excluded, 0u) << "the floor under the box must be left out";
}

}  // namespace
}  // namespace deformable_collision
