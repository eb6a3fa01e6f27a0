// Wiring of the nodelet (rostest nodelet.test): clouds in, contacts, markers, deformed
// clouds and stats out, both services, malformed input, tf, and a refused configuration.
// Every wait is on an event with a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <map>

#include <geometry_msgs/WrenchStamped.h>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/ContactSummaryArray.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/Stats.h"
#include "deformable_collision/ros/deformable_collision_node.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kNode = "/deformable_collision";
const std::vector<std::string> kObjects = {"floor", "probe", "jaw", "ball"};

/// A 0.6 m floor of two layers, top at z = 0.
Points floorPoints() { return grid(31, 31, 2, 0.02, {0.0, 0.0, -0.01}); }
/// A 0.1 m cube whose bottom is 0.01 m above the floor: closer than the contact distance.
Points probePoints() { return grid(6, 6, 6, 0.02, {-0.15, 0.0, 0.06}); }
/// The jaw in its own frame, test_jaw, which the test puts at (0.5, 0, 0.1).
Points jawPoints() { return grid(5, 5, 5, 0.02, Eigen::Vector3d::Zero()); }
const Eigen::Vector3d kJawOrigin(0.5, 0.0, 0.1);
/// A floating ball, far from everything (no gravity in the test's config).
Points ballPoints() {
  Points ball;
  for (const auto& p : grid(7, 7, 7, 0.02, {0.0, 0.0, 0.0})) {
    if (p.norm() <= 0.061) ball.push_back(p + Eigen::Vector3d(0.1, 0.1, 0.4));
  }
  return ball;
}

/// The test's tf frame of the jaw, at `origin` in the world.
geometry_msgs::TransformStamped jawFrame(const Eigen::Vector3d& origin) {
  geometry_msgs::TransformStamped frame;
  frame.header.stamp = ros::Time::now();
  frame.header.frame_id = "world";
  frame.child_frame_id = "test_jaw";
  frame.transform.translation.x = origin.x();
  frame.transform.translation.y = origin.y();
  frame.transform.translation.z = origin.z();
  frame.transform.rotation.w = 1.0;
  return frame;
}

class NodeletTest : public ::testing::Test {
 protected:
  void SetUp() override {
    tf_broadcaster_.sendTransform(jawFrame(kJawOrigin));

    for (const auto& name : kObjects) {
      inputs_[name] = handle_.advertise<PointCloud2>("/test/" + name, 10, name != "probe");
      deformed_subscribers_.push_back(
          handle_.subscribe<PointCloud2>(kNode + "/deformed/" + name, 10,
                                         boost::function<void(const PointCloud2::ConstPtr&)>(
                                             [this, name](const PointCloud2::ConstPtr& cloud) {
                                               deformed_[name].push_back(cloud);
                                             })));
    }
    contacts_subscriber_ = handle_.subscribe<ContactArray>(
        kNode + "/contacts", 10,
        boost::function<void(const ContactArray::ConstPtr&)>(
            [this](const ContactArray::ConstPtr& m) { contacts_ = m; }));
    stats_subscriber_ =
        handle_.subscribe<Stats>(kNode + "/stats", 10,
                                 boost::function<void(const Stats::ConstPtr&)>(
                                     [this](const Stats::ConstPtr& m) { stats_ = m; }));
    ASSERT_TRUE(waitFor([this] {
      for (const auto& [name, publisher] : inputs_) {
        if (publisher.getNumSubscribers() == 0) return false;
      }
      return contacts_subscriber_.getNumPublishers() > 0 &&
             stats_subscriber_.getNumPublishers() > 0;
    })) << "the nodelet did not connect";
    inputs_["floor"].publish(cloudOf(floorPoints(), "world"));
    inputs_["jaw"].publish(cloudOf(jawPoints(), "test_jaw"));
    inputs_["ball"].publish(cloudOf(ballPoints(), "world"));
    // The probe is tracked: every test starts from it touching the floor.
    inputs_["probe"].publish(cloudOf(probePoints(), "world"));
    ASSERT_TRUE(waitFor([this] {
      return stats_ && stats_->objects >= kObjects.size() && probeAt(probePoints());
    })) << "the objects did not arrive";
    ASSERT_TRUE(ros::service::waitForService(kNode + "/set_level", ros::Duration(kTimeoutS)));
    ASSERT_TRUE(ros::service::waitForService(kNode + "/get_contacts", ros::Duration(kTimeoutS)));
    SetLevel running;
    running.request.level = SetLevel::Request::RUNNING;
    ASSERT_TRUE(ros::service::call(kNode + "/set_level", running));
    ASSERT_TRUE(running.response.success) << running.response.message;
    max_level_ = running.response.max_level;
    setLevel(SetLevel::Request::FINEST);
  }

  /// Whether the last ~deformed/probe holds `points` (float32 as published).
  bool probeAt(const Points& points) {
    auto& clouds = deformed_["probe"];
    if (clouds.empty()) return false;
    Points published;
    if (!readCloudPoints(*clouds.back(), NonFinitePoints::kKeepAsNaN, 1 << 20, published).ok() ||
        published.size() != points.size()) {
      return false;
    }
    for (std::size_t i = 0; i < points.size(); ++i) {
      if ((published[i] - points[i]).norm() > 1e-5) return false;
    }
    return true;
  }

  /// Sets a level in [0, max_level_] or the finest, and waits for a cycle at it.
  void setLevel(int requested) {
    const int level = requested == SetLevel::Request::FINEST ? max_level_ : requested;
    SetLevel call;
    call.request.level = static_cast<std::int16_t>(requested);
    ASSERT_TRUE(ros::service::call(kNode + "/set_level", call));
    ASSERT_TRUE(call.response.success) << call.response.message;
    ASSERT_EQ(call.response.level, level);
    ASSERT_EQ(call.response.max_level, max_level_);
    // Contacts of a cycle at the new level.
    contacts_.reset();
    ASSERT_TRUE(waitFor([&] { return contacts_ && contacts_->level == level; }));
  }

  GetContacts getContacts(const std::string& a, const std::string& b, int level,
                          double budget_ms = 0.0) {
    GetContacts call;
    call.request.object_a = a;
    call.request.object_b = b;
    call.request.level = static_cast<std::int16_t>(level);
    call.request.budget_ms = budget_ms;
    EXPECT_TRUE(ros::service::call(kNode + "/get_contacts", call));
    return call;
  }

  ros::NodeHandle handle_;
  tf2_ros::StaticTransformBroadcaster tf_broadcaster_;
  std::map<std::string, ros::Publisher> inputs_;
  std::vector<ros::Subscriber> deformed_subscribers_;
  std::map<std::string, std::deque<PointCloud2::ConstPtr>> deformed_;
  ros::Subscriber contacts_subscriber_;
  ros::Subscriber stats_subscriber_;
  ContactArray::ConstPtr contacts_;
  Stats::ConstPtr stats_;
  int max_level_ = 0;
};

TEST_F(NodeletTest, PublishesContactsBetweenTouchingObjects) {
  ASSERT_TRUE(waitFor([this] { return contacts_ && !contacts_->contacts.empty(); }));
  EXPECT_EQ(contacts_->header.frame_id, "world");
  EXPECT_EQ(contacts_->level, max_level_);
  for (const Contact& c : contacts_->contacts) {
    const std::set<std::string> pair{c.object_a, c.object_b};
    EXPECT_EQ(pair, (std::set<std::string>{"floor", "probe"})) << "only the probe touches";
    EXPECT_GT(c.depth, 0.0);
    EXPECT_NEAR(std::hypot(c.normal.x, c.normal.y, c.normal.z), 1.0, 1e-9);
    // From b to a: up when a is the probe, which lies above the floor.
    EXPECT_GT((c.object_a == "probe" ? 1.0 : -1.0) * c.normal.z, 0.5);
    EXPECT_NEAR(c.position.z, 0.005, 0.011);
    EXPECT_EQ(c.error_bound_m, 0.0) << "the leaves' contacts are their closest point pairs";
  }
  EXPECT_GT(stats_->points, 0u);
  EXPECT_EQ(stats_->max_level, max_level_);
  EXPECT_FALSE(stats_->level_auto) << "the config has no level: auto";
  EXPECT_EQ(stats_->cycle_budget_ms, 0.0);
  // Between the probe's clouds the probe and the floor keep their contacts, unqueried.
  ASSERT_TRUE(waitFor([this] { return stats_ && stats_->object_pairs_reused > 0; }));
  EXPECT_LE(stats_->object_pairs_reused, stats_->object_pairs_tested);
}

TEST_F(NodeletTest, SetLevelAnswersGoodAndBadRequests) {
  setLevel(1);
  for (const int level : {max_level_ + 1, 32767, -3, -32768}) {
    SCOPED_TRACE(level);
    SetLevel bad;
    bad.request.level = static_cast<std::int16_t>(level);
    ASSERT_TRUE(ros::service::call(kNode + "/set_level", bad));
    EXPECT_FALSE(bad.response.success);
    EXPECT_NE(bad.response.message.find("level " + std::to_string(level) + " is outside [0, " +
                                        std::to_string(max_level_) + "]"),
              std::string::npos)
        << bad.response.message;
    EXPECT_EQ(bad.response.level, 1) << "a refused request leaves the level alone";
    EXPECT_EQ(bad.response.max_level, max_level_);
  }
  SetLevel running;
  running.request.level = SetLevel::Request::RUNNING;
  ASSERT_TRUE(ros::service::call(kNode + "/set_level", running));
  EXPECT_TRUE(running.response.success) << running.response.message;
  EXPECT_EQ(running.response.level, 1);
  EXPECT_EQ(running.response.max_level, max_level_);
  contacts_.reset();
  ASSERT_TRUE(waitFor([this] { return contacts_ != nullptr; }));
  EXPECT_EQ(contacts_->level, 1);
  setLevel(SetLevel::Request::FINEST);
}

TEST_F(NodeletTest, GetContactsNamesTheFinestAndTheRunningLevel) {
  setLevel(1);
  const GetContacts running = getContacts("probe", "floor", GetContacts::Request::RUNNING);
  ASSERT_TRUE(running.response.success) << running.response.message;
  EXPECT_EQ(running.response.level, 1);
  EXPECT_EQ(running.response.contacts.level, 1);
  EXPECT_FALSE(running.response.contacts.contacts.empty());
  const GetContacts finest = getContacts("probe", "floor", GetContacts::Request::FINEST);
  ASSERT_TRUE(finest.response.success) << finest.response.message;
  EXPECT_EQ(finest.response.level, max_level_);
  EXPECT_EQ(finest.response.contacts.level, max_level_);
  EXPECT_FALSE(finest.response.contacts.contacts.empty());
  contacts_.reset();
  ASSERT_TRUE(waitFor([this] { return contacts_ != nullptr; }));
  EXPECT_EQ(contacts_->level, 1) << "a query at the finest level changed the running level";
}

TEST_F(NodeletTest, GetContactsAnswersAtAnyLevelAndLeavesTheRunningOneAlone) {
  const GetContacts current = getContacts("probe", "floor", GetContacts::Request::RUNNING);
  ASSERT_TRUE(current.response.success) << current.response.message;
  EXPECT_EQ(current.response.contacts.level, max_level_);
  ASSERT_FALSE(current.response.contacts.contacts.empty());
  for (const Contact& c : current.response.contacts.contacts) {
    EXPECT_EQ(c.object_a, "probe");  // in the order asked for
    EXPECT_EQ(c.object_b, "floor");
  }
  // At the roots the floor's wide sphere also reaches the jaw's and the ball's.
  const GetContacts roots = getContacts("floor", "", 0);
  ASSERT_TRUE(roots.response.success) << roots.response.message;
  std::set<std::string> partners;
  for (const Contact& c : roots.response.contacts.contacts) {
    EXPECT_EQ(c.object_a, "floor");
    EXPECT_EQ(c.sphere_a, 0u);
    EXPECT_EQ(c.sphere_b, 0u);
    EXPECT_EQ(c.level, 0);
    // The roots stand for whole objects: their contacts' bounds are finite and above 0.
    EXPECT_TRUE(std::isfinite(c.error_bound_m));
    EXPECT_GT(c.error_bound_m, 0.0);
    partners.insert(c.object_b);
  }
  EXPECT_EQ(partners.size(), roots.response.contacts.contacts.size()) << "one contact per pair";
  EXPECT_EQ(partners.count("probe"), 1u);
  const GetContacts untouched = getContacts("ball", "", GetContacts::Request::FINEST);
  EXPECT_TRUE(untouched.response.success);
  EXPECT_TRUE(untouched.response.contacts.contacts.empty());

  contacts_.reset();
  ASSERT_TRUE(waitFor([this] { return contacts_ != nullptr; }));
  EXPECT_EQ(contacts_->level, max_level_) << "a query at level 0 changed the running level";

  struct BadRequest {
    std::string a, b;
    int level;
    std::string expected;
  };
  for (const BadRequest& request : {BadRequest{"nothing", "", -1, "unknown object 'nothing'"},
                                    BadRequest{"probe", "Floor", -1, "unknown object 'Floor'"},
                                    BadRequest{"", "", max_level_ + 1, "outside"},
                                    BadRequest{"", "", -3, "level -3 is outside"}}) {
    const GetContacts answer = getContacts(request.a, request.b, request.level);
    EXPECT_FALSE(answer.response.success) << request.expected;
    EXPECT_NE(answer.response.message.find(request.expected), std::string::npos)
        << answer.response.message;
  }
  EXPECT_TRUE(getContacts("", "", GetContacts::Request::RUNNING).response.success)
      << "the node goes on answering";
}

// The levels come from the node's own measurements: SetUp waits for a cycle at the finest.
TEST_F(NodeletTest, GetContactsWithABudgetAnswersAtALevelTheNodeMeasured) {
  const GetContacts ample = getContacts("probe", "floor", 0, 1e6);
  ASSERT_TRUE(ample.response.success) << ample.response.message;
  EXPECT_EQ(ample.response.level, max_level_);
  EXPECT_EQ(ample.response.contacts.level, max_level_);
  EXPECT_FALSE(ample.response.contacts.contacts.empty());
  EXPECT_NE(ample.response.message.find("the finest expected within 1e+06 ms of detection"),
            std::string::npos)
      << ample.response.message;

  const GetContacts tiny = getContacts("probe", "floor", 0, 1e-9);
  ASSERT_TRUE(tiny.response.success) << tiny.response.message;
  EXPECT_LE(tiny.response.level, max_level_);
  EXPECT_NE(tiny.response.message.find("no level is expected within 1e-09 ms of detection; this "
                                       "one is the cheapest measured"),
            std::string::npos)
      << tiny.response.message;

  const GetContacts refused = getContacts("probe", "floor", 0, -2.5);
  EXPECT_FALSE(refused.response.success);
  EXPECT_NE(refused.response.message.find("budget_ms = -2.5 must be finite and >= 0"),
            std::string::npos)
      << refused.response.message;

  contacts_.reset();
  ASSERT_TRUE(waitFor([this] { return contacts_ != nullptr; }));
  EXPECT_EQ(contacts_->level, max_level_) << "a query with a budget changed the running level";
}

TEST_F(NodeletTest, MalformedCloudsLeaveTheNodeRunningAndItsStateIntact) {
  ASSERT_TRUE(waitFor([this] { return stats_ != nullptr; }));
  const auto rejected_before = stats_->clouds_rejected;
  const auto non_finite_before = stats_->non_finite_points;
  const PointCloud2 good = cloudOf(probePoints(), "world");

  std::vector<PointCloud2> malformed;
  PointCloud2 no_z = good;
  no_z.fields.pop_back();
  malformed.push_back(no_z);
  PointCloud2 small_step = good;
  small_step.point_step = 8;
  malformed.push_back(small_step);
  PointCloud2 short_data = good;
  short_data.data.resize(short_data.data.size() / 2);
  malformed.push_back(short_data);
  PointCloud2 empty = good;
  empty.width = 0;
  empty.row_step = 0;
  empty.data.clear();
  malformed.push_back(empty);
  const Points probe = probePoints();
  malformed.push_back(cloudOf(Points(probe.begin(), probe.begin() + 10), "world"));
  PointCloud2 no_frame = good;
  no_frame.header.frame_id.clear();
  malformed.push_back(no_frame);
  PointCloud2 unknown_frame = good;  // no transform to the fixed frame: the last state stays
  unknown_frame.header.frame_id = "nowhere";
  malformed.push_back(unknown_frame);
  // One at a time: the node keeps only the newest clouds of a topic.
  for (std::size_t k = 0; k < malformed.size(); ++k) {
    inputs_["probe"].publish(malformed[k]);
    ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected == rejected_before + k + 1; }))
        << "malformed cloud " << k << " was not rejected";
  }

  // NaN points are unobserved for a tracked object: the others still register.
  Points with_nan = probePoints();
  for (std::size_t i = 0; i < with_nan.size(); i += 7) with_nan[i].x() = std::nan("");
  inputs_["probe"].publish(cloudOf(with_nan, "world"));
  ASSERT_TRUE(waitFor([&] { return stats_->non_finite_points > non_finite_before; }));
  EXPECT_EQ(stats_->clouds_rejected, rejected_before + malformed.size());

  deformed_["probe"].clear();
  ASSERT_TRUE(waitFor([this] { return !deformed_["probe"].empty(); }));
  EXPECT_TRUE(probeAt(probePoints())) << "the probe moved";
  const GetContacts answer = getContacts("probe", "floor", GetContacts::Request::FINEST);
  EXPECT_TRUE(answer.response.success);
  EXPECT_FALSE(answer.response.contacts.contacts.empty());
}

TEST_F(NodeletTest, TrackedCloudsMoveTheObjectAndItsContacts) {
  Points lifted = probePoints();
  for (auto& p : lifted) p.z() += 0.2;
  inputs_["probe"].publish(cloudOf(lifted, "world"));
  ASSERT_TRUE(waitFor([&] { return probeAt(lifted); }));
  const GetContacts answer = getContacts("probe", "", GetContacts::Request::FINEST);
  ASSERT_TRUE(answer.response.success) << answer.response.message;
  EXPECT_TRUE(answer.response.contacts.contacts.empty());
  // The cycles after the cloud query the moved probe again: it no longer touches the floor.
  contacts_.reset();
  ASSERT_TRUE(waitFor([this] { return contacts_ != nullptr; }));
  EXPECT_TRUE(contacts_->contacts.empty());
}

TEST_F(NodeletTest, TrackedObjectKeepsItsPointsWhenTheFirstCloudHasHoles) {
  // An organized depth cloud: holes (NaN) in the first frame, then filled in later ones.
  const Points hand = grid(4, 4, 4, 0.02, {0.0, -0.2, 0.3});
  Points first = hand;
  for (std::size_t i = 0; i < first.size(); i += 5) first[i].y() = std::nan("");
  ros::Publisher input = handle_.advertise<PointCloud2>("/test/hand", 10);
  std::deque<PointCloud2::ConstPtr> deformed;
  ros::Subscriber output = handle_.subscribe<PointCloud2>(
      kNode + "/deformed/hand", 10,
      boost::function<void(const PointCloud2::ConstPtr&)>(
          [&](const PointCloud2::ConstPtr& c) { deformed.push_back(c); }));
  ASSERT_TRUE(
      waitFor([&] { return input.getNumSubscribers() > 0 && output.getNumPublishers() > 0; }));
  input.publish(cloudOf(first, "world"));
  Points moved = hand;
  for (auto& p : moved) p.z() += 0.05;
  Points expected;
  for (std::size_t i = 0; i < hand.size(); ++i) {
    if (i % 5 != 0) expected.push_back(moved[i]);
  }
  ASSERT_TRUE(waitFor([&] { return !deformed.empty(); }));
  input.publish(cloudOf(moved, "world"));
  ASSERT_TRUE(waitFor([&] {
    Points published;
    if (deformed.empty() ||
        !readCloudPoints(*deformed.back(), NonFinitePoints::kDrop, 1 << 20, published).ok() ||
        published.size() != expected.size()) {
      return false;
    }
    for (std::size_t k = 0; k < expected.size(); ++k) {
      if ((published[k] - expected[k]).norm() > 1e-5) return false;
    }
    return true;
  })) << "the full cloud did not register point for point";
}

TEST_F(NodeletTest, ResetCloudsGiveANewRestShape) {
  Points smaller = ballPoints();
  smaller.resize(smaller.size() / 2);
  for (auto& p : smaller) p.z() += 0.1;
  inputs_["ball"].publish(cloudOf(smaller, "world"));
  ASSERT_TRUE(waitFor([&] {
    auto& clouds = deformed_["ball"];
    Points published;
    return !clouds.empty() &&
           readCloudPoints(*clouds.back(), NonFinitePoints::kDrop, 1 << 20, published).ok() &&
           published.size() == smaller.size() && (published[0] - smaller[0]).norm() < 1e-5;
  })) << "the ball kept its old shape";
}

TEST_F(NodeletTest, KinematicObjectFollowsItsFrame) {
  const Points local = jawPoints();
  const auto jawAt = [&](const Eigen::Vector3d& origin) {
    Points published;
    if (deformed_["jaw"].empty() ||
        !readCloudPoints(*deformed_["jaw"].back(), NonFinitePoints::kDrop, 1 << 20, published)
             .ok() ||
        published.size() != local.size()) {
      return false;
    }
    for (std::size_t i = 0; i < local.size(); ++i) {
      if ((published[i] - (local[i] + origin)).norm() > 1e-5) return false;
    }
    return true;
  };
  ASSERT_TRUE(waitFor([&] { return jawAt(kJawOrigin); }));
  // The frame moves: the object follows without a new cloud.
  const Eigen::Vector3d moved_origin = kJawOrigin + Eigen::Vector3d(0.0, 0.1, 0.02);
  tf_broadcaster_.sendTransform(jawFrame(moved_origin));
  EXPECT_TRUE(waitFor([&] { return jawAt(moved_origin); })) << "the jaw stayed where it was";
}

/// The pad: a tracked slab 1 cm off the jaw's +x face (x = 0.54 with the jaw at kJawOrigin).
Points padPoints() { return grid(3, 9, 9, 0.01, {0.56, 0.0, 0.1}); }
/// The pad as a camera sees it with the jaw pressing 5 mm into the middle of its face.
Points pressedPadPoints() {
  Points points = padPoints();
  for (auto& p : points) {
    if (p.x() < 0.551 && std::abs(p.y()) <= 0.0201 && std::abs(p.z() - 0.1) <= 0.0201) {
      p.x() += 0.005;
    }
  }
  return points;
}

// A tracked pad with contact_stiffness_n_per_m: 200 seen pressed 5 mm by the jaw: the jaw, a
// kinematic object, reads about 1 N as a force-torque sensor in its frame would
// (~wrench/jaw), and ~contact_summary reports the pair with the same force in the same cycle.
TEST_F(NodeletTest, KinematicObjectReadsItsContactForces) {
  std::vector<geometry_msgs::WrenchStamped::ConstPtr> wrenches;
  std::vector<ContactSummaryArray::ConstPtr> summaries;
  ros::Subscriber wrench_subscriber = handle_.subscribe<geometry_msgs::WrenchStamped>(
      kNode + "/wrench/jaw", 100,
      boost::function<void(const geometry_msgs::WrenchStamped::ConstPtr&)>(
          [&](const geometry_msgs::WrenchStamped::ConstPtr& m) { wrenches.push_back(m); }));
  ros::Subscriber summary_subscriber = handle_.subscribe<ContactSummaryArray>(
      kNode + "/contact_summary", 100,
      boost::function<void(const ContactSummaryArray::ConstPtr&)>(
          [&](const ContactSummaryArray::ConstPtr& m) { summaries.push_back(m); }));
  // The only test that publishes the pad: advertised once in the program.
  ros::Publisher pad = handle_.advertise<PointCloud2>("/test/pad", 10);
  ASSERT_TRUE(waitFor([&] {
    return wrench_subscriber.getNumPublishers() > 0 && summary_subscriber.getNumPublishers() > 0 &&
           pad.getNumSubscribers() > 0;
  }));
  // The pressed cloud only once the pad is seen at rest against the jaw (its first cloud the
  // rest shape, or in a repeated run the rest shape seen again): a newer cloud would replace
  // it before a cycle took it.
  const auto is_jaw_and_pad = [](const ContactSummary& p) {
    return (p.object_a == "jaw" && p.object_b == "pad") ||
           (p.object_a == "pad" && p.object_b == "jaw");
  };
  pad.publish(cloudOf(padPoints(), "world"));
  ASSERT_TRUE(waitFor([&] {
    if (summaries.empty()) return false;
    const auto& pairs = summaries.back()->pairs;
    const auto pair = std::find_if(pairs.begin(), pairs.end(), is_jaw_and_pad);
    return pair != pairs.end() && std::abs(pair->force_n.x) < 0.1;
  })) << "the pad did not come to rest against the jaw";
  wrenches.clear();
  pad.publish(cloudOf(pressedPadPoints(), "world"));
  const auto pressed = [](const geometry_msgs::WrenchStamped::ConstPtr& w) {
    return w->wrench.force.x < -0.5;
  };
  ASSERT_TRUE(waitFor([&] { return std::any_of(wrenches.begin(), wrenches.end(), pressed); }))
      << "the jaw read no force";
  const auto wrench = *std::find_if(wrenches.begin(), wrenches.end(), pressed);
  EXPECT_EQ(wrench->header.frame_id, "test_jaw");
  EXPECT_NEAR(wrench->wrench.force.x, -200.0 * 0.005, 0.2);
  ASSERT_TRUE(waitFor([&] {
    return !summaries.empty() && summaries.back()->header.stamp >= wrench->header.stamp;
  }));
  const auto same_cycle = std::find_if(summaries.begin(), summaries.end(), [&](const auto& s) {
    return s->header.stamp == wrench->header.stamp;
  });
  ASSERT_NE(same_cycle, summaries.end());
  const auto pair =
      std::find_if((*same_cycle)->pairs.begin(), (*same_cycle)->pairs.end(), is_jaw_and_pad);
  ASSERT_NE(pair, (*same_cycle)->pairs.end());
  const double sign = pair->object_a == "jaw" ? 1.0 : -1.0;
  EXPECT_GT(pair->contacts, 0u);
  EXPECT_GT(pair->area_m2, 0.0);
  // The frame is not turned: the wrench's force is the summary's, in the same axes.
  EXPECT_NEAR(sign * pair->force_n.x, wrench->wrench.force.x, 1e-9);
  EXPECT_NEAR(sign * pair->force_n.y, wrench->wrench.force.y, 1e-9);
  EXPECT_NEAR(sign * pair->force_n.z, wrench->wrench.force.z, 1e-9);
  // Pressed on its +x face, about its origin: little torque about x.
  EXPECT_LT(std::abs(wrench->wrench.torque.x), 0.01);
}

/// Spheres of one object as a client decodes ~hierarchy: centre = point, radius = scale / 2.
using DecodedSpheres = std::vector<std::pair<Eigen::Vector3d, double>>;

class MarkerTest : public NodeletTest, public ::testing::WithParamInterface<int> {};

TEST_P(MarkerTest, EveryDeformedPointLiesInASphereOfThePublishedLevel) {
  const int level = std::min(GetParam(), max_level_);
  setLevel(level);
  std::deque<visualization_msgs::MarkerArray::ConstPtr> arrays;
  ros::Subscriber markers = handle_.subscribe<visualization_msgs::MarkerArray>(
      kNode + "/hierarchy", 10,
      boost::function<void(const visualization_msgs::MarkerArray::ConstPtr&)>(
          [&](const visualization_msgs::MarkerArray::ConstPtr& m) { arrays.push_back(m); }));
  for (auto& [name, clouds] : deformed_) clouds.clear();
  // Markers and clouds of the same cycle carry the same stamp.
  visualization_msgs::MarkerArray::ConstPtr array;
  std::map<std::string, PointCloud2::ConstPtr> clouds;
  ASSERT_TRUE(waitFor([&] {
    for (auto it = arrays.rbegin(); it != arrays.rend(); ++it) {
      if ((*it)->markers.size() < 2) continue;
      const ros::Time stamp = (*it)->markers[1].header.stamp;
      clouds.clear();
      for (const auto& name : kObjects) {
        for (const auto& cloud : deformed_[name]) {
          if (cloud->header.stamp == stamp) clouds[name] = cloud;
        }
      }
      if (clouds.size() == kObjects.size()) {
        array = *it;
        return true;
      }
    }
    return false;
  })) << "no markers and clouds of one cycle";

  std::map<std::string, DecodedSpheres> spheres;
  std::size_t highlighted = 0;
  for (const auto& marker : array->markers) {
    if (marker.action != visualization_msgs::Marker::ADD) continue;
    EXPECT_EQ(marker.type, visualization_msgs::Marker::SPHERE_LIST);
    for (std::size_t k = 0; k < marker.points.size(); ++k) {
      const auto& p = marker.points[k];
      spheres[marker.ns].emplace_back(Eigen::Vector3d(p.x, p.y, p.z), marker.scale.x / 2);
      highlighted += marker.colors[k].r == 1.0f && marker.colors[k].g < 0.2f;
    }
  }
  EXPECT_GT(highlighted, 0u) << "the probe and the floor touch";
  for (const auto& name : kObjects) {
    Points points;
    ASSERT_TRUE(readCloudPoints(*clouds[name], NonFinitePoints::kDrop, 1 << 20, points).ok());
    ASSERT_FALSE(points.empty());
    const DecodedSpheres& drawn = spheres[name];
    ASSERT_FALSE(drawn.empty()) << name;
    for (const auto& point : points) {
      const bool inside = std::any_of(drawn.begin(), drawn.end(), [&](const auto& sphere) {
        return (point - sphere.first).norm() <= sphere.second;
      });
      ASSERT_TRUE(inside) << name << " at level " << level;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Levels, MarkerTest, ::testing::Values(0, 2, 255));

TEST(NodeletConfiguration, RefusesABadParameterNamingIt) {
  ros::NodeHandle bad("/refused_node");
  bad.setParam("rate_hz", -5.0);
  bad.setParam("objects", std::vector<std::string>{});
  try {
    DeformableCollisionNode node(ros::NodeHandle(), bad);
    FAIL() << "started";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rate_hz = -5"), std::string::npos) << e.what();
  }
  ros::NodeHandle empty("/no_parameters");
  EXPECT_THROW(DeformableCollisionNode(ros::NodeHandle(), empty), std::invalid_argument);
}

// A subscriber in the node's process (a nodelet in the same manager) gets the node's own
// ~contacts messages, not copies: those it holds must stay as they were published while the
// node goes on publishing, which reuses a message only once nobody holds it.
TEST(NodeInProcess, ContactsASubscriberHoldsStayAsPublished) {
  XmlRpc::XmlRpcValue params;
  params["fixed_frame"] = "world";
  params["rate_hz"] = 100;
  params["gravity_mps2"][0] = 0.0;
  params["gravity_mps2"][1] = 0.0;
  params["gravity_mps2"][2] = 0.0;
  params["contact_distance_m"] = 0.02;
  params["objects"][0]["name"] = "floor";
  params["objects"][0]["topic"] = "/in_process/floor";
  params["objects"][0]["dynamic"] = false;
  params["objects"][1]["name"] = "probe";
  params["objects"][1]["topic"] = "/in_process/probe";
  params["objects"][1]["dynamic"] = false;
  params["objects"][1]["on_cloud"] = "track";
  params["objects"][1]["mode"] = "rigid";
  ros::param::set("/in_process_node", params);
  DeformableCollisionNode node(ros::NodeHandle(), ros::NodeHandle("/in_process_node"));

  struct Received {
    ContactArray::ConstPtr held;
    ContactArray copy;
  };
  std::vector<Received> received;
  ros::NodeHandle handle;
  ros::Subscriber contacts = handle.subscribe<ContactArray>(
      "/in_process_node/contacts", 100,
      boost::function<void(const ContactArray::ConstPtr&)>([&](const ContactArray::ConstPtr& m) {
        received.push_back({m, *m});
      }));
  ros::Publisher floor = handle.advertise<PointCloud2>("/in_process/floor", 1, true);
  ros::Publisher probe = handle.advertise<PointCloud2>("/in_process/probe", 1);
  floor.publish(cloudOf(floorPoints(), "world"));
  // The probe slides along the floor, its contacts other ones in each cycle.
  const Points start = probePoints();
  constexpr std::size_t kMessages = 40;
  std::size_t sent = 0;
  ASSERT_TRUE(waitFor([&] {
    Points moved = start;
    for (auto& p : moved) p.x() += 0.003 * static_cast<double>(sent % 50);
    probe.publish(cloudOf(moved, "world"));
    ++sent;
    ros::WallDuration(0.01).sleep();
    std::size_t touching = 0;
    for (const auto& r : received) touching += !r.copy.contacts.empty();
    return touching >= kMessages;
  })) << received.size()
      << " messages, fewer than " << kMessages << " with contacts";
  std::size_t changed = 0;
  for (std::size_t i = 0; i < received.size(); ++i) {
    // The messages' generated operator== compares every field.
    EXPECT_TRUE(*received[i].held == received[i].copy) << "message " << i;
    if (i > 0 && received[i].copy.contacts != received[i - 1].copy.contacts) ++changed;
  }
  EXPECT_GT(changed, kMessages / 2) << "the contacts hardly changed: the test shows nothing";
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_nodelet");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
