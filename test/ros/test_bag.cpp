// A recording replayed (rostest bag.test): scene_bag records the gripper scene, its fruit
// and floor seen from a camera frame that circles them and its jaws on tf, recorded 0.3 s
// after the clouds, and rosbag play --clock gives it to the node, which runs on the bag's
// clock: at rate 1, at a quarter (the clouds then wait 1.2 s of wall time for tf, more than
// tf_wait_s), at 4x, and looped. Each time the fruit's clouds give ContactArrays stamped with
// them (all of them but on a loaded machine, where a cloud may be replaced by the next before
// a cycle), the contacts of each stamp are the same as at rate 1, no cloud is rejected, and
// each jump back of the clock is said once.
#include <gtest/gtest.h>
#include <rosgraph_msgs/Log.h>
#include <stdlib.h>

#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

const std::string kNode = "/deformable_collision";
/// 4 s of the gripper at 10 clouds per second (SetUp).
constexpr std::size_t kClouds = 40;
constexpr std::size_t kMostClouds = 30;
constexpr double kToleranceM = 1e-9;
/// Less than config/scene_bag.yaml's tf_wait_s = 0.5 s, more than it at a quarter of the rate.
const std::string kTfLagS = "0.3";

/// One replay's contacts, by stamp (nanoseconds of bag time).
using ContactsByStamp = std::map<std::uint64_t, std::vector<Contact>>;

/// The clouds' stamps as scene_bag writes them: from 1000 s, one in five steps of 1/50 s.
const std::set<std::uint64_t>& cloudStamps() {
  static const std::set<std::uint64_t> stamps = [] {
    std::set<std::uint64_t> made;
    for (std::size_t k = 0; k < kClouds; ++k) {
      made.insert(ros::Time(1000.0 + static_cast<double>(5 * k) * (1.0 / 50.0)).toNSec());
    }
    return made;
  }();
  return stamps;
}

std::filesystem::path executableDirectory() {
  return std::filesystem::read_symlink("/proc/self/exe").parent_path();
}

void expectSameContact(const Contact& a, const Contact& b, const std::string& where) {
  EXPECT_EQ(a.object_a, b.object_a) << where;
  EXPECT_EQ(a.object_b, b.object_b) << where;
  EXPECT_EQ(a.sphere_a, b.sphere_a) << where;
  EXPECT_EQ(a.sphere_b, b.sphere_b) << where;
  EXPECT_EQ(a.level, b.level) << where;
  EXPECT_NEAR(a.position.x, b.position.x, kToleranceM) << where;
  EXPECT_NEAR(a.position.y, b.position.y, kToleranceM) << where;
  EXPECT_NEAR(a.position.z, b.position.z, kToleranceM) << where;
  EXPECT_NEAR(a.normal.x, b.normal.x, kToleranceM) << where;
  EXPECT_NEAR(a.normal.y, b.normal.y, kToleranceM) << where;
  EXPECT_NEAR(a.normal.z, b.normal.z, kToleranceM) << where;
  EXPECT_NEAR(a.depth, b.depth, kToleranceM) << where;
}

/// `replay` has a ContactArray for most of the reference's stamps, each with the same
/// contacts. A loaded machine may coalesce a cloud with the next (the newest is taken): its
/// stamp is then missing, never wrong.
void expectSameContacts(const ContactsByStamp& reference, const ContactsByStamp& replay,
                        const std::string& name) {
  EXPECT_GE(replay.size(), kMostClouds) << name << ": most clouds give their contacts";
  for (const auto& [stamp, contacts] : replay) {
    EXPECT_EQ(cloudStamps().count(stamp), 1u) << name << ": a stamp of no cloud";
  }
  for (const auto& [stamp, contacts] : reference) {
    const auto found = replay.find(stamp);
    const std::string where = name + ", stamp " + std::to_string(stamp * 1e-9) + " s";
    if (found == replay.end()) continue;
    ASSERT_EQ(found->second.size(), contacts.size()) << where;
    for (std::size_t k = 0; k < contacts.size(); ++k) {
      expectSameContact(found->second[k], contacts[k], where);
    }
  }
}

class BagTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char directory[] = "/tmp/deformable_collision_bag_XXXXXX";
    ASSERT_NE(mkdtemp(directory), nullptr);
    directory_ = directory;
    bag_ = (directory_ / "gripper.bag").string();
    ChildProcess writer(
        {(executableDirectory() / "scene_bag").string(), bag_, "gripper", "4", "10", "0", kTfLagS});
    int status = -1;
    ASSERT_TRUE(waitFor([&] { return writer.ended(status); }));
    ASSERT_EQ(status, 0) << "scene_bag failed";
    contacts_ = handle_.subscribe<ContactArray>(
        kNode + "/contacts", 100,
        boost::function<void(const ContactArray::ConstPtr&)>(
            [this](const ContactArray::ConstPtr& m) { received_.push_back(m); }));
    stats_ = handle_.subscribe<Stats>(kNode + "/stats", 10,
                                      boost::function<void(const Stats::ConstPtr&)>(
                                          [this](const Stats::ConstPtr& m) { last_stats_ = m; }));
    log_ = handle_.subscribe<rosgraph_msgs::Log>(
        "/rosout", 100,
        boost::function<void(const rosgraph_msgs::Log::ConstPtr&)>(
            [this](const rosgraph_msgs::Log::ConstPtr& m) {
              if (m->msg.find("ROS time went back") != std::string::npos) ++jumps_logged_;
            }));
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }

  /// Plays the bag at `rate` `loops` times (more than 1: looped, then stopped once the last
  /// loop's last stamp or the next loop came) and returns each time's contacts, as many as
  /// came. wraps_ counts the loops that started again.
  std::vector<ContactsByStamp> play(const std::string& rate, int loops = 1) {
    received_.clear();
    wraps_ = 0;
    std::vector<std::string> argv = {"/usr/bin/rosbag",        "play",   "--clock", "--quiet",
                                     "--wait-for-subscribers", "--rate", rate};
    if (loops > 1) argv.push_back("--loop");
    argv.push_back(bag_);
    ChildProcess player(argv);
    EXPECT_TRUE(player.running());
    std::vector<ContactsByStamp> replays(1);
    std::size_t read = 0;
    // Each loop ends with its last stamp; a stamp earlier than the one before starts the next.
    const auto complete = [&] {
      for (; read < received_.size(); ++read) {
        const ContactArray& message = *received_[read];
        ContactsByStamp& replay = replays.back();
        if (!replay.empty() && message.header.stamp.toNSec() < replay.rbegin()->first) {
          ++wraps_;
          if (static_cast<int>(replays.size()) == loops) return true;
          replays.emplace_back();
        }
        replays.back()[message.header.stamp.toNSec()] = message.contacts;
      }
      return static_cast<int>(replays.size()) == loops &&
             replays.back().count(*cloudStamps().rbegin()) == 1;
    };
    // A single replay ends with its player, its last contacts maybe still on their way; a
    // looped one is stopped after its last loop. Missing stamps are the caller's to judge.
    bool ended = false;
    int status = 0;
    EXPECT_TRUE(waitFor(
        [&] {
          ended = ended || player.ended(status);
          return complete() || (ended && loops == 1);
        },
        120.0))
        << "rate " << rate << ": the player did not end";
    if (ended) waitFor(complete, 2.0);
    player.stop(SIGTERM);
    return replays;
  }

  ros::NodeHandle handle_;
  std::filesystem::path directory_;
  std::string bag_;
  ros::Subscriber contacts_;
  ros::Subscriber stats_;
  ros::Subscriber log_;
  std::vector<ContactArray::ConstPtr> received_;
  Stats::ConstPtr last_stats_;
  int jumps_logged_ = 0;
  int wraps_ = 0;
};

TEST_F(BagTest, EveryRateAndEveryLoopGiveTheSameContactsInBagTime) {
  // The first replay makes the objects; from the second on, each starts with them in place.
  play("4");
  const ContactsByStamp reference = play("1").front();
  ASSERT_GE(reference.size(), kMostClouds);
  std::size_t touching = 0;
  for (const auto& [stamp, contacts] : reference) touching += contacts.empty() ? 0 : 1;
  EXPECT_GT(touching, reference.size() / 2) << "the fruit rests on the floor in the jaws";
  expectSameContacts(reference, play("0.25").front(), "rate 0.25");
  expectSameContacts(reference, play("4").front(), "rate 4");
  const std::vector<ContactsByStamp> loops = play("1", 2);
  ASSERT_EQ(loops.size(), 2u);
  const int loop_wraps = wraps_;  // 1, or 2 if the second loop's last stamp was coalesced
  expectSameContacts(reference, loops[0], "loop 1");
  expectSameContacts(reference, loops[1], "loop 2");

  ASSERT_TRUE(waitFor([&] { return last_stats_ != nullptr; }));
  EXPECT_EQ(last_stats_->clouds_rejected, 0u);
  EXPECT_GE(last_stats_->clouds_received, 6 * kClouds) << "6 replays";
  // A jump back at the start of each replay after the first, and one per loop started again.
  const int jumps = 3 + 1 + loop_wraps;
  EXPECT_TRUE(waitFor([&] { return jumps_logged_ >= jumps; }, 5.0));
  EXPECT_EQ(jumps_logged_, jumps);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bag");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
