// A cycle's shape matching on several threads: the same contacts and states, bit for bit,
// as on one, for every built-in scene; a bad thread count is refused naming the key.
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/byte_digest.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {
namespace {

/// The contacts of `cycles` cycles and the final points of every object, as one digest.
std::uint64_t trajectory(DemoScene kind, std::size_t points, int threads, int cycles) {
  SceneConfig config;
  config.threads = threads;
  std::unique_ptr<Scene> scene = makeDemoScene(kind, points, config);
  ByteDigest digest;
  for (int c = 0; c < cycles; ++c) {
    driveDemoScene(kind, *scene, c * scene->config().dt_s);
    scene->cycle();
    for (const SceneContact& contact : scene->contacts()) {
      digest.add(contact.contact.node_a);
      digest.add(contact.contact.node_b);
      digest.add(contact.contact.depth_m);
    }
  }
  for (std::size_t i = 0; i < scene->objectCount(); ++i) {
    for (const auto& p : scene->body(i).positions()) digest.add(p);
  }
  return digest.value();
}

TEST(SceneThreads, GiveTheStatesOfOneThread) {
  for (const DemoScene kind : {DemoScene::kTwoObjects, DemoScene::kPile, DemoScene::kGripper}) {
    SCOPED_TRACE(toString(kind));
    // Enough points for the objects to step on the pool (Scene::kPointsWorthSharing).
    const std::uint64_t one = trajectory(kind, 40000, 1, 40);
    EXPECT_EQ(trajectory(kind, 40000, 2, 40), one);
    EXPECT_EQ(trajectory(kind, 40000, 4, 40), one);
  }
}

TEST(SceneThreads, RefuseACountOutOfRangeNamingIt) {
  SceneConfig config;
  config.threads = 0;
  try {
    Scene scene(config);
    FAIL() << "threads = 0 was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("SceneConfig.threads = 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deformable_collision
