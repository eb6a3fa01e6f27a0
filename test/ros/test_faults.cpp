// Faults the nodelet must survive (rostest faults.test): late and missing tf, clouds in a
// frame tf does not know among good ones, a publisher process killed and started again, a
// tracked cloud of another size, one with points at 1e100 m, a cloud of 10 million points, and
// services hammered from several clients at once. Each test meets its own object of
// faults_test.yaml and checks the node's ~stats and outputs; every wait is on an event with a
// timeout. The manager killed and respawned has its own rostest (manager_respawn.test), as a
// respawn would start the other cases on a new node.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <deque>
#include <filesystem>
#include <thread>
#include <vector>

#include "deformable_collision/SetLevel.h"
#include "fault_test_fixture.h"

extern char** environ;

namespace deformable_collision {
namespace test {
namespace {

constexpr double kTfWaitS = 2.0;  // faults_test.yaml
constexpr double kRateHz = 50.0;  // faults_test.yaml

/// `points` as an unorganized FLOAT64 x y z cloud in the host's byte order, which holds
/// what FLOAT32 cannot (1e100).
sensor_msgs::PointCloud2 doubleCloudOf(const Points& points, const std::string& frame) {
  sensor_msgs::PointCloud2 cloud = cloudOf(points, frame);
  for (std::uint32_t axis = 0; axis < 3; ++axis) {
    cloud.fields[axis].offset = axis * sizeof(double);
    cloud.fields[axis].datatype = sensor_msgs::PointField::FLOAT64;
  }
  cloud.point_step = 3 * sizeof(double);
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.data.resize(cloud.row_step);
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::memcpy(&cloud.data[i * cloud.point_step], points[i].data(), cloud.point_step);
  }
  return cloud;
}

/// The fault cases' client, which also reads what the node logs (/rosout).
class FaultsTest : public FaultTestFixture {
 protected:
  void SetUp() override {
    log_subscriber_ = handle_.subscribe<rosgraph_msgs::Log>(
        "/rosout", 100,
        boost::function<void(const rosgraph_msgs::Log::ConstPtr&)>(
            [this](const rosgraph_msgs::Log::ConstPtr& m) { log_.push_back(m); }));
    FaultTestFixture::SetUp();
  }

  /// Whether a line of at least `level` that names `topic` was logged. Its words are the
  /// node's to choose: the tests check what happened on ~stats and the outputs.
  bool problemLogged(std::uint8_t level, const std::string& topic) const {
    for (const auto& line : log_) {
      if (line->level >= level && line->msg.find(topic) != std::string::npos) return true;
    }
    return false;
  }

  /// A publisher on /tf that the node's listener is connected to.
  ros::Publisher tfPublisher() {
    ros::Publisher tf = handle_.advertise<tf2_msgs::TFMessage>("/tf", 2);
    EXPECT_TRUE(waitFor([&] { return tf.getNumSubscribers() > 0; }));
    return tf;
  }

  /// Poses of `frame`, 1 m above the world's origin, at each stamp.
  static tf2_msgs::TFMessage posesOf(const std::string& frame,
                                     const std::vector<ros::Time>& stamps) {
    tf2_msgs::TFMessage poses;
    for (const ros::Time& stamp : stamps) {
      geometry_msgs::TransformStamped pose;
      pose.header.stamp = stamp;
      pose.header.frame_id = "world";
      pose.child_frame_id = frame;
      pose.transform.translation.z = 1.0;
      pose.transform.rotation.w = 1.0;
      poses.transforms.push_back(pose);
    }
    return poses;
  }

  /// Waits until the node is past its start-up grace, max(tf_wait_s, 1 s), in which a frame
  /// tf does not know may still come. Cycles at rate_hz never count faster than time.
  bool pastStartUpGrace() {
    const auto grace_cycles = static_cast<std::uint64_t>(kRateHz * std::max(kTfWaitS, 1.0)) + 1;
    return waitFor([&] { return stats_->cycles >= grace_cycles; });
  }

  ros::Subscriber log_subscriber_;
  std::deque<rosgraph_msgs::Log::ConstPtr> log_;
};

TEST_F(FaultsTest, CloudsWaitInOrderForATransformThatComesLate) {
  ros::Publisher late = input("/faults/late");
  deformed("late");
  const std::uint32_t rejected = stats_->clouds_rejected;
  // Two clouds (the second a new rest shape, 0.1 m along x) before any pose of their sensor.
  std::vector<PointCloud2> clouds;
  for (double x : {0.0, 0.1}) {
    clouds.push_back(cloudOf(cubePoints(x), "late_sensor"));
    const std::uint32_t received = stats_->clouds_received;
    late.publish(clouds.back());
    ASSERT_TRUE(waitFor([&] { return stats_->clouds_received > received; }));
  }
  // The sensor's poses come five cycles later, stamped around the clouds' stamps.
  ASSERT_TRUE(cyclesPass(5));
  EXPECT_FALSE(hasShape("late")) << "placed without a transform";
  ros::Publisher tf = tfPublisher();
  tf.publish(posesOf("late_sensor", {clouds.front().header.stamp - ros::Duration(0.1),
                                     clouds.back().header.stamp + ros::Duration(0.1)}));
  ASSERT_TRUE(waitFor([&] { return hasShape("late"); }, 3 * kTfWaitS))
      << "the clouds were not applied";
  ASSERT_TRUE(waitFor([&] {
    return deformed("late") &&
           (meanOf(*deformed("late")) - Eigen::Vector3d(0.1, 0.0, 1.04)).norm() < 1e-4;
  })) << "the second cloud, placed by the pose at its stamp, is not the object";
  EXPECT_EQ(stats_->clouds_rejected, rejected) << "a waiting cloud was dropped";
}

TEST_F(FaultsTest, ACloudWhoseSensorPoseNeverComesIsDroppedAfterTfWaitWithAWarning) {
  ros::Publisher ghost = input("/faults/ghost");
  ros::Publisher anchor = input("/faults/anchor");
  ros::Publisher tf = tfPublisher();
  // tf learns ghost_sensor from poses around one stamp, shown by a cloud of another object
  // placed with them. tf and clouds come on connections of their own: a cloud that came
  // first is dropped as in a frame tf does not know, and sent again.
  PointCloud2 placed = cloudOf(cubePoints(0.0), "ghost_sensor");
  tf.publish(posesOf("ghost_sensor", {placed.header.stamp - ros::Duration(0.1),
                                      placed.header.stamp + ros::Duration(0.1)}));
  const std::uint64_t received_before_anchor = stats_->clouds_received;
  std::uint64_t anchors_sent = 0;
  for (; anchors_sent < 20 && !hasShape("anchor"); ++anchors_sent) {
    anchor.publish(placed);
    waitFor([&] { return hasShape("anchor"); }, 0.5);
  }
  ASSERT_TRUE(hasShape("anchor")) << "the node did not learn ghost_sensor";
  ASSERT_TRUE(
      waitFor([&] { return stats_->clouds_received >= received_before_anchor + anchors_sent; }));

  // A cloud stamped after the newest pose: its pose at its stamp never comes.
  PointCloud2 lost = cloudOf(cubePoints(0.0), "ghost_sensor");
  lost.header.stamp = placed.header.stamp + ros::Duration(0.5);
  const std::uint64_t received = stats_->clouds_received;
  const std::uint64_t rejected = stats_->clouds_rejected;
  const ros::WallTime sent = ros::WallTime::now();
  ghost.publish(lost);
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected > rejected; }));
  const double waited_s = (ros::WallTime::now() - sent).toSec();
  EXPECT_GE(waited_s, 0.9 * kTfWaitS);
  EXPECT_LT(waited_s, 3 * kTfWaitS);
  EXPECT_EQ(stats_->clouds_received, received + 1);
  EXPECT_EQ(stats_->clouds_rejected, rejected + 1);
  EXPECT_TRUE(
      waitFor([&] { return problemLogged(rosgraph_msgs::Log::WARN, "/faults/ghost"); }, 5.0));
  EXPECT_FALSE(hasShape("ghost"));
}

TEST_F(FaultsTest, CloudsInAFrameTfDoesNotKnowAreDroppedAtOnceAndBlockNoGoodCloud) {
  ASSERT_TRUE(pastStartUpGrace());
  ros::Publisher mixed = input("/faults/mixed");
  deformed("mixed");
  const std::uint64_t received = stats_->clouds_received;
  const std::uint64_t rejected = stats_->clouds_rejected;
  // A second publisher on the same topic sends a cloud in a frame nobody publishes every 0.3 s.
  ros::NodeHandle wrong_handle;
  ros::Publisher wrong = wrong_handle.advertise<PointCloud2>("/faults/mixed", 2);
  ASSERT_TRUE(waitFor([&] { return wrong.getNumSubscribers() > 0; }));
  std::uint64_t wrong_sent = 0;
  const PointCloud2 wrong_cloud = cloudOf(cubePoints(0.5), "no_such_frame");
  ros::WallTimer wrong_timer =
      wrong_handle.createWallTimer(ros::WallDuration(0.3), [&](const ros::WallTimerEvent&) {
        wrong.publish(wrong_cloud);
        ++wrong_sent;
      });
  ASSERT_TRUE(waitFor([&] { return wrong_sent > 0; }));

  // Good clouds, each a new rest shape elsewhere, while the wrong ones keep coming: each is
  // applied well before a cloud that waited tf_wait_s in front of it would have left.
  std::uint64_t good_sent = 0;
  while (wrong_sent < 5) {
    const double x = good_sent % 2 == 0 ? 0.3 : 0.32;
    mixed.publish(cloudOf(cubePoints(x), "world"));
    ++good_sent;
    ASSERT_TRUE(waitFor(
        [&] {
          return deformed("mixed") &&
                 (meanOf(*deformed("mixed")) - Eigen::Vector3d(x, 0.0, 0.04)).norm() < 1e-4;
        },
        0.5 * kTfWaitS))
        << "good cloud " << good_sent << " waited behind a cloud in an unknown frame";
  }
  wrong_timer.stop();
  const std::uint64_t wrong_total = wrong_sent;
  ASSERT_TRUE(
      waitFor([&] { return stats_->clouds_received >= received + good_sent + wrong_total; }));
  EXPECT_EQ(stats_->clouds_received, received + good_sent + wrong_total);
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected >= rejected + wrong_total; }));
  EXPECT_TRUE(cyclesPass(5));
  EXPECT_EQ(stats_->clouds_rejected, rejected + wrong_total) << "a good cloud was dropped";
  EXPECT_TRUE(
      waitFor([&] { return problemLogged(rosgraph_msgs::Log::ERROR, "/faults/mixed"); }, 5.0));
}

TEST_F(FaultsTest, ATrackedCloudOfAnotherSizeIsRefusedAndTheNextGoodOneTaken) {
  ros::Publisher floor = input("/faults/floor");
  ros::Publisher counted = input("/faults/counted");
  deformed("counted");
  floor.publish(cloudOf(floorPoints(), "world"));
  counted.publish(cloudOf(cubePoints(-0.2), "world"));
  ASSERT_TRUE(waitFor([&] { return hasShape("counted") && hasShape("floor"); }));

  const std::uint32_t rejected = stats_->clouds_rejected;
  Points more = cubePoints(-0.2);
  more.resize(more.size() + 8, Eigen::Vector3d(-0.2, 0.0, 0.2));
  counted.publish(cloudOf(more, "world"));
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected == rejected + 1; }));
  EXPECT_TRUE(
      waitFor([&] { return problemLogged(rosgraph_msgs::Log::ERROR, "/faults/counted"); }, 5.0));

  counted.publish(cloudOf(cubePoints(-0.1), "world"));
  EXPECT_TRUE(waitFor([&] {
    return deformed("counted") && std::abs(meanOf(*deformed("counted")).x() + 0.1) < 1e-4;
  })) << "the next cloud of the right size did not move the object";
  EXPECT_EQ(stats_->clouds_rejected, rejected + 1);
}

TEST_F(FaultsTest, ATrackedCloudWithPointsBeyondMaxCoordinateIsRefusedAndTheNextGoodOneTaken) {
  ros::Publisher far = input("/faults/far");
  deformed("far");
  const auto slab = [](double x) { return grid(10, 10, 2, 0.02, {x, 0.3, 0.04}); };
  const auto deformedAtX = [&](double x) {
    return deformed("far") && std::abs(meanOf(*deformed("far")).x() - x) < 1e-4;
  };
  far.publish(doubleCloudOf(slab(0.4), "world"));
  ASSERT_TRUE(waitFor([&] { return deformedAtX(0.4); })) << "the first cloud was not taken";

  // 1% of the points at a finite but absurd 1e100 m (the default bound is 1e4 m).
  const std::uint32_t rejected = stats_->clouds_rejected;
  Points absurd = slab(0.45);
  absurd[17].x() = 1e100;
  absurd[123].z() = -1e100;
  far.publish(doubleCloudOf(absurd, "world"));
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected == rejected + 1; }))
      << "a cloud with points at 1e100 m was taken";
  ASSERT_TRUE(cyclesPass(3));
  EXPECT_TRUE(waitFor([&] { return deformedAtX(0.4); })) << "the refused cloud moved the object";
  EXPECT_TRUE(
      waitFor([&] { return problemLogged(rosgraph_msgs::Log::ERROR, "/faults/far"); }, 5.0));

  far.publish(doubleCloudOf(slab(0.45), "world"));
  EXPECT_TRUE(waitFor([&] { return deformedAtX(0.45); }))
      << "the next good cloud did not move the object";
  EXPECT_EQ(stats_->clouds_rejected, rejected + 1);
}

TEST_F(FaultsTest, ACloudOfTenMillionPointsIsRefusedByMaxPointsPerObject) {
  ros::Publisher big = input("/faults/big");
  PointCloud2 cloud = cloudOf(cubePoints(0.3), "world");
  cloud.width = 10000000;
  cloud.row_step = cloud.width * cloud.point_step;
  cloud.data.assign(cloud.row_step, 0);
  const std::uint32_t rejected = stats_->clouds_rejected;
  big.publish(cloud);
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected > rejected; }, 60.0));
  EXPECT_EQ(stats_->clouds_rejected, rejected + 1);
  EXPECT_TRUE(
      waitFor([&] { return problemLogged(rosgraph_msgs::Log::ERROR, "/faults/big"); }, 5.0));
  EXPECT_FALSE(hasShape("big"));
  EXPECT_TRUE(cyclesPass(5)) << "the node stopped cycling";
}

TEST_F(FaultsTest, APublisherProcessKilledAndStartedAgainIsFollowedAgain) {
  const std::string publisher =
      (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "scene_publisher").string();
  const std::vector<std::string> argv = {publisher,
                                         "__name:=fault_scene_publisher",
                                         "__ns:=/fault_scene",
                                         "_scene:=three_objects",
                                         "_points:=8000",
                                         "_rate_hz:=20"};
  std::uint32_t rejected = stats_->clouds_rejected;
  {
    ChildProcess first(argv);
    ASSERT_TRUE(first.running()) << publisher;
    ASSERT_TRUE(waitFor([&] { return hasShape("ball"); })) << "no cloud from the publisher";
    const std::uint32_t received = stats_->clouds_received;
    ASSERT_TRUE(waitFor([&] { return stats_->clouds_received >= received + 5; }));
    first.stop(SIGKILL);
  }
  ASSERT_TRUE(cyclesPass(10)) << "the node stopped cycling without its publisher";
  ChildProcess second(argv);
  ASSERT_TRUE(second.running());
  const std::uint32_t received = stats_->clouds_received;
  EXPECT_TRUE(waitFor([&] { return stats_->clouds_received >= received + 5; }))
      << "the clouds of the new publisher did not arrive";
  EXPECT_EQ(stats_->clouds_rejected, rejected) << "a cloud of the same object was refused";
}

TEST_F(FaultsTest, ServicesAnswerEveryCallOfSeveralClientsInATightLoop) {
  ros::Publisher floor = input("/faults/floor");
  ros::Publisher counted = input("/faults/counted");
  floor.publish(cloudOf(floorPoints(), "world"));
  counted.publish(cloudOf(cubePoints(-0.2), "world"));
  ASSERT_TRUE(waitFor([&] { return hasShape("counted") && hasShape("floor"); }));
  SetLevel running;
  running.request.level = SetLevel::Request::RUNNING;
  ASSERT_TRUE(ros::service::call(kNode + "/set_level", running));
  ASSERT_TRUE(running.response.success);
  const int max_level = running.response.max_level;

  constexpr int kClients = 4;
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(2.0);
  std::atomic<int> calls{0}, transport_failures{0}, wrong_answers{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      ros::NodeHandle handle;
      ros::ServiceClient get = handle.serviceClient<GetContacts>(kNode + "/get_contacts", true);
      ros::ServiceClient set = handle.serviceClient<SetLevel>(kNode + "/set_level", true);
      for (int i = 0; ros::WallTime::now() < end; ++i) {
        GetContacts contacts;
        contacts.request.object_a = (i + c) % 3 == 0 ? "nobody" : "counted";
        // -2 (the running level) to one past the leaves.
        contacts.request.level = static_cast<std::int16_t>(i % (max_level + 4) - 2);
        SetLevel level;
        level.request.level = static_cast<std::int16_t>(i % 2 == 0 ? max_level : 200);
        const bool answered = get.call(contacts) && set.call(level);
        calls += 2;
        if (!answered) {
          ++transport_failures;
          continue;
        }
        const bool get_valid =
            contacts.request.object_a == "counted" && contacts.request.level <= max_level;
        if (contacts.response.success != get_valid || level.response.success != (i % 2 == 0)) {
          ++wrong_answers;
        }
      }
    });
  }
  for (auto& client : clients) client.join();
  SetLevel finest;
  finest.request.level = SetLevel::Request::FINEST;
  ASSERT_TRUE(ros::service::call(kNode + "/set_level", finest));
  EXPECT_GT(calls, 100);
  EXPECT_EQ(transport_failures, 0);
  EXPECT_EQ(wrong_answers, 0);
  EXPECT_TRUE(cyclesPass(10)) << "the node stopped cycling";
  RecordProperty("service_calls", calls.load());
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "faults_client");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
