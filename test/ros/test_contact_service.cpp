#include "deformable_collision/ros/contact_service.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {
namespace {

/// The squeezed gripper (every kind of object, contacts), plus a configured object that
/// has had no cloud yet.
class ContactServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = makeDemoScene(DemoScene::kGripper, 3000);
    for (int step = 0; step < 150; ++step) {
      driveDemoScene(DemoScene::kGripper, *scene_, step * scene_->config().dt_s);
      scene_->cycle();
    }
    for (std::size_t i = 0; i < scene_->objectCount(); ++i) {
      objects_.push_back({scene_->objectConfig(i).name, i});
    }
    objects_.push_back({"late", std::nullopt});
    ASSERT_FALSE(scene_->contacts().empty());
  }

  /// The answer with `detection_costs_` as what the node measured.
  GetContacts::Response ask(const std::string& a, const std::string& b, int level,
                            double budget_ms = 0.0) {
    GetContacts::Request request;
    request.object_a = a;
    request.object_b = b;
    request.level = static_cast<std::int16_t>(level);
    request.budget_ms = budget_ms;
    GetContacts::Response response;
    answerGetContacts(*scene_, detection_costs_, objects_, request, scratch_, response);
    return response;
  }

  GetDistance::Response distance(const std::string& a, const std::string& b, int level,
                                 double max_distance_m = 1.0) {
    GetDistance::Request request;
    request.object_a = a;
    request.object_b = b;
    request.level = static_cast<std::int16_t>(level);
    request.max_distance_m = max_distance_m;
    GetDistance::Response response;
    answerGetDistance(*scene_, objects_, request, response);
    return response;
  }

  std::unique_ptr<Scene> scene_;
  LevelCosts detection_costs_;
  std::vector<NamedObject> objects_;
  std::vector<SceneContact> scratch_;
};

TEST_F(ContactServiceTest, SetLevelTakesALevelInRangeOrANamedOneAndRefusesOthers) {
  const int max_level = scene_->maxLevel();
  constexpr int kUnchanged = -100;
  struct Case {
    const char* name;
    int level;
    bool success;
    int in_force;  ///< After the call; kUnchanged: the level before it.
  };
  const Case cases[] = {
      {"root", 0, true, 0},
      {"middle", max_level / 2, true, max_level / 2},
      {"running, after a level", SetLevel::Request::RUNNING, true, kUnchanged},
      {"finest", SetLevel::Request::FINEST, true, max_level},
      {"running, after finest", SetLevel::Request::RUNNING, true, max_level},
      {"leaves", max_level, true, max_level},
      {"one past the leaves", max_level + 1, false, kUnchanged},
      {"largest uint8", 255, false, kUnchanged},
      {"largest int16", 32767, false, kUnchanged},
      {"one below running", -3, false, kUnchanged},
      {"smallest int16", -32768, false, kUnchanged},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const int before = scene_->level();
    SetLevel::Request request;
    request.level = static_cast<std::int16_t>(c.level);
    SetLevel::Response response;
    answerSetLevel(*scene_, request, response);
    EXPECT_EQ(response.success, c.success);
    EXPECT_EQ(response.max_level, max_level);
    EXPECT_EQ(response.level, scene_->level());
    EXPECT_EQ(scene_->level(), c.in_force == kUnchanged ? before : c.in_force);
    if (!c.success) {
      EXPECT_NE(response.message.find("level " + std::to_string(c.level) + " is outside [0, " +
                                      std::to_string(max_level) + "]"),
                std::string::npos)
          << response.message;
      EXPECT_NE(response.message.find("-1: the finest; -2: the running one"), std::string::npos)
          << response.message;
    }
  }
}

TEST_F(ContactServiceTest, SetLevelFinestIsTheFinestOfTheConfig) {
  scene_->setLevel(1);
  SetLevel::Request request;
  request.level = SetLevel::Request::FINEST;
  SetLevel::Response response;
  answerSetLevel(*scene_, request, response);
  ASSERT_TRUE(response.success) << response.message;
  // As `level: -1` in the config: the finest also of objects whose trees come later.
  EXPECT_EQ(scene_->config().level, -1);
  EXPECT_EQ(response.level, scene_->maxLevel());
}

TEST_F(ContactServiceTest, SetLevelAutoEntersBudgetModeWithTheConfiguredBudget) {
  SetLevel::Request request;
  request.level = static_cast<std::int16_t>(kAutoLevel);
  SetLevel::Response response;
  answerSetLevel(*scene_, request, response);
  EXPECT_FALSE(response.success);
  EXPECT_NE(response.message.find("-3 (auto) needs level: auto and cycle_budget_ms"),
            std::string::npos)
      << response.message;
  EXPECT_FALSE(scene_->cycleBudget());

  scene_->setLevel(2);
  answerSetLevel(*scene_, request, response, 4.5);
  ASSERT_TRUE(response.success) << response.message;
  EXPECT_EQ(scene_->cycleBudget(), 4.5);
  EXPECT_EQ(response.level, 0);  // budget mode starts from the coarsest level
  EXPECT_NE(response.message.find("picked each cycle to fit 4.5 ms"), std::string::npos)
      << response.message;

  request.level = SetLevel::Request::RUNNING;  // only answers: the budget stays
  answerSetLevel(*scene_, request, response, 4.5);
  ASSERT_TRUE(response.success);
  EXPECT_EQ(scene_->cycleBudget(), 4.5);

  request.level = 3;  // a number leaves budget mode
  answerSetLevel(*scene_, request, response, 4.5);
  ASSERT_TRUE(response.success);
  EXPECT_FALSE(scene_->cycleBudget());
  EXPECT_EQ(scene_->level(), 3);

  request.level = static_cast<std::int16_t>(scene_->maxLevel() + 1);
  answerSetLevel(*scene_, request, response, 4.5);
  EXPECT_FALSE(response.success);
  EXPECT_NE(response.message.find("; -3: auto"), std::string::npos) << response.message;
}

TEST(ContactService, SetLevelOnAnEmptySceneSaysWhy) {
  Scene scene{SceneConfig{}};
  SetLevel::Request request;
  SetLevel::Response response;
  answerSetLevel(scene, request, response);
  EXPECT_FALSE(response.success);
  EXPECT_NE(response.message.find("publish clouds first"), std::string::npos);
}

TEST_F(ContactServiceTest, GetContactsAtANamedLevelAnswersAtThatLevel) {
  scene_->setLevel(1);
  ASSERT_LT(1, scene_->maxLevel());
  struct Case {
    const char* name;
    int requested;
    int level;
  };
  const Case cases[] = {{"running", GetContacts::Request::RUNNING, 1},
                        {"finest", GetContacts::Request::FINEST, scene_->maxLevel()}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    // The state has moved on since the cycle found its contacts (the response pushed the
    // objects apart), so the answer is compared with an explicit query, not contacts().
    const GetContacts::Response named = ask("", "", c.requested);
    const GetContacts::Response explicit_level = ask("", "", c.level);
    ASSERT_TRUE(named.success) << named.message;
    EXPECT_EQ(named.level, c.level);
    EXPECT_EQ(named.contacts.level, c.level);
    EXPECT_FALSE(named.contacts.contacts.empty());
    EXPECT_EQ(named.contacts.contacts, explicit_level.contacts.contacts);
    std::vector<SceneContact> core;
    scene_->contactsAt(c.level, std::nullopt, std::nullopt, core);
    ASSERT_EQ(named.contacts.contacts.size(), core.size());
    for (std::size_t k = 0; k < core.size(); ++k) {
      const Contact& contact = named.contacts.contacts[k];
      EXPECT_NEAR(std::hypot(contact.normal.x, contact.normal.y, contact.normal.z), 1.0, 1e-9);
      EXPECT_TRUE(std::isfinite(contact.depth));
      // The core's bound, carried as it is: 0 at the leaves, a sphere's radius or more above.
      EXPECT_EQ(contact.error_bound_m, core[k].contact.error_bound_m);
      EXPECT_TRUE(std::isfinite(contact.error_bound_m));
      // The force, the last cycle's pair force shared among these contacts, carried as is.
      EXPECT_EQ(contact.force_n.x, core[k].force_n.x());
      EXPECT_EQ(contact.force_n.y, core[k].force_n.y());
      EXPECT_EQ(contact.force_n.z, core[k].force_n.z());
      EXPECT_EQ(contact.force_error_n, core[k].force_error_n);
      EXPECT_EQ(contact.registration_error_m, core[k].registration_error_m);
      if (core[k].contact.point_a != SphereContact::kNoPoint) {
        EXPECT_EQ(contact.error_bound_m, 0.0);
      } else {
        EXPECT_GE(contact.error_bound_m,
                  scene_->currentSphere(core[k].object_a, core[k].contact.node_a).radius);
      }
    }
    EXPECT_EQ(scene_->level(), 1);
  }
}

TEST_F(ContactServiceTest, GetContactsOfOneObjectAtAnotherLevelLeavesTheRunningLevel) {
  const int running = scene_->level();
  for (int level = 0; level <= scene_->maxLevel(); ++level) {
    SCOPED_TRACE(level);
    const GetContacts::Response response = ask("fruit", "", level);
    ASSERT_TRUE(response.success) << response.message;
    EXPECT_EQ(response.contacts.level, level);
    EXPECT_FALSE(response.contacts.contacts.empty());
    for (const Contact& contact : response.contacts.contacts) {
      EXPECT_TRUE(contact.object_a == "fruit" || contact.object_b == "fruit");
      EXPECT_LE(contact.level, level);  // The deeper node's level; shallow trees end above.
    }
    EXPECT_EQ(scene_->level(), running);
  }
}

TEST_F(ContactServiceTest, GetContactsRefusesBadRequestsSayingWhy) {
  const int max_level = scene_->maxLevel();
  const double kNaN = std::numeric_limits<double>::quiet_NaN();
  const double kInf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* name;
    std::string a, b;
    int level;
    double budget_ms;
    const char* says;
  };
  const Case cases[] = {
      {"unknown a", "plum", "", -1, 0.0, "unknown object 'plum'; the objects are: "},
      {"unknown b", "fruit", "Fruit", -1, 0.0, "unknown object 'Fruit'"},
      {"level below running", "", "", -3, 0.0, "level -3 is outside [0, "},
      {"level past the leaves", "", "", max_level + 1, 0.0, "-1: the finest; -2: the running one)"},
      {"largest int16", "", "", 32767, 0.0, "level 32767 is outside"},
      {"smallest int16", "", "", -32768, 0.0, "level -32768 is outside"},
      {"negative budget", "", "", 0, -1.0, "budget_ms = -1 must be finite and >= 0"},
      {"NaN budget", "", "", 0, kNaN, "budget_ms = nan must be finite"},
      {"infinite budget", "", "", 0, kInf, "budget_ms = inf must be finite"},
      {"budget of minus infinity", "", "", 0, -kInf, "budget_ms = -inf must be finite"},
  };
  // A level is known for any budget: only the budget's value can make it a bad request.
  detection_costs_ = LevelCosts(max_level);
  detection_costs_.record(0, 0.1);
  scene_->setLevel(1);
  const std::size_t cycle_contacts = scene_->contacts().size();
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const GetContacts::Response response = ask(c.a, c.b, c.level, c.budget_ms);
    EXPECT_FALSE(response.success);
    EXPECT_TRUE(response.contacts.contacts.empty());
    EXPECT_NE(response.message.find(c.says), std::string::npos) << response.message;
    EXPECT_EQ(scene_->level(), 1);
    EXPECT_FALSE(scene_->cycleBudget());
    EXPECT_EQ(scene_->contacts().size(), cycle_contacts);
  }
}

TEST_F(ContactServiceTest, GetContactsWithABudgetAnswersAtTheFinestLevelExpectedWithinIt) {
  const int max_level = scene_->maxLevel();
  ASSERT_GT(max_level, 4);
  // Detection ms as if measured by the node's cycles: not monotone (level 2 cheaper than
  // level 1), levels 4 to max_level - 1 never run.
  LevelCosts measured(max_level);
  for (const auto& [level, cost_ms] :
       {std::pair{0, 0.1}, {1, 0.3}, {2, 0.2}, {3, 0.9}, {max_level, 2.0}}) {
    measured.record(level, cost_ms);
  }
  struct Case {
    const char* name;
    bool measured;  ///< false: no cycle has run.
    std::string a;
    int level;  ///< Not read with a budget.
    double budget_ms;
    int answered_at;
    std::string says;
  };
  const Case cases[] = {
      {"within", true, "", 0, 0.5, 2, ", the finest expected within 0.5 ms of detection (0.2 ms)"},
      {"of one object", true, "fruit", 0, 0.5, 2, ", the finest expected within 0.5 ms"},
      {"the leaves", true, "", 0, 5.0, max_level, "within 5 ms of detection (2 ms)"},
      {"level not read", true, "", 32767, 1.0, 3, "within 1 ms of detection (0.9 ms)"},
      {"none fits", true, "", 0, 0.05, 0,
       ": no level is expected within 0.05 ms of detection; this one is the cheapest measured "
       "(0.1 ms)"},
      {"none measured", false, "", max_level, 1.0, 0,
       ": no level's detection has been measured yet (no cycle has run), so the coarsest"},
  };
  scene_->setLevel(1);
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    detection_costs_ = c.measured ? measured : LevelCosts();
    const GetContacts::Response response = ask(c.a, "", c.level, c.budget_ms);
    ASSERT_TRUE(response.success) << response.message;
    EXPECT_EQ(response.level, c.answered_at);
    EXPECT_EQ(response.contacts.level, c.answered_at);
    EXPECT_EQ(response.message.rfind(std::to_string(response.contacts.contacts.size()) +
                                         " contacts at level " + std::to_string(c.answered_at),
                                     0),
              0u)
        << response.message;
    EXPECT_NE(response.message.find(c.says), std::string::npos) << response.message;
    EXPECT_EQ(response.contacts.contacts, ask(c.a, "", c.answered_at).contacts.contacts);
    EXPECT_EQ(scene_->level(), 1);
  }
}

TEST_F(ContactServiceTest, GetContactsOfAnObjectWithoutACloudIsEmptyAndSaysSo) {
  const GetContacts::Response response = ask("fruit", "late", 0);
  EXPECT_TRUE(response.success);
  EXPECT_TRUE(response.contacts.contacts.empty());
  EXPECT_NE(response.message.find("'late' has had no valid cloud yet"), std::string::npos)
      << response.message;
}

TEST_F(ContactServiceTest, GetDistanceAnswersTheClosestPointsAtTheLevelAskedFor) {
  const int finest = scene_->maxLevel();
  const GetDistance::Response exact = distance("floor", "jaw_left", GetDistance::Request::FINEST);
  ASSERT_TRUE(exact.success) << exact.message;
  ASSERT_TRUE(exact.distance.found) << exact.message;
  EXPECT_EQ(exact.distance.level, finest);
  EXPECT_EQ(exact.distance.error_bound_m, 0.0);
  const Eigen::Vector3d a(exact.distance.point_a.x, exact.distance.point_a.y,
                          exact.distance.point_a.z);
  const Eigen::Vector3d b(exact.distance.point_b.x, exact.distance.point_b.y,
                          exact.distance.point_b.z);
  EXPECT_NEAR((a - b).norm(), exact.distance.distance_m, 1e-12);
  EXPECT_NE(exact.message.find("(exact)"), std::string::npos) << exact.message;
  const GetDistance::Response coarse = distance("floor", "jaw_left", 1);
  ASSERT_TRUE(coarse.distance.found) << coarse.message;
  EXPECT_EQ(coarse.distance.level, 1);
  EXPECT_LE(coarse.distance.distance_m, exact.distance.distance_m);
  EXPECT_GE(coarse.distance.distance_m + coarse.distance.error_bound_m, exact.distance.distance_m);
  const GetDistance::Response running =
      distance("jaw_left", "floor", GetDistance::Request::RUNNING);
  EXPECT_EQ(running.distance.level, scene_->level());
  EXPECT_EQ(scene_->level(), finest) << "the running level stays";
}

TEST_F(ContactServiceTest, GetDistanceBeyondTheMaximumIsNotFound) {
  const double exact =
      distance("floor", "jaw_left", GetDistance::Request::FINEST).distance.distance_m;
  const GetDistance::Response response =
      distance("floor", "jaw_left", GetDistance::Request::FINEST, 0.5 * exact);
  EXPECT_TRUE(response.success);
  EXPECT_FALSE(response.distance.found);
  EXPECT_NE(response.message.find("farther apart than"), std::string::npos) << response.message;
  const GetDistance::Response late = distance("fruit", "late", 0);
  EXPECT_TRUE(late.success);
  EXPECT_FALSE(late.distance.found);
  EXPECT_NE(late.message.find("'late' has had no valid cloud yet"), std::string::npos);
}

TEST_F(ContactServiceTest, GetDistanceRefusesBadRequestsSayingWhy) {
  struct Bad {
    const char* a;
    const char* b;
    int level;
    double max_distance_m;
    const char* says;
  };
  const Bad cases[] = {
      {"", "floor", -1, 1.0, "must both be named"},
      {"floor", "floor", -1, 1.0, "are both 'floor'"},
      {"floor", "ghost", -1, 1.0, "unknown object 'ghost'"},
      {"floor", "fruit", 99, 1.0, "level 99 is outside"},
      {"floor", "fruit", -3, 1.0, "level -3 is outside"},
      {"floor", "fruit", -1, -1.0, "max_distance_m = -1"},
      {"floor", "fruit", -1, std::numeric_limits<double>::infinity(), "max_distance_m = inf"},
  };
  for (const Bad& c : cases) {
    const GetDistance::Response response = distance(c.a, c.b, c.level, c.max_distance_m);
    EXPECT_FALSE(response.success) << c.says;
    EXPECT_NE(response.message.find(c.says), std::string::npos) << response.message;
  }
}

}  // namespace
}  // namespace deformable_collision
