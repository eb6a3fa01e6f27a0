// Steady-state cycles allocate nothing. This binary replaces the global allocation functions
// to count, so it holds this one test: every other test keeps the standard ones.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/core/scene.h"

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

namespace deformable_collision {
namespace {

// A steady state with every kind of work: a fruit held by two kinematic jaws (posed each
// cycle) on a static floor. (In three_objects the bar balanced on the ball may fall off
// late, a new contact whose scratch grows once.)
TEST(Scene, SteadyStateCyclesAllocateNothing) {
  auto scene = makeDemoScene(DemoScene::kGripper, 3000);
  int cycle = 0;
  const auto step = [&] {
    driveDemoScene(DemoScene::kGripper, *scene, cycle++ * scene->config().dt_s);
    scene->cycle();
  };
  while (cycle < 300) step();  // the jaws closed at 2 s
  allocations = 0;
  counting = true;
  for (int steady = 0; steady < 20; ++steady) step();
  counting = false;
  EXPECT_EQ(allocations.load(), 0);
  EXPECT_GT(scene->stats().contacts, 0u) << "the jaws must hold the fruit";
}

}  // namespace
}  // namespace deformable_collision
