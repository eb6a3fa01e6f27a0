// Faults the nodelet must survive (rostest faults.test): late and missing tf, a publisher
// process killed and started again, a tracked cloud of another size, a cloud of 10 million
// points, services hammered from several clients at once, and its manager killed (the
// launch file respawns it). Each test meets its own object of faults_test.yaml; every wait
// is on an event with a timeout. The manager test comes last: it restarts the node.
#include <gtest/gtest.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <atomic>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <thread>

#include "deformable_collision/GetContacts.h"
#include "deformable_collision/SetLevel.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

extern char** environ;

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kNode = "/deformable_collision";
const std::string kManager = "/faults_manager";
constexpr double kTfWaitS = 1.0;  // faults_test.yaml

/// A 0.6 m floor of two layers, top at z = 0, and a cube resting on it.
Points floorPoints() { return grid(31, 31, 2, 0.02, {0.0, 0.0, -0.01}); }
Points cubePoints(double x) { return grid(4, 4, 4, 0.02, {x, 0.0, 0.04}); }

Eigen::Vector3d meanOf(const PointCloud2& cloud) {
  Points points;
  EXPECT_TRUE(readCloudPoints(cloud, NonFinitePoints::kDrop, 1 << 20, points).ok());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) sum += p;
  return sum / std::max<std::size_t>(points.size(), 1);
}

/// The process id of a ROS node, asked through its own XML-RPC API (getPid); std::nullopt
/// if the master does not know it or it does not answer (dead).
std::optional<int> pidOfNode(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return std::nullopt;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return std::nullopt;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue request, response;
  request[0] = ros::this_node::getName();
  const bool answered = client.execute("getPid", request, response);
  client.close();
  if (!answered || response.getType() != XmlRpc::XmlRpcValue::TypeArray ||
      static_cast<int>(response[0]) != 1) {
    return std::nullopt;
  }
  return static_cast<int>(response[2]);
}

/// A child process, stopped by its pid (SIGTERM, then waited for) when it goes out of scope.
class ChildProcess {
 public:
  explicit ChildProcess(std::vector<std::string> argv) {
    std::vector<char*> args;
    for (auto& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    if (posix_spawn(&pid_, args[0], nullptr, nullptr, args.data(), environ) != 0) pid_ = -1;
  }
  ~ChildProcess() { stop(SIGTERM); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool running() const { return pid_ > 0; }
  void stop(int signal) {
    if (pid_ <= 0) return;
    kill(pid_, signal);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

class FaultsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    stats_subscriber_ = handle_.subscribe<Stats>(
        kNode + "/stats", 10,
        boost::function<void(const Stats::ConstPtr&)>([this](const Stats::ConstPtr& m) { stats_ = m; }));
    log_subscriber_ = handle_.subscribe<rosgraph_msgs::Log>(
        "/rosout", 100, boost::function<void(const rosgraph_msgs::Log::ConstPtr&)>(
                            [this](const rosgraph_msgs::Log::ConstPtr& m) { log_.push_back(m->msg); }));
    ASSERT_TRUE(waitFor([this] { return stats_ != nullptr; })) << "no ~stats from the node";
    ASSERT_TRUE(ros::service::waitForService(kNode + "/get_contacts", ros::Duration(kTimeoutS)));
  }

  ros::Publisher input(const std::string& topic, bool latch = false) {
    ros::Publisher publisher = handle_.advertise<PointCloud2>(topic, 2, latch);
    EXPECT_TRUE(waitFor([&] { return publisher.getNumSubscribers() > 0; })) << topic;
    return publisher;
  }

  /// The newest cloud on ~deformed/<object>, collected from now on.
  const PointCloud2::ConstPtr& deformed(const std::string& object) {
    if (deformed_subscribers_.count(object) == 0) {
      deformed_subscribers_[object] = handle_.subscribe<PointCloud2>(
          kNode + "/deformed/" + object, 2,
          boost::function<void(const PointCloud2::ConstPtr&)>(
              [this, object](const PointCloud2::ConstPtr& m) { deformed_[object] = m; }));
    }
    return deformed_[object];
  }

  bool hasShape(const std::string& object) {
    GetContacts call;
    call.request.object_a = object;
    call.request.level = -1;
    return ros::service::call(kNode + "/get_contacts", call) && call.response.success &&
           call.response.message.find("has had no valid cloud yet") == std::string::npos;
  }

  bool logged(const std::string& text) const {
    for (const auto& line : log_) {
      if (line.find(text) != std::string::npos) return true;
    }
    return false;
  }

  /// Waits until the node has cycled `cycles` more times.
  bool cyclesPass(std::uint32_t cycles) {
    const std::uint32_t target = stats_->cycles + cycles;
    return waitFor([&] { return stats_->cycles >= target; });
  }

  ros::NodeHandle handle_;
  ros::Subscriber stats_subscriber_;
  ros::Subscriber log_subscriber_;
  std::map<std::string, ros::Subscriber> deformed_subscribers_;
  std::map<std::string, PointCloud2::ConstPtr> deformed_;
  Stats::ConstPtr stats_;
  std::deque<std::string> log_;
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
  ros::Publisher tf = handle_.advertise<tf2_msgs::TFMessage>("/tf", 2);
  ASSERT_TRUE(waitFor([&] { return tf.getNumSubscribers() > 0; }));
  tf2_msgs::TFMessage poses;
  for (const ros::Time& stamp : {clouds.front().header.stamp - ros::Duration(0.1),
                                 clouds.back().header.stamp + ros::Duration(0.1)}) {
    geometry_msgs::TransformStamped pose;
    pose.header.stamp = stamp;
    pose.header.frame_id = "world";
    pose.child_frame_id = "late_sensor";
    pose.transform.translation.z = 1.0;
    pose.transform.rotation.w = 1.0;
    poses.transforms.push_back(pose);
  }
  tf.publish(poses);
  ASSERT_TRUE(waitFor([&] { return hasShape("late"); }, 3 * kTfWaitS)) << "the clouds were not applied";
  ASSERT_TRUE(waitFor([&] {
    return deformed("late") && (meanOf(*deformed("late")) - Eigen::Vector3d(0.1, 0.0, 1.04)).norm() < 1e-4;
  })) << "the second cloud, placed by the pose at its stamp, is not the object";
  EXPECT_EQ(stats_->clouds_rejected, rejected) << "a waiting cloud was dropped";
}

TEST_F(FaultsTest, ACloudWithoutTransformIsDroppedAfterTfWaitSayingWhy) {
  ros::Publisher ghost = input("/faults/ghost");
  const std::uint32_t rejected = stats_->clouds_rejected;
  const ros::WallTime sent = ros::WallTime::now();
  ghost.publish(cloudOf(cubePoints(0.0), "ghost_sensor"));
  ASSERT_TRUE(waitFor([&] { return stats_->clouds_rejected > rejected; }));
  const double waited_s = (ros::WallTime::now() - sent).toSec();
  EXPECT_GE(waited_s, 0.9 * kTfWaitS);
  EXPECT_LT(waited_s, 3 * kTfWaitS);
  EXPECT_TRUE(waitFor([&] { return logged("cloud on /faults/ghost dropped"); }, 5.0));
  EXPECT_TRUE(logged("no transform from 'ghost_sensor' to 'world' within tf_wait_s"));
  EXPECT_FALSE(hasShape("ghost"));
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
  EXPECT_TRUE(waitFor([&] { return logged("it has 72 points, the first had 64"); }, 5.0));

  counted.publish(cloudOf(cubePoints(-0.1), "world"));
  EXPECT_TRUE(waitFor([&] {
    return deformed("counted") && std::abs(meanOf(*deformed("counted")).x() + 0.1) < 1e-4;
  })) << "the next cloud of the right size did not move the object";
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
  EXPECT_TRUE(waitFor([&] {
    return logged("cloud on /faults/big dropped, object 'big' unchanged: cloud of 10000000 "
                  "points exceeds max_points_per_object 200000");
  }, 5.0));
  EXPECT_FALSE(hasShape("big"));
  EXPECT_TRUE(cyclesPass(5)) << "the node stopped cycling";
}

TEST_F(FaultsTest, APublisherProcessKilledAndStartedAgainIsFollowedAgain) {
  const std::string publisher =
      (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "scene_publisher").string();
  const std::vector<std::string> argv = {publisher, "__name:=fault_scene_publisher",
                                         "__ns:=/fault_scene", "_scene:=three_objects",
                                         "_points:=8000", "_rate_hz:=20"};
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
  SetLevel finest;
  finest.request.level = 255;
  ASSERT_TRUE(ros::service::call(kNode + "/set_level", finest));
  const int max_level = finest.response.max_level;

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
        contacts.request.level = static_cast<std::int16_t>(i % (max_level + 3) - 1);
        SetLevel level;
        level.request.level = static_cast<std::uint8_t>(i % 2 == 0 ? max_level : 200);
        const bool answered = get.call(contacts) && set.call(level);
        calls += 2;
        if (!answered) {
          ++transport_failures;
          continue;
        }
        const bool get_valid = contacts.request.object_a == "counted" &&
                               contacts.request.level <= max_level;
        if (contacts.response.success != get_valid || level.response.success != (i % 2 == 0)) {
          ++wrong_answers;
        }
      }
    });
  }
  for (auto& client : clients) client.join();
  ASSERT_TRUE(ros::service::call(kNode + "/set_level", finest));
  EXPECT_GT(calls, 100);
  EXPECT_EQ(transport_failures, 0);
  EXPECT_EQ(wrong_answers, 0);
  EXPECT_TRUE(cyclesPass(10)) << "the node stopped cycling";
  RecordProperty("service_calls", calls.load());
}

TEST_F(FaultsTest, TheManagerKilledIsRespawnedAndTheNodeComesBack) {
  // Latched, as a driver's static clouds often are: the new node gets them on connecting.
  ros::Publisher floor = input("/faults/floor", true);
  floor.publish(cloudOf(floorPoints(), "world"));
  ASSERT_TRUE(waitFor([&] { return hasShape("floor"); }));
  const std::optional<int> manager = pidOfNode(kManager);
  ASSERT_TRUE(manager) << "no pid for " << kManager;
  const std::uint32_t cycles = stats_->cycles;
  ASSERT_EQ(kill(*manager, SIGKILL), 0);

  ASSERT_TRUE(waitFor([&] {
    const auto now = pidOfNode(kManager);
    return now && *now != *manager;
  }, 60.0)) << "the manager was not respawned";
  ASSERT_TRUE(ros::service::waitForService(kNode + "/get_contacts", ros::Duration(kTimeoutS)));
  EXPECT_TRUE(waitFor([&] { return stats_->cycles < cycles && stats_->objects >= 1; }, 60.0))
      << "no new node, or it did not get the latched cloud";
  EXPECT_TRUE(waitFor([&] { return hasShape("floor"); }));
  EXPECT_FALSE(std::filesystem::exists("/proc/" + std::to_string(*manager)));
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
