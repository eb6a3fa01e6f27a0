// The robot block in a nodelet (rostest robot_links.test): the fingers of data/two_fingers.urdf
// become kinematic objects that follow the joint states this client publishes (through
// robot_state_publisher's tf), and touch a static block between them only when closed; a
// link missing from the description, and a missing description, leave the other objects
// served; a registered object's clouds leave the fingers' points out. Every wait is on an
// event with a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>

#include <algorithm>
#include <functional>
#include <string>

#include "deformable_collision/GetContacts.h"
#include "deformable_collision/Stats.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kManager = "/robot_links_manager";
const std::string kBlockTopic = "/robot_links_test/block";
const std::string kCameraTopic = "/robot_links_test/camera";
/// Open, the fingers' inner faces are at y = +-0.03, 2 cm from the block; closed, at
/// y = +-0.008, inside the block's faces at +-0.01.
constexpr double kOpen = 0.0;
constexpr double kClosed = 0.022;
/// How often the client publishes the joint states and the block.
constexpr double kPublishPeriodS = 0.02;

/// The client's publishers, advertised once for all tests: advertised again per test, a
/// publisher went while the manager kept its subscription (test_register.cpp says how that
/// lost messages).
class Publishers : public ::testing::Environment {
 public:
  void SetUp() override {
    ros::NodeHandle handle;
    joints = handle.advertise<sensor_msgs::JointState>("/joint_states", 10);
    block = handle.advertise<PointCloud2>(kBlockTopic, 2);
    camera = handle.advertise<PointCloud2>(kCameraTopic, 2);
  }
  void TearDown() override {
    joints.shutdown();
    block.shutdown();
    camera.shutdown();
  }
  ros::Publisher joints;
  ros::Publisher block;
  ros::Publisher camera;
};

Publishers* publishers = nullptr;  ///< Owned by gtest, set in main().

/// Both fingers' joints at `q` (0: open).
void publishJoints(double q) {
  sensor_msgs::JointState state;
  state.header.stamp = ros::Time::now();
  state.name = {"left_joint", "right_joint"};
  state.position = {q, q};
  publishers->joints.publish(state);
}

/// A 2 cm cube of points every 2 mm, centred between the fingers.
Points cube() { return grid(11, 11, 11, 0.002, Eigen::Vector3d::Zero()); }

void publishBlock() { publishers->block.publish(cloudOf(cube(), "base_link")); }

/// Publishes the joints at `q` and the block every kPublishPeriodS until `done` or the
/// timeout; returns `done()`.
bool whilePublishing(double q, const std::function<bool()>& done) {
  ros::WallTime next;
  bool finished = false;
  waitFor([&] {
    if (ros::WallTime::now() < next) return false;
    next = ros::WallTime::now() + ros::WallDuration(kPublishPeriodS);
    publishJoints(q);
    publishBlock();
    finished = done();
    return finished;
  });
  return finished;
}

/// The block (static; or registered from the camera's clouds) and the robot's fingers;
/// `no_such_link` is not in the description.
XmlRpc::XmlRpcValue nodeParams(const std::string& description_param, bool registered = false) {
  XmlRpc::XmlRpcValue params;
  params["fixed_frame"] = "base_link";
  params["rate_hz"] = 50;
  params["contact_distance_m"] = 0.003;
  XmlRpc::XmlRpcValue& block = params["objects"][0];
  block["name"] = "block";
  block["topic"] = registered ? kCameraTopic : kBlockTopic;
  block["dynamic"] = false;
  if (registered) block["on_cloud"] = "register";
  XmlRpc::XmlRpcValue& robot = params["robot"];
  robot["description_param"] = description_param;
  robot["links"][0] = "left_finger";
  robot["links"][1] = "right_finger";
  robot["links"][2] = "no_such_link";
  return params;
}

class RobotLinksNodeTest : public ::testing::Test {
 protected:
  /// Loads `node` and waits until it has `objects` objects with a rest shape.
  void startNode(const std::string& node, const std::string& description_param,
                 std::uint32_t objects, bool registered = false) {
    node_ = node;
    stats_subscriber_ = handle_.subscribe<Stats>(
        node + "/stats", 10,
        boost::function<void(const Stats::ConstPtr&)>([this](const Stats::ConstPtr& stats) {
          stats_ = stats;
          ++stats_received_;
        }));
    ASSERT_TRUE(loadNodelet(kManager, node, nodeParams(description_param, registered)))
        << "the nodelet did not start";
    ASSERT_TRUE(whilePublishing(kOpen, [&] {
      if (registered) publishers->camera.publish(cloudOf(cube(), "base_link"));
      return stats_ && stats_->objects == objects;
    })) << "the objects were not made";
  }

  /// The finest level's contacts between `a` and `b` on the node's current state.
  GetContacts::Response contacts(const std::string& a, const std::string& b) {
    GetContacts call;
    call.request.object_a = a;
    call.request.object_b = b;
    call.request.level = GetContacts::Request::FINEST;
    EXPECT_TRUE(ros::service::call(node_ + "/get_contacts", call));
    return call.response;
  }

  std::size_t fingerContacts(const std::string& finger) {
    const GetContacts::Response answer = contacts(finger, "block");
    EXPECT_TRUE(answer.success) << answer.message;
    return answer.contacts.contacts.size();
  }

  /// Whether both fingers touch the block (`touching`) or neither does.
  bool fingersTouch(bool touching) {
    const bool left = fingerContacts("left_finger") > 0, right = fingerContacts("right_finger") > 0;
    return left == touching && right == touching;
  }

  ros::NodeHandle handle_;
  ros::Subscriber stats_subscriber_;
  Stats::ConstPtr stats_;
  std::size_t stats_received_ = 0;
  std::string node_;
};

TEST_F(RobotLinksNodeTest, FingersFollowTheJointStatesAndTouchTheBlockOnlyWhenClosed) {
  // The block and both fingers: no_such_link is refused, with an error naming it.
  ASSERT_NO_FATAL_FAILURE(startNode("/robot_links_node", "robot_description", 3));
  PointCloud2::ConstPtr left;
  const ros::Subscriber left_subscriber = handle_.subscribe<PointCloud2>(
      node_ + "/deformed/left_finger", 1,
      boost::function<void(const PointCloud2::ConstPtr&)>(
          [&](const PointCloud2::ConstPtr& cloud) { left = cloud; }));
  // The left finger's points span y from its inner face, 0.03 - q, to 1 cm beyond.
  auto leftFingerAt = [&](double q) {
    Points points;
    if (!left || !readCloudPoints(*left, NonFinitePoints::kDrop, 1 << 20, points).ok())
      return false;
    const auto [low, high] = std::minmax_element(
        points.begin(), points.end(), [](const auto& a, const auto& b) { return a.y() < b.y(); });
    return std::abs(low->y() - (0.03 - q)) < 1e-5 && std::abs(high->y() - (0.04 - q)) < 1e-5;
  };
  for (const double q : {kOpen, kClosed, kOpen}) {
    SCOPED_TRACE("joints at " + std::to_string(q));
    EXPECT_TRUE(whilePublishing(q, [&] { return leftFingerAt(q); }))
        << "~deformed/left_finger does not follow the joint";
    EXPECT_TRUE(whilePublishing(q, [&] { return fingersTouch(q == kClosed); }))
        << "the fingers " << (q == kClosed ? "do not touch" : "still touch") << " the block";
  }
  // A refused link stays listed, like an object without a cloud: it has no contacts.
  const GetContacts::Response refused = contacts("no_such_link", "");
  EXPECT_TRUE(refused.success) << refused.message;
  EXPECT_TRUE(refused.contacts.contacts.empty());
}

TEST_F(RobotLinksNodeTest, AMissingRobotDescriptionLeavesTheOtherObjectsServed) {
  ASSERT_NO_FATAL_FAILURE(startNode("/robot_links_without_robot", "no_such_description", 1));
  const GetContacts::Response answer = contacts("block", "");
  EXPECT_TRUE(answer.success) << answer.message;
  const std::size_t received = stats_received_;
  EXPECT_TRUE(whilePublishing(kOpen, [&] { return stats_received_ >= received + 10; }))
      << "the node stopped cycling";
}

TEST_F(RobotLinksNodeTest, RegisteredCloudsLeaveTheFingersPointsOut) {
  // The block registered from the camera, its model its first cloud: the cube.
  ASSERT_NO_FATAL_FAILURE(startNode("/robot_links_register", "robot_description", 3, true));
  // The camera also sees the open left finger's inner face (y = 0.03), 2 cm from the block:
  // its points are the finger's, within the contact distance of its surface points.
  Points seen = cube();
  const Points face = grid(11, 1, 21, 0.002, Eigen::Vector3d(0.0, 0.03, 0.0));
  seen.insert(seen.end(), face.begin(), face.end());
  auto registered = [&] {
    return !stats_->registrations.empty() && stats_->registrations[0].cloud_points == seen.size();
  };
  EXPECT_TRUE(whilePublishing(kOpen, [&] {
    publishers->camera.publish(cloudOf(seen, "base_link"));
    return registered();
  })) << "no registration of the cloud with the face";
  ASSERT_TRUE(registered());
  // The face's points and only those: the block's are 2 cm from the finger.
  EXPECT_EQ(stats_->registrations[0].excluded_points, face.size());
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_robot_links_node");
  ros::NodeHandle handle;  // Keeps the node up between the tests.
  deformable_collision::test::publishers = new deformable_collision::test::Publishers;
  ::testing::AddGlobalTestEnvironment(deformable_collision::test::publishers);
  return RUN_ALL_TESTS();
}
