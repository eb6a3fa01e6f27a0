// A cycle on several threads (shape matching, the pair queries, the response): the same
// contacts and states, bit for bit, as on one, for built-in scenes, for a grid of tracked
// objects whose pairs are partly kept and partly queried, ahead of cycles too, and for a grid
// of soft boxes on a floor; a bad thread count is refused naming the key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/byte_digest.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

/// The contacts of a cycle, their forces too.
void addContacts(const Scene& scene, ByteDigest& digest) {
  for (const SceneContact& contact : scene.contacts()) {
    digest.add(contact.object_a);
    digest.add(contact.object_b);
    digest.add(contact.contact.node_a);
    digest.add(contact.contact.node_b);
    digest.add(contact.contact.position);
    digest.add(contact.contact.depth_m);
    digest.add(contact.force_n);
  }
}

/// The points of every object.
void addPositions(const Scene& scene, ByteDigest& digest) {
  for (std::size_t i = 0; i < scene.objectCount(); ++i) {
    for (const auto& p : scene.body(i).positions()) digest.add(p);
  }
}

/// `run(threads)` on 1, 2 and 4 threads: the same digest on each. The run on one.
template <typename Run>
auto sameOnEveryCount(const Run& run) {
  const auto one = run(1);
  EXPECT_EQ(run(2).digest, one.digest);
  EXPECT_EQ(run(4).digest, one.digest);
  return one;
}

/// The contacts of `cycles` cycles and the final points of every object, as one digest.
std::uint64_t trajectory(DemoScene kind, std::size_t points, int threads, int cycles) {
  SceneConfig config;
  config.threads = threads;
  std::unique_ptr<Scene> scene = makeDemoScene(kind, points, config);
  ByteDigest digest;
  for (int c = 0; c < cycles; ++c) {
    driveDemoScene(kind, *scene, c * scene->config().dt_s);
    scene->cycle();
    addContacts(*scene, digest);
  }
  addPositions(*scene, digest);
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

/// A 7 x 7 grid of tracked boxes and ellipsoids, each touching its neighbours, on a floor,
/// with soft balls dropped on it; clouds come for a few objects at a time, some detected ahead
/// of the cycle: enough candidate pairs to share, some kept and some queried each cycle.
/// The digest of the contacts and states of `cycles` cycles, and the pairs kept and queried.
struct GridRun {
  std::uint64_t digest = 0;
  std::size_t pairs_reused = 0;
  std::size_t pairs_tested = 0;
};

GridRun trackedGrid(int level, int threads, int cycles) {
  SceneConfig config;
  config.threads = threads;
  auto scene = sceneOnFloor(level, config);
  std::vector<Points> rests;
  ObjectConfig tracked;
  tracked.kind = ObjectKind::kTracked;
  for (int i = 0; i < 49; ++i) {
    tracked.name = "tracked_" + std::to_string(i);
    const std::uint64_t seed = 40 + static_cast<std::uint64_t>(i);
    Points points = i % 3 == 0 ? sampleEllipsoid(300, {0.05, 0.05, 0.05}, seed)
                               : sampleBox(300, {0.05, 0.05, 0.05}, seed);
    const Eigen::Vector3d at(0.095 * (i % 7 - 3), 0.095 * (i / 7 - 3), 0.055);
    for (auto& p : points) p += at;
    rests.push_back(points);
    scene->addObject(tracked, points);
  }
  ObjectConfig ball;
  ball.shape.mode = DeformationMode::kQuadratic;
  ball.shape.stiffness = 0.4;
  for (int i = 0; i < 4; ++i) {
    ball.name = "ball_" + std::to_string(i);
    Points points = sampleEllipsoid(400, {0.04, 0.05, 0.04}, 90 + static_cast<std::uint64_t>(i));
    for (auto& p : points) p += Eigen::Vector3d(0.1 * i - 0.15, 0.03 * i, 0.16);
    scene->addObject(ball, points);
  }
  std::mt19937_64 rng(7);
  GridRun run;
  ByteDigest digest;
  for (int c = 0; c < cycles; ++c) {
    for (int k = 0; k < 5; ++k) {
      const std::size_t object = 1 + rng() % rests.size();
      Points observed = rests[object - 1];
      const double lift_m = 1e-4 * static_cast<double>(rng() % 20);
      for (auto& p : observed) p.z() += lift_m;
      scene->observe(object, observed);
      if (rng() % 3 == 0) scene->detectAhead();
    }
    scene->cycle();
    addContacts(*scene, digest);
    run.pairs_reused += scene->stats().object_pairs_reused;
    run.pairs_tested += scene->stats().object_pairs_tested;
  }
  addPositions(*scene, digest);
  run.digest = digest.value();
  return run;
}

TEST(SceneThreads, GiveThePairContactsOfOneThreadWhenPairsAreKept) {
  for (const int level : {-1, 3}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const GridRun one =
        sameOnEveryCount([&](int threads) { return trackedGrid(level, threads, 30); });
    // Both kinds of pair were there, and enough for the pool (Scene::kPairsWorthSharing).
    EXPECT_GT(one.pairs_reused, 30u * 20u);
    EXPECT_GT(one.pairs_tested - one.pairs_reused, 30u * 20u);
  }
}

/// A 6 x 6 grid of soft boxes dropped side by side on a floor between two walls: the boxes'
/// pairs with the floor and the walls are resolved on the pool, object by object (a box at a
/// wall has two, in order), and the pairs between neighbours have their normals measured on
/// it (from 32 pairs of each kind). The digest of the contacts and states of `cycles`
/// cycles, and the most pairs of each kind that one cycle had.
struct BoxGridRun {
  std::uint64_t digest = 0;
  std::size_t most_fixed_pairs = 0;
  std::size_t most_box_pairs = 0;
};

/// A static wall across x at `x_m`, two layers thick away from the boxes.
Points wallAt(double x_m) {
  Points wall;
  for (int j = -30; j <= 30; ++j) {
    for (int k = 0; k <= 12; ++k) {
      for (int layer = 0; layer < 2; ++layer) {
        wall.emplace_back(x_m + std::copysign(0.02 * layer, x_m), 0.01 * j, 0.01 * k);
      }
    }
  }
  return wall;
}

BoxGridRun boxGrid(int level, int threads, int cycles) {
  SceneConfig config;
  config.threads = threads;
  auto scene = sceneOnFloor(level, config);
  ObjectConfig wall;
  wall.kind = ObjectKind::kStatic;
  for (const double x_m : {-0.26, 0.26}) {
    wall.name = "wall_" + std::to_string(scene->objectCount());
    scene->addObject(wall, wallAt(x_m));
  }
  const std::uint32_t first_box = static_cast<std::uint32_t>(scene->objectCount());
  ObjectConfig box;
  box.shape.stiffness = 0.5;
  for (int i = 0; i < 36; ++i) {
    box.name = "box_" + std::to_string(i);
    box.shape.mode = i % 2 == 0 ? DeformationMode::kLinear : DeformationMode::kQuadratic;
    Points points = sampleBox(300, {0.04, 0.04, 0.04}, 70 + static_cast<std::uint64_t>(i));
    const Eigen::Vector3d at(0.085 * (i % 6 - 2.5), 0.085 * (i / 6 - 2.5), 0.045);
    for (auto& p : points) p += at;
    scene->addObject(box, points);
  }
  BoxGridRun run;
  ByteDigest digest;
  for (int c = 0; c < cycles; ++c) {
    scene->cycle();
    addContacts(*scene, digest);
    std::set<std::pair<std::uint32_t, std::uint32_t>> fixed_pairs, box_pairs;
    for (const SceneContact& contact : scene->contacts()) {
      const auto pair = std::make_pair(contact.object_a, contact.object_b);
      (contact.object_a < first_box ? fixed_pairs : box_pairs).insert(pair);
    }
    run.most_fixed_pairs = std::max(run.most_fixed_pairs, fixed_pairs.size());
    run.most_box_pairs = std::max(run.most_box_pairs, box_pairs.size());
  }
  addPositions(*scene, digest);
  run.digest = digest.value();
  return run;
}

TEST(SceneThreads, GiveTheStatesOfOneThreadForABoxGridOnAFloor) {
  for (const int level : {-1, 3}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const BoxGridRun one =
        sameOnEveryCount([&](int threads) { return boxGrid(level, threads, 40); });
    EXPECT_GE(one.most_fixed_pairs, 36u + 12u) << "every box on the floor, and 12 at the walls";
    EXPECT_GE(one.most_box_pairs, 32u);
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
}  // namespace test
}  // namespace deformable_collision
