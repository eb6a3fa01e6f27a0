// The robot_gripper demo end to end (robot_gripper_demo.test): the fingers, robot links of
// config/robot/two_finger_gripper.urdf, close on the fruit, hold it and open again
// (scripts/gripper_joint_driver). While they hold it, their ~wrench/<finger> read equal and
// opposite squeezing forces; once open, next to none. The windows come from the joint states
// the driver sends, on the clock of the wrenches' stamps.
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>

#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

/// A finger's force along its frame's x, by stamp.
struct ForceSamples {
  std::vector<std::pair<ros::Time, double>> samples;

  /// The mean over [from, to); NaN if none.
  double mean(const ros::Time& from, const ros::Time& to) const {
    double sum = 0.0;
    int count = 0;
    for (const auto& [t, fx] : samples) {
      if (t < from || t >= to) continue;
      sum += fx;
      ++count;
    }
    return count > 0 ? sum / count : std::nan("");
  }
};

/// When the driver's right finger joint reached the closed pad (0.06 m), left it, and came
/// back to the open one (0.1 m).
struct Course {
  std::optional<ros::Time> closed, opening, opened;

  void add(const sensor_msgs::JointState& state) {
    if (state.position.size() < 2) return;
    const double right = state.position[1];
    if (!closed && right <= 0.0601) closed = state.header.stamp;
    if (closed && !opening && right > 0.0601) opening = state.header.stamp;
    if (opening && !opened && right >= 0.0999) opened = state.header.stamp;
  }
};

template <typename Message, typename Callback>
ros::Subscriber subscribe(ros::NodeHandle& handle, const std::string& topic, Callback callback) {
  return handle.subscribe<Message>(
      topic, 1000, boost::function<void(const typename Message::ConstPtr&)>(callback));
}

TEST(RobotGripperDemo, FingersReadTheSqueezeTheyHold) {
  ros::NodeHandle handle;
  ForceSamples left, right;
  Course course;
  const auto record = [](ForceSamples& finger) {
    return [&finger](const geometry_msgs::WrenchStamped::ConstPtr& m) {
      finger.samples.emplace_back(m->header.stamp, m->wrench.force.x);
    };
  };
  const std::string node = "/deformable_collision/wrench/";
  auto left_subscriber =
      subscribe<geometry_msgs::WrenchStamped>(handle, node + "left_finger", record(left));
  auto right_subscriber =
      subscribe<geometry_msgs::WrenchStamped>(handle, node + "right_finger", record(right));
  auto joints_subscriber = subscribe<sensor_msgs::JointState>(
      handle, "/joint_states",
      [&course](const sensor_msgs::JointState::ConstPtr& m) { course.add(*m); });
  ASSERT_TRUE(waitFor(
      [&] {
        return course.opened && !right.samples.empty() &&
               right.samples.back().first > *course.opened + ros::Duration(1.0);
      },
      60.0))
      << "the fingers did not close and open again with wrenches read";
  // Held: from a second after closing to half a second before opening (4 s at the defaults).
  const ros::Time held_from = *course.closed + ros::Duration(1.0);
  const ros::Time held_to = *course.opening - ros::Duration(0.5);
  const double held_left = left.mean(held_from, held_to);
  const double held_right = right.mean(held_from, held_to);
  // Each finger is pushed outwards, the left one towards -x, by about 2 N (gripper scene).
  EXPECT_LT(held_left, -0.5);
  EXPECT_GT(held_right, 0.5);
  EXPECT_LT(std::abs(held_left + held_right), 0.05 * held_right);
  const double open_right =
      right.mean(*course.opened + ros::Duration(0.5), *course.opened + ros::Duration(1.0));
  EXPECT_LT(std::abs(open_right), 0.2 * held_right) << "the open fingers still press";
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_robot_gripper_demo");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
