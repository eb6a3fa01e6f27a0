// The Scene's detection: the broad phase and the query miss no close point pair and pair
// no two static objects, kept contacts are those a query finds, detections ahead leave the
// cycle only the pairs changed after them, and spheres follow deferred moves.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/scenes/shapes.h"
#include "scene_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

/// The pile scene of 3000 points; with `self_collision`, every soft object's self-contacts
/// detected too (the same objects and start: the pile sets no velocities).
std::unique_ptr<Scene> pile(bool self_collision) {
  auto scene = makeDemoScene(DemoScene::kPile, 3000);
  if (!self_collision) return scene;
  auto with_self = std::make_unique<Scene>(scene->config());
  for (std::size_t i = 0; i < scene->objectCount(); ++i) {
    ObjectConfig config = scene->objectConfig(i);
    config.self_collision = config.kind == ObjectKind::kDynamic;
    with_self->addObject(config, scene->body(i).restPositions());
  }
  return with_self;
}

// The broad phase (sweep, boxes, root spheres) and the queries together miss nothing: at the
// leaves, a settling pile's contacts cover exactly the point pairs closer than the contact
// distance of every pair of objects, walls and floor included, and with self-collision on,
// of every soft object with itself more than the rest distance apart at rest.
class LeafContactsTest : public ::testing::TestWithParam<bool> {};

TEST_P(LeafContactsTest, CoverEveryClosePointPairOfTheScene) {
  const bool self_collision = GetParam();
  auto scene = pile(self_collision);
  for (int cycle = 0; cycle < 60; ++cycle) scene->cycle();
  std::vector<SceneContact> contacts;
  scene->contactsAt(scene->maxLevel(), std::nullopt, std::nullopt, contacts);
  const double reach_squared = std::pow(scene->config().contact_distance_m, 2);
  const double rest_squared =
      std::pow(kSelfRestContactDistances * scene->config().contact_distance_m, 2);

  using ObjectPointPair = std::tuple<std::size_t, std::size_t, std::uint32_t, std::uint32_t>;
  std::set<ObjectPointPair> truth;
  for (std::size_t a = 0; a < scene->objectCount(); ++a) {
    for (std::size_t b = a; b < scene->objectCount(); ++b) {
      if (a == b && !scene->objectConfig(a).self_collision) continue;
      if (scene->objectConfig(a).kind == ObjectKind::kStatic &&
          scene->objectConfig(b).kind == ObjectKind::kStatic) {
        continue;
      }
      const Points& pa = scene->body(a).positions();
      const Points& pb = scene->body(b).positions();
      const Points& rest = scene->body(a).restPositions();
      for (std::uint32_t i = 0; i < pa.size(); ++i) {
        for (std::uint32_t j = a == b ? i + 1 : 0; j < pb.size(); ++j) {
          if ((pa[i] - pb[j]).squaredNorm() >= reach_squared) continue;
          if (a == b && (rest[i] - rest[j]).squaredNorm() <= rest_squared) continue;
          truth.emplace(a, b, i, j);
        }
      }
    }
  }
  ASSERT_GT(truth.size(), 100u) << "the pile must be touching";
  std::set<ObjectPointPair> covered;
  for (const SceneContact& c : contacts) {
    ASSERT_LE(c.object_a, c.object_b);
    const auto ordered = [&](std::uint32_t p, std::uint32_t q) {
      return c.object_a == c.object_b && q < p ? ObjectPointPair{c.object_a, c.object_b, q, p}
                                               : ObjectPointPair{c.object_a, c.object_b, p, q};
    };
    ASSERT_TRUE(truth.count(ordered(c.contact.point_a, c.contact.point_b)))
        << "a contact without a close point pair";
    const SphereTree& ta = scene->tree(c.object_a);
    const SphereTree& tb = scene->tree(c.object_b);
    const SphereNode& na = ta.node(c.contact.node_a);
    const SphereNode& nb = tb.node(c.contact.node_b);
    for (std::uint32_t s = na.first_point; s < na.first_point + na.point_count; ++s) {
      for (std::uint32_t t = nb.first_point; t < nb.first_point + nb.point_count; ++t) {
        covered.insert(ordered(ta.pointIndices()[s], tb.pointIndices()[t]));
      }
    }
  }
  std::size_t missed = 0;
  for (const auto& pair : truth) missed += covered.count(pair) == 0;
  EXPECT_EQ(missed, 0u) << "of " << truth.size() << " close point pairs";
  // Object pairs come in the order of their objects, whatever order the sweep saw them in;
  // self-contacts after them.
  const auto self_begin = std::find_if(contacts.begin(), contacts.end(), [](const SceneContact& c) {
    return c.object_a == c.object_b;
  });
  EXPECT_TRUE(std::all_of(self_begin, contacts.end(),
                          [](const SceneContact& c) { return c.object_a == c.object_b; }));
  EXPECT_TRUE(std::is_sorted(
      contacts.begin(), self_begin, [](const SceneContact& x, const SceneContact& y) {
        return std::tie(x.object_a, x.object_b) < std::tie(y.object_a, y.object_b);
      }));
}

INSTANTIATE_TEST_SUITE_P(SelfCollisionOffAndOn, LeafContactsTest, ::testing::Bool());

// Two static objects cannot move each other, so the broad phase never pairs them: neither a
// cycle nor a query at any level reports them, however much they overlap. A dynamic object
// in the same place is reported against both.
TEST(Scene, TwoStaticObjectsAreNeverReportedTouching) {
  Scene scene{SceneConfig{}};
  for (const char* name : {"wall", "shelf", "ball"}) {
    ObjectConfig object;
    object.name = name;
    object.kind = std::string(name) == "ball" ? ObjectKind::kDynamic : ObjectKind::kStatic;
    scene.addObject(object, sampleEllipsoid(300, Eigen::Vector3d(0.1, 0.1, 0.1), 3));
  }
  scene.cycle();
  std::vector<SceneContact> contacts;
  for (int level = 0; level <= scene.maxLevel(); ++level) {
    scene.contactsAt(level, std::nullopt, std::nullopt, contacts);
    bool wall_with_shelf = false, ball_with_wall = false;
    for (const auto& c : contacts) {
      const std::uint32_t ball = 2;
      wall_with_shelf |= c.object_a != ball && c.object_b != ball;
      ball_with_wall |=
          (c.object_a == ball) != (c.object_b == ball) && (c.object_a == 0 || c.object_b == 0);
    }
    EXPECT_FALSE(wall_with_shelf) << "level " << level;
    EXPECT_TRUE(ball_with_wall) << "level " << level;
  }
  for (const auto& c : scene.contacts()) EXPECT_TRUE(c.object_a == 2 || c.object_b == 2);
}

// ---------------------------------------------------------------------------------------
// A cycle keeps the contacts of a pair of objects neither of which changed since the last
// cycle instead of querying the pair again; they must be what a query finds. Four tracked
// objects in a row on the floor, each touching the next, observed at random (half the time
// at the same points: a new observation all the same); a kinematic jaw against the last one,
// posed now and then; a dynamic ball dropped on the first two, which moves every cycle;
// between cycles, queries at other levels, spheres asked for, level changes and a new rest
// shape. After every cycle, the contacts between objects the response does not move equal,
// field for field and in order, those contactsAt finds at the cycle's level.

struct ContactReuseCase {
  const char* name;
  int level;  ///< The first cycles' level; -1: the finest.
  std::uint64_t seed;
};

void PrintTo(const ContactReuseCase& c, std::ostream* os) { *os << c.name; }

class ContactReuseTest : public ::testing::TestWithParam<ContactReuseCase> {};

/// The contacts between two objects that are not dynamic, in their order.
std::vector<SceneContact> betweenFixedObjects(const Scene& scene,
                                              const std::vector<SceneContact>& contacts) {
  std::vector<SceneContact> kept;
  for (const SceneContact& c : contacts) {
    if (scene.objectConfig(c.object_a).kind != ObjectKind::kDynamic &&
        scene.objectConfig(c.object_b).kind != ObjectKind::kDynamic) {
      kept.push_back(c);
    }
  }
  return kept;
}

bool sameContact(const SceneContact& x, const SceneContact& y) {
  const SphereContact& a = x.contact;
  const SphereContact& b = y.contact;
  return x.object_a == y.object_a && x.object_b == y.object_b && a.node_a == b.node_a &&
         a.node_b == b.node_b && a.level == b.level && a.position == b.position &&
         a.normal == b.normal && a.depth_m == b.depth_m && a.error_bound_m == b.error_bound_m &&
         a.point_a == b.point_a && a.point_b == b.point_b;
}

/// The scene of ContactReuseTest: floor 0, tracked objects 1 to 4, jaw 5, ball 6.
std::unique_ptr<Scene> trackedRowOnFloor(int level, std::vector<Points>& tracked_rests) {
  auto scene = sceneOnFloor(level);
  ObjectConfig tracked;
  tracked.kind = ObjectKind::kTracked;
  for (int i = 0; i < 4; ++i) {
    tracked.name = "tracked_" + std::to_string(i);
    const std::uint64_t seed = 20 + static_cast<std::uint64_t>(i);
    Points points = i % 2 == 0 ? sampleEllipsoid(500, {0.05, 0.06, 0.05}, seed)
                               : sampleBox(500, {0.05, 0.05, 0.05}, seed);
    for (auto& p : points) p += Eigen::Vector3d(-0.15 + 0.1 * i, 0.0, 0.055);
    tracked_rests.push_back(points);
    scene->addObject(tracked, points);
  }
  ObjectConfig jaw;
  jaw.name = "jaw";
  jaw.kind = ObjectKind::kKinematic;
  scene->addObject(jaw, sampleBox(300, {0.02, 0.06, 0.06}, 30));
  scene->setPose(5, Eigen::Isometry3d(Eigen::Translation3d(0.225, 0.0, 0.065)));
  ObjectConfig ball;
  ball.name = "ball";
  ball.shape.mode = DeformationMode::kLinear;
  ball.shape.stiffness = 0.5;
  Points ball_points = sampleEllipsoid(400, {0.04, 0.04, 0.04}, 31);
  for (auto& p : ball_points) p += Eigen::Vector3d(-0.1, 0.0, 0.2);
  scene->addObject(ball, ball_points);
  return scene;
}

TEST_P(ContactReuseTest, KeptContactsAreThoseAQueryFinds) {
  const ContactReuseCase& c = GetParam();
  std::vector<Points> tracked_rests;
  auto scene = trackedRowOnFloor(c.level, tracked_rests);
  std::mt19937_64 rng(c.seed);
  const auto chance = [&](int one_in) { return rng() % one_in == 0; };
  const auto millimetres = [&] { return 1e-6 * (static_cast<double>(rng() % 2001) - 1000.0); };
  const auto offset = [&] {
    // Within a millimetre, or none at all.
    if (chance(2)) return Eigen::Vector3d::Zero().eval();
    return Eigen::Vector3d(millimetres(), millimetres(), millimetres());
  };
  std::size_t reused_pairs = 0, kept_contacts = 0, detections_ahead = 0;
  std::vector<SceneContact> queried;
  for (int cycle = 0; cycle < 60; ++cycle) {
    for (std::size_t t = 1; t <= 4; ++t) {
      if (!chance(3)) continue;
      Points observed = tracked_rests[t - 1];
      const Eigen::Vector3d shift = offset();
      for (auto& p : observed) p += shift;
      scene->observe(t, observed);
      // A node detects ahead the clouds it applied while its cycle waits; more may follow.
      if (chance(3)) {
        scene->detectAhead();
        ++detections_ahead;
      }
    }
    if (chance(4)) {
      scene->setPose(5, Eigen::Isometry3d(
                            Eigen::Translation3d(Eigen::Vector3d(0.225, 0.0, 0.065) + offset())));
    }
    const int max_level = scene->maxLevel();
    if (chance(5)) {
      scene->contactsAt(static_cast<int>(rng() % (max_level + 1)), std::nullopt, std::nullopt,
                        queried);
    }
    if (chance(5)) {
      const std::size_t object = rng() % scene->objectCount();
      scene->currentSphere(object,
                           static_cast<std::uint32_t>(rng() % scene->tree(object).nodeCount()));
    }
    if (chance(10)) scene->setLevel(static_cast<int>(rng() % (max_level + 2)) - 1);
    if (chance(15)) {
      const std::size_t t = 1 + rng() % 4;
      scene->resetRestShape(t, tracked_rests[t - 1]);
    }
    if (chance(6)) scene->detectAhead();
    scene->cycle();
    const std::vector<SceneContact> kept = betweenFixedObjects(*scene, scene->contacts());
    scene->contactsAt(scene->stats().level, std::nullopt, std::nullopt, queried);
    const std::vector<SceneContact> found = betweenFixedObjects(*scene, queried);
    ASSERT_EQ(kept.size(), found.size()) << "cycle " << cycle;
    for (std::size_t k = 0; k < kept.size(); ++k) {
      ASSERT_TRUE(sameContact(kept[k], found[k]))
          << "cycle " << cycle << ", contact " << k << " of objects " << kept[k].object_a << " and "
          << kept[k].object_b;
    }
    reused_pairs += scene->stats().object_pairs_reused;
    kept_contacts += kept.size();
  }
  // The case tested something: pairs were kept, fixed objects touched, detections ran ahead.
  EXPECT_GT(reused_pairs, 20u);
  EXPECT_GT(kept_contacts, 0u);
  EXPECT_GT(detections_ahead, 20u);
}

INSTANTIATE_TEST_SUITE_P(LevelsAndSeeds, ContactReuseTest,
                         ::testing::Values(ContactReuseCase{"Level0", 0, 1},
                                           ContactReuseCase{"Level2", 2, 2},
                                           ContactReuseCase{"Level4", 4, 3},
                                           ContactReuseCase{"Finest", -1, 4},
                                           ContactReuseCase{"FinestOtherSeed", -1, 5}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Scene, PairsOfUnchangedObjectsAreNotQueriedAgain) {
  std::vector<Points> tracked_rests;
  auto scene = trackedRowOnFloor(-1, tracked_rests);
  scene->cycle();
  scene->cycle();
  // The ball, still falling, is no candidate: no pair is queried.
  const CycleStats settled = scene->stats();
  EXPECT_GE(settled.object_pairs_reused, 8u);
  EXPECT_EQ(settled.object_pairs_reused, settled.object_pairs_tested);
  EXPECT_EQ(settled.node_pairs_tested, 0u);
  scene->observe(2, tracked_rests[1]);
  scene->cycle();
  // Tracked object 2 touches the floor and tracked objects 1 and 3: those pairs are queried.
  const CycleStats observed = scene->stats();
  EXPECT_EQ(observed.object_pairs_reused + 3, settled.object_pairs_reused);
  EXPECT_GT(observed.node_pairs_tested, 0u);
  scene->setLevel(2);
  scene->cycle();
  EXPECT_EQ(scene->stats().object_pairs_reused, 0u);
  scene->cycle();
  EXPECT_EQ(scene->stats().object_pairs_reused, settled.object_pairs_reused);
}

TEST(Scene, ADetectionAheadLeavesTheCycleThePairsChangedAfterIt) {
  // Two copies of one scene, one detecting ahead of its cycles and one not.
  std::vector<Points> tracked_rests;
  auto ahead = trackedRowOnFloor(-1, tracked_rests);
  auto in_cycle = trackedRowOnFloor(-1, tracked_rests);
  for (Scene* scene : {ahead.get(), in_cycle.get()}) {
    scene->cycle();
    scene->cycle();
  }
  const std::size_t settled_reused = in_cycle->stats().object_pairs_reused;
  ASSERT_EQ(settled_reused, in_cycle->stats().object_pairs_tested);
  const auto expect_same_contacts = [&](const char* step) {
    const CycleStats& x = ahead->stats();
    const CycleStats& y = in_cycle->stats();
    EXPECT_EQ(x.object_pairs_tested, y.object_pairs_tested) << step;
    EXPECT_GT(x.detection_ahead_ms, 0.0) << step;
    EXPECT_EQ(y.detection_ahead_ms, 0.0) << step;
    ASSERT_EQ(ahead->contacts().size(), in_cycle->contacts().size()) << step;
    for (std::size_t k = 0; k < ahead->contacts().size(); ++k) {
      EXPECT_TRUE(sameContact(ahead->contacts()[k], in_cycle->contacts()[k]))
          << step << ", contact " << k;
    }
  };

  // Object 2, observed and detected ahead: the cycle queries none of its 3 pairs (the floor,
  // objects 1 and 3) again, and reports the work done ahead as its own.
  ahead->observe(2, tracked_rests[1]);
  ahead->detectAhead();
  ahead->cycle();
  in_cycle->observe(2, tracked_rests[1]);
  in_cycle->cycle();
  EXPECT_EQ(ahead->stats().object_pairs_reused, settled_reused);
  EXPECT_EQ(in_cycle->stats().object_pairs_reused + 3, settled_reused);
  EXPECT_GT(in_cycle->stats().node_pairs_tested, 0u);
  EXPECT_EQ(ahead->stats().node_pairs_tested, in_cycle->stats().node_pairs_tested);
  EXPECT_EQ(ahead->stats().point_tests, in_cycle->stats().point_tests);
  EXPECT_EQ(ahead->stats().spheres_updated, in_cycle->stats().spheres_updated);
  expect_same_contacts("object 2 detected ahead");

  // Object 1, observed after the detection ahead: the cycle queries its 2 pairs (the floor
  // and object 2) itself, the pair with object 2 for the second time.
  ahead->observe(2, tracked_rests[1]);
  ahead->detectAhead();
  ahead->observe(1, tracked_rests[0]);
  ahead->cycle();
  in_cycle->observe(2, tracked_rests[1]);
  in_cycle->observe(1, tracked_rests[0]);
  in_cycle->cycle();
  EXPECT_EQ(ahead->stats().object_pairs_reused + 2, settled_reused);
  EXPECT_GT(ahead->stats().node_pairs_tested, in_cycle->stats().node_pairs_tested);
  expect_same_contacts("object 1 observed after");
}

// The response defers the whole-object moves of objects it does not dent to the next step:
// spheres asked for before anything reads the points must already enclose the moved points.
TEST(Scene, CurrentSpheresFollowTheResponse) {
  // Coarse contacts between two soft objects dent neither: the pile defers many moves.
  auto scene = makeDemoScene(DemoScene::kPile, 8000);
  scene->setLevel(2);
  std::size_t deferred_seen = 0;
  for (int step = 0; step < 120; ++step) {
    scene->cycle();
    if (step % 10 != 9) continue;
    for (std::size_t o = 0; o < scene->objectCount(); ++o) {
      deferred_seen += scene->body(o).hasDeferredMove() ? 1 : 0;
      const SphereTree& tree = scene->tree(o);
      std::vector<Sphere> spheres;
      for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
        spheres.push_back(scene->currentSphere(o, n));
      }
      const auto& positions = scene->body(o).positions();
      for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
        const SphereNode& node = tree.node(n);
        for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
          ASSERT_LE((positions[tree.pointIndices()[s]] - spheres[n].center).norm(),
                    spheres[n].radius * (1 + 1e-12) + 1e-15)
              << "object " << o << ", node " << n << ", cycle " << step;
        }
      }
    }
  }
  EXPECT_GT(deferred_seen, 0u) << "no deferred move to check";
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision
