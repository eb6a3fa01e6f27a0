// level: auto through the node (rostest level_auto.test): each cycle's level is picked to fit
// cycle_budget_ms, which every level of the test's scene fits, so the node climbs from the
// root to the leaves; ~stats and ~contacts say which level ran, SetLevel fixes a level and
// -3 returns to auto. Every wait is on an event with a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <map>
#include <string>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kNode = "/deformable_collision";
constexpr double kBudgetMs = 500.0;  ///< As in level_auto_test.yaml.

/// A 0.6 m floor of two layers, top at z = 0.
Points floorPoints() { return grid(31, 31, 2, 0.02, {0.0, 0.0, -0.01}); }
/// A 0.1 m cube whose bottom is 0.01 m above the floor: closer than the contact distance.
Points boxPoints() { return grid(6, 6, 6, 0.02, {0.0, 0.0, 0.06}); }

class LevelAutoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    stats_subscriber_ =
        handle_.subscribe<Stats>(kNode + "/stats", 10,
                                 boost::function<void(const Stats::ConstPtr&)>(
                                     [this](const Stats::ConstPtr& m) { stats_ = m; }));
    contacts_subscriber_ = handle_.subscribe<ContactArray>(
        kNode + "/contacts", 10,
        boost::function<void(const ContactArray::ConstPtr&)>(
            [this](const ContactArray::ConstPtr& m) { contacts_ = m; }));
    for (const char* name : {"floor", "box"}) {
      inputs_[name] = handle_.advertise<PointCloud2>(std::string("/test/") + name, 1, true);
    }
    ASSERT_TRUE(waitFor([this] {
      for (const auto& [name, publisher] : inputs_) {
        if (publisher.getNumSubscribers() == 0) return false;
      }
      return stats_subscriber_.getNumPublishers() > 0 &&
             contacts_subscriber_.getNumPublishers() > 0;
    })) << "the nodelet did not connect";
    inputs_["floor"].publish(cloudOf(floorPoints(), "world"));
    inputs_["box"].publish(cloudOf(boxPoints(), "world"));
    ASSERT_TRUE(waitFor([this] { return stats_ && stats_->objects == 2; }))
        << "the objects did not arrive";
    ASSERT_TRUE(ros::service::waitForService(kNode + "/set_level", ros::Duration(kTimeoutS)));
  }

  /// Calls set_level and expects it to succeed.
  SetLevel setLevel(int level) {
    SetLevel call;
    call.request.level = static_cast<std::int16_t>(level);
    EXPECT_TRUE(ros::service::call(kNode + "/set_level", call));
    EXPECT_TRUE(call.response.success) << call.response.message;
    return call;
  }

  /// Waits for ~stats and ~contacts of one cycle after this call that meet `done`.
  bool waitForCycle(const std::function<bool(const Stats&, const ContactArray&)>& done) {
    stats_.reset();
    contacts_.reset();
    return waitFor([&] {
      return stats_ && contacts_ && stats_->header.stamp == contacts_->header.stamp &&
             done(*stats_, *contacts_);
    });
  }

  ros::NodeHandle handle_;
  std::map<std::string, ros::Publisher> inputs_;
  ros::Subscriber stats_subscriber_;
  ros::Subscriber contacts_subscriber_;
  Stats::ConstPtr stats_;
  ContactArray::ConstPtr contacts_;
};

bool anyCycle(const Stats&, const ContactArray&) { return true; }

TEST_F(LevelAutoTest, ClimbsFromTheRootToTheLeavesWithinTheBudget) {
  ASSERT_TRUE(waitForCycle([](const Stats& stats, const ContactArray& contacts) {
    EXPECT_EQ(contacts.level, stats.level);
    return stats.level == stats.max_level;
  })) << "the level did not reach the leaves";
  const Stats& stats = *stats_;
  EXPECT_TRUE(stats.level_auto);
  EXPECT_EQ(stats.cycle_budget_ms, kBudgetMs);
  EXPECT_GT(stats.max_level, 1) << "a scene with levels to pick from";
  EXPECT_GT(stats.contacts, 0u);
  EXPECT_LT(stats.detection_ms + stats.response_ms, kBudgetMs);
  for (const Contact& c : contacts_->contacts) {
    EXPECT_EQ(c.error_bound_m, 0.0) << "contacts at the leaves are closest point pairs";
  }
  // Once at the leaves, auto stays there: every level fits.
  for (int cycle = 0; cycle < 10; ++cycle) {
    ASSERT_TRUE(waitForCycle(anyCycle));
    ASSERT_EQ(stats_->level, stats_->max_level) << "cycle " << cycle;
    ASSERT_TRUE(stats_->level_auto);
  }
  const SetLevel running = setLevel(SetLevel::Request::RUNNING);
  EXPECT_EQ(running.response.level, running.response.max_level);
  EXPECT_NE(running.response.message.find("picked each cycle to fit 500 ms"), std::string::npos)
      << running.response.message;
}

TEST_F(LevelAutoTest, SetLevelFixesALevelAndMinusThreeReturnsToAuto) {
  const SetLevel fixed = setLevel(1);
  EXPECT_EQ(fixed.response.level, 1);
  EXPECT_EQ(fixed.response.message.find("picked each cycle"), std::string::npos)
      << fixed.response.message;
  ASSERT_TRUE(waitForCycle([](const Stats& stats, const ContactArray& contacts) {
    return !stats.level_auto && stats.level == 1 && contacts.level == 1;
  })) << "no cycle at the fixed level";
  EXPECT_EQ(stats_->cycle_budget_ms, 0.0) << "no budget with a fixed level";
  EXPECT_GT(contacts_->contacts.size(), 0u);
  for (const Contact& c : contacts_->contacts) {
    EXPECT_GT(c.error_bound_m, 0.0) << "a contact of two spheres above the leaves is an estimate";
  }
  // A fixed level stays, where auto would climb within a few cycles.
  for (int cycle = 0; cycle < 10; ++cycle) {
    ASSERT_TRUE(waitForCycle(anyCycle));
    ASSERT_EQ(stats_->level, 1) << "cycle " << cycle;
    ASSERT_FALSE(stats_->level_auto);
  }

  const SetLevel back = setLevel(-3);
  EXPECT_NE(back.response.message.find("picked each cycle to fit 500 ms"), std::string::npos)
      << back.response.message;
  // Auto starts again from the root and climbs, two cycles a level, without ever going
  // back: every level fits.
  int previous_level = 0;
  int lowest_level = std::numeric_limits<int>::max();
  ASSERT_TRUE(waitForCycle([&](const Stats& stats, const ContactArray& contacts) {
    if (!stats.level_auto) return false;
    EXPECT_EQ(contacts.level, stats.level);
    EXPECT_GE(stats.level, previous_level);
    previous_level = stats.level;
    lowest_level = std::min<int>(lowest_level, stats.level);
    return stats.level == stats.max_level;
  })) << "auto did not climb back to the leaves";
  EXPECT_LT(lowest_level, stats_->max_level) << "no cycle of the climb was seen";
  EXPECT_EQ(stats_->cycle_budget_ms, kBudgetMs);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_level_auto");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
