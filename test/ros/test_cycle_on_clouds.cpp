// cycle_on: clouds (rostest cycle_on_clouds.test): every cloud of a tracked object starts
// exactly one cycle whose outputs carry its stamp, a burst faster than rate_hz is coalesced,
// a cloud that comes while a cycle must wait is applied at once and detected before that
// cycle, and a FLOAT64 cloud far from the origin comes back as FLOAT64 with its points.
// Every wait is on an event with a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <algorithm>
#include <map>
#include <vector>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kNode = "/deformable_collision";
constexpr double kRateHz = 10.0;  // cycle_on_clouds_test.yaml
/// Probe clouds sent, one cycle each, until a cycle has taken the floor's cloud.
constexpr int kFloorAttempts = 20;
/// Rounds of three clouds tried until one fits in a cycle's wait (1 / rate_hz).
constexpr int kWaitAttempts = 5;

/// A 0.6 m floor of two layers, top at z = 0.
Points floorPoints() { return grid(31, 31, 2, 0.02, {0.0, 0.0, -0.01}); }
/// A 0.1 m cube 0.01 m above the floor, moved `shift_m` along x.
Points probePoints(double shift_m) { return grid(6, 6, 6, 0.02, {-0.15 + shift_m, 0.0, 0.06}); }

/// The mean x of the contacts' positions: the probe's clouds move it along x by their shift.
double meanX(const ContactArray& contacts) {
  double sum = 0.0;
  for (const Contact& contact : contacts.contacts) sum += contact.position.x;
  return contacts.contacts.empty() ? 0.0 : sum / static_cast<double>(contacts.contacts.size());
}

/// Spins until `messages` holds one stamped `stamp`: the last such, or null after the timeout.
template <typename Message>
boost::shared_ptr<const Message> waitForStamp(
    const std::vector<boost::shared_ptr<const Message>>& messages, const ros::Time& stamp) {
  boost::shared_ptr<const Message> found;
  waitFor([&] {
    for (const auto& message : messages) {
      if (message->header.stamp == stamp) found = message;
    }
    return found != nullptr;
  });
  return found;
}

/// The clouds' publishers, advertised once for all the tests, and the floor, published once
/// on a latched topic. The tests share the node, and a floor sent again by each test could
/// reach it at any time after that test's counts had started. A publisher advertised again
/// by each test went while the node kept its subscription: roscpp reconnected the
/// subscription to the next test's publisher by itself, and the master's late word that the
/// old one had gone then dropped the connection the test had waited for, losing the clouds
/// sent until the node connected again (a burst, the cloud of a test's start).
class InputEnvironment : public ::testing::Environment {
 public:
  void SetUp() override {
    ros::NodeHandle handle;
    floor_ = handle.advertise<PointCloud2>("/test/floor", 1, true);
    floor_.publish(cloudOf(floorPoints(), "world"));
    for (const std::string name : {"probe", "far"}) {
      inputs_[name] = handle.advertise<PointCloud2>("/test/" + name, 100);
    }
  }
  void TearDown() override {
    floor_.shutdown();
    inputs_.clear();
  }

  /// The publishers of /test/probe and /test/far, by object.
  std::map<std::string, ros::Publisher>& inputs() { return inputs_; }

 private:
  ros::Publisher floor_;
  std::map<std::string, ros::Publisher> inputs_;
};

InputEnvironment* input_environment = nullptr;  ///< Owned by gtest, set in main().

class CycleOnCloudsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    contacts_subscriber_ = handle_.subscribe<ContactArray>(
        kNode + "/contacts", 1000,
        boost::function<void(const ContactArray::ConstPtr&)>(
            [this](const ContactArray::ConstPtr& m) { contacts_.push_back(m); }));
    stats_subscriber_ =
        handle_.subscribe<Stats>(kNode + "/stats", 1000,
                                 boost::function<void(const Stats::ConstPtr&)>(
                                     [this](const Stats::ConstPtr& m) { stats_.push_back(m); }));
    far_subscriber_ = handle_.subscribe<PointCloud2>(
        kNode + "/deformed/far", 100,
        boost::function<void(const PointCloud2::ConstPtr&)>(
            [this](const PointCloud2::ConstPtr& m) { far_.push_back(m); }));
    probe_subscriber_ = handle_.subscribe<PointCloud2>(
        kNode + "/deformed/probe", 100,
        boost::function<void(const PointCloud2::ConstPtr&)>(
            [this](const PointCloud2::ConstPtr& m) { probe_.push_back(m); }));
    ASSERT_TRUE(waitFor([this] {
      for (const auto& [name, publisher] : inputs_) {
        if (publisher.getNumSubscribers() == 0) return false;
      }
      return contacts_subscriber_.getNumPublishers() > 0 &&
             stats_subscriber_.getNumPublishers() > 0 && far_subscriber_.getNumPublishers() > 0 &&
             probe_subscriber_.getNumPublishers() > 0;
    })) << "the nodelet did not connect";
    // The floor's cloud comes on its own connection and may reach the node after the probe's:
    // until a cycle has taken it, it would wait and be counted in the first test's clouds.
    // The probe touches the floor, so a cycle with contacts has it. The first probe cloud
    // sets the probe's rest shape; the last cycle here is the test's starting point.
    bool floor_taken = false;
    for (int attempt = 0; attempt < kFloorAttempts && !floor_taken; ++attempt) {
      const ContactArray::ConstPtr contacts = publishProbe(0.0, ros::Time::now());
      ASSERT_NE(contacts, nullptr) << "no cycle for the probe's cloud";
      floor_taken = !contacts->contacts.empty();
    }
    ASSERT_TRUE(floor_taken) << "no cycle took the floor's cloud";
  }

  /// Publishes a probe cloud stamped `stamp` and waits for the contacts of a cycle with it.
  ContactArray::ConstPtr publishProbe(double shift_m, const ros::Time& stamp) {
    PointCloud2 cloud = cloudOf(probePoints(shift_m), "world");
    cloud.header.stamp = stamp;
    inputs_["probe"].publish(cloud);
    return waitForContacts(stamp);
  }

  ContactArray::ConstPtr waitForContacts(const ros::Time& stamp) {
    return waitForStamp(contacts_, stamp);
  }
  Stats::ConstPtr waitForStats(const ros::Time& stamp) { return waitForStamp(stats_, stamp); }

  ros::NodeHandle handle_;
  std::map<std::string, ros::Publisher>& inputs_ = input_environment->inputs();
  ros::Subscriber contacts_subscriber_, stats_subscriber_, far_subscriber_, probe_subscriber_;
  std::vector<ContactArray::ConstPtr> contacts_;
  std::vector<Stats::ConstPtr> stats_;
  std::vector<PointCloud2::ConstPtr> far_, probe_;
};

TEST_F(CycleOnCloudsTest, EveryCloudStartsExactlyOneCycleCarryingItsStamp) {
  const Stats::ConstPtr before = waitForStats(contacts_.back()->header.stamp);
  ASSERT_NE(before, nullptr);
  const std::size_t contacts_before = contacts_.size();
  std::vector<ros::Time> stamps;
  // The last cloud's cycle also shows that no further cycle followed the others.
  for (int i = 1; i <= 11; ++i) {
    stamps.push_back(ros::Time::now());
    const ContactArray::ConstPtr contacts = publishProbe(0.001 * i, stamps.back());
    ASSERT_NE(contacts, nullptr) << "no cycle for cloud " << i;
    EXPECT_FALSE(contacts->contacts.empty()) << "the probe touches the floor";
  }
  ASSERT_EQ(contacts_.size() - contacts_before, stamps.size()) << "one cycle per cloud";
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    EXPECT_EQ(contacts_[contacts_before + i]->header.stamp, stamps[i]) << i;
  }
  const Stats::ConstPtr after = waitForStats(stamps.back());
  ASSERT_NE(after, nullptr);
  EXPECT_EQ(after->cycles - before->cycles, stamps.size());
  EXPECT_EQ(after->clouds_coalesced, before->clouds_coalesced);
  EXPECT_LE(after->overruns_from_input, after->overruns);
  // Taking the clouds is the cycle's first part, apart from the scene's stages and the
  // publication.
  for (const ros::Time& stamp : stamps) {
    const Stats::ConstPtr stats = waitForStats(stamp);
    ASSERT_NE(stats, nullptr);
    EXPECT_GT(stats->input_ms, 0.0);
    EXPECT_LE(stats->input_ms + stats->shape_matching_ms + stats->detection_ms +
                  stats->response_ms + stats->publish_ms,
              stats->cycle_ms + 1e-9);
  }
}

TEST_F(CycleOnCloudsTest, ABurstFasterThanTheRateIsCoalesced) {
  const Stats::ConstPtr before = waitForStats(contacts_.back()->header.stamp);
  ASSERT_NE(before, nullptr);
  const std::size_t contacts_before = contacts_.size();
  constexpr int kBurst = 40;
  const ros::WallTime started = ros::WallTime::now();
  ros::Time last;
  for (int i = 0; i < kBurst; ++i) {
    last = std::max(ros::Time::now(), last + ros::Duration(1e-6));
    PointCloud2 cloud = cloudOf(probePoints(0.0005 * i), "world");
    cloud.header.stamp = last;
    inputs_["probe"].publish(cloud);
  }
  ASSERT_NE(waitForContacts(last), nullptr) << "the burst's newest cloud started no cycle";
  const double elapsed_s = (ros::WallTime::now() - started).toSec();
  const Stats::ConstPtr after = waitForStats(last);
  ASSERT_NE(after, nullptr);
  const std::uint64_t cycles = after->cycles - before->cycles;
  EXPECT_EQ(contacts_.size() - contacts_before, cycles);
  EXPECT_LT(cycles, static_cast<std::uint64_t>(kBurst));
  EXPECT_LE(static_cast<double>(cycles), elapsed_s * kRateHz + 1.0) << "at most at rate_hz";
  // Each cloud the node read either started (or joined) a cycle or was replaced by a newer one.
  EXPECT_EQ(after->clouds_received - before->clouds_received,
            cycles + (after->clouds_coalesced - before->clouds_coalesced));
  EXPECT_GT(after->clouds_coalesced, before->clouds_coalesced);
  for (std::size_t i = contacts_before + 1; i < contacts_.size(); ++i) {
    EXPECT_GT(contacts_[i]->header.stamp, contacts_[i - 1]->header.stamp) << "newest cloud first";
  }
}

// Cloud 1 starts a cycle; cloud 2, sent while the next cycle must wait for rate_hz, is
// applied at once (get_contacts, answered on the cycle's thread, sees the probe moved before
// any cycle took it); cloud 3 then waits for the cycle, which applies it and carries its
// stamp, and cloud 2, applied but never a cycle's, counts as coalesced.
TEST_F(CycleOnCloudsTest, ACloudThatComesWhileACycleWaitsIsAppliedAtOnce) {
  ros::ServiceClient get_contacts = handle_.serviceClient<GetContacts>(kNode + "/get_contacts");
  ASSERT_TRUE(get_contacts.waitForExistence(ros::Duration(kTimeoutS)));
  // Two grid spacings of probe and floor: the contacts' positions move by about as much
  // (not exactly: which of the floor's leaves meet which of the probe's changes).
  constexpr double kStepM = 0.04;
  const auto moved_by = [](const ContactArray& contacts, const ContactArray& from, double shift_m) {
    return std::abs(meanX(contacts) - meanX(from) - shift_m) < 0.25 * kStepM;
  };
  bool fitted = false;
  for (int attempt = 0; attempt < kWaitAttempts && !fitted; ++attempt) {
    const ros::Time first = ros::Time::now();
    const ContactArray::ConstPtr first_contacts = publishProbe(0.0, first);
    ASSERT_NE(first_contacts, nullptr);
    ASSERT_FALSE(first_contacts->contacts.empty());
    const Stats::ConstPtr before = waitForStats(first);
    ASSERT_NE(before, nullptr);

    const ros::Time second = ros::Time::now();
    PointCloud2 cloud = cloudOf(probePoints(kStepM), "world");
    cloud.header.stamp = second;
    inputs_["probe"].publish(cloud);
    GetContacts query;
    query.request.object_a = "probe";
    query.request.object_b = "floor";
    query.request.level = GetContacts::Request::FINEST;
    ASSERT_TRUE(waitFor([&] {
      return get_contacts.call(query) && query.response.success &&
             moved_by(query.response.contacts, *first_contacts, kStepM);
    })) << "get_contacts never saw cloud 2";
    ros::spinOnce();
    const auto cycle_of = [this](const ros::Time& stamp) {
      return std::any_of(contacts_.begin(), contacts_.end(),
                         [&](const ContactArray::ConstPtr& c) { return c->header.stamp == stamp; });
    };
    // On a slow host the wait may have run out already: cloud 2 then had a cycle of its own.
    if (cycle_of(second)) continue;

    const ros::Time third = ros::Time::now();
    const ContactArray::ConstPtr third_contacts = publishProbe(2.0 * kStepM, third);
    ASSERT_NE(third_contacts, nullptr);
    if (cycle_of(second)) continue;
    fitted = true;
    EXPECT_TRUE(moved_by(*third_contacts, *first_contacts, 2.0 * kStepM))
        << meanX(*third_contacts) - meanX(*first_contacts);
    const Stats::ConstPtr after = waitForStats(third);
    ASSERT_NE(after, nullptr);
    EXPECT_EQ(after->cycles - before->cycles, 1u) << "clouds 2 and 3 in one cycle";
    EXPECT_EQ(after->clouds_received - before->clouds_received, 2u);
    EXPECT_EQ(after->clouds_coalesced - before->clouds_coalesced, 1u) << "cloud 2";
  }
  EXPECT_TRUE(fitted) << "no round of three clouds fitted in a cycle's wait of " << 1.0 / kRateHz
                      << " s";
}

TEST_F(CycleOnCloudsTest, ACloudAppliedWhileACycleWaitsIsDetectedBeforeTheCycle) {
  bool detected_ahead = false;
  for (int attempt = 0; attempt < kWaitAttempts && !detected_ahead; ++attempt) {
    const ContactArray::ConstPtr first_contacts = publishProbe(0.0, ros::Time::now());
    ASSERT_NE(first_contacts, nullptr);
    // Cloud 2 comes in the wait for rate_hz that cloud 1's cycle began.
    const ros::Time second = ros::Time::now();
    const ContactArray::ConstPtr second_contacts = publishProbe(0.02, second);
    ASSERT_NE(second_contacts, nullptr);
    const Stats::ConstPtr stats = waitForStats(second);
    ASSERT_NE(stats, nullptr);
    // On a slow host the wait may have run out already, or ended before the node was done
    // applying cloud 2: then its cycle detected it.
    if (stats->detection_ahead_ms == 0.0) continue;
    detected_ahead = true;
    // The probe's one pair, with the floor, was queried ahead: the cycle kept its contacts.
    EXPECT_EQ(stats->object_pairs_tested, 1u);
    EXPECT_EQ(stats->object_pairs_reused, 1u);
    EXPECT_GT(stats->node_pairs_tested, 0u) << "the work done ahead counts";
    EXPECT_FALSE(second_contacts->contacts.empty());
    EXPECT_GT(meanX(*second_contacts), meanX(*first_contacts));
  }
  EXPECT_TRUE(detected_ahead) << "no cloud of " << kWaitAttempts
                              << " was detected ahead of its cycle";
}

TEST_F(CycleOnCloudsTest, AFloat64CloudFarFromTheOriginComesBackFloat64Unchanged) {
  Points far = grid(5, 5, 5, 0.02, {1e5 + 0.1234567, -2.5, 0.75});
  PointCloud2 cloud;
  writeCloudPoints(far, cloud, sensor_msgs::PointField::FLOAT64);
  cloud.header.frame_id = "world";
  cloud.header.stamp = ros::Time::now();
  inputs_["far"].publish(cloud);
  const PointCloud2::ConstPtr deformed = waitForStamp(far_, cloud.header.stamp);
  ASSERT_NE(deformed, nullptr);
  for (const sensor_msgs::PointField& field : deformed->fields) {
    EXPECT_EQ(field.datatype, sensor_msgs::PointField::FLOAT64) << field.name;
  }
  Points published;
  ASSERT_TRUE(readCloudPoints(*deformed, NonFinitePoints::kKeepAsNaN, 1 << 20, published).ok());
  ASSERT_EQ(published.size(), far.size());
  for (std::size_t i = 0; i < far.size(); ++i) {
    EXPECT_LE((published[i] - far[i]).norm(), 1e-9 * far[i].norm()) << i;
  }
  // The probe's clouds are FLOAT32, and so is its output.
  ASSERT_TRUE(waitFor([&] { return !probe_.empty(); }));
  EXPECT_EQ(probe_.back()->fields[0].datatype, sensor_msgs::PointField::FLOAT32);
}

TEST_F(CycleOnCloudsTest, StatsSummariseTheLatenciesOfAPeriod) {
  const Stats::ConstPtr before = waitForStats(contacts_.back()->header.stamp);
  ASSERT_NE(before, nullptr);
  Stats::ConstPtr summary;
  double shift_m = 0.0;
  // Clouds until the node closes a latency period that holds some of them.
  ASSERT_TRUE(waitFor([&] {
    const ros::Time stamp = ros::Time::now();
    shift_m += 1e-4;
    if (!publishProbe(shift_m, stamp)) return false;
    summary = waitForStats(stamp);
    return summary && summary->latency_periods > before->latency_periods + 1 &&
           summary->latency_clouds > 0;
  }));
  EXPECT_GE(summary->latency_period_s, 1.0);
  EXPECT_GT(summary->arrival_latency_mean_ms, 0.0);
  EXPECT_LE(summary->arrival_latency_mean_ms, summary->arrival_latency_max_ms);
  EXPECT_LE(summary->arrival_latency_p99_ms, summary->arrival_latency_max_ms);
  EXPECT_GT(summary->stamp_latency_mean_ms, 0.0);
  EXPECT_LE(summary->stamp_latency_p99_ms, summary->stamp_latency_max_ms);
  // A cloud is stamped before it is sent, so it is older by its stamp than by its arrival.
  EXPECT_GE(summary->stamp_latency_max_ms, summary->arrival_latency_max_ms);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cycle_on_clouds");
  ros::NodeHandle handle;
  deformable_collision::test::input_environment = new deformable_collision::test::InputEnvironment;
  testing::AddGlobalTestEnvironment(deformable_collision::test::input_environment);
  return RUN_ALL_TESTS();
}
