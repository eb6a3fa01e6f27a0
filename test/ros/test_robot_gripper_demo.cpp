// The robot_gripper demo end to end (robot_gripper_demo.test): the fingers, robot links of
// config/robot/two_finger_gripper.urdf, close on the fruit over 2 s, hold it and open at 6 s
// (scripts/gripper_joint_driver). Their ~wrench/<finger> read equal and opposite squeezing
// forces while they hold it, and next to none once open.
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cmath>
#include <string>
#include <vector>

#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

/// A finger's force along its frame's x, stamped from the first wrench of either finger.
struct ForceSamples {
  std::vector<std::pair<double, double>> samples;  ///< (s since the first, N)

  /// The mean over [from_s, to_s); NaN if none.
  double mean(double from_s, double to_s) const {
    double sum = 0.0;
    int count = 0;
    for (const auto& [t, fx] : samples) {
      if (t < from_s || t >= to_s) continue;
      sum += fx;
      ++count;
    }
    return count > 0 ? sum / count : std::nan("");
  }
};

TEST(RobotGripperDemo, FingersReadTheSqueezeTheyHold) {
  ros::NodeHandle handle;
  ros::Time first;
  ForceSamples left, right;
  const auto record = [&first](ForceSamples& finger) {
    return boost::function<void(const geometry_msgs::WrenchStamped::ConstPtr&)>(
        [&finger, &first](const geometry_msgs::WrenchStamped::ConstPtr& m) {
          if (first.isZero()) first = m->header.stamp;
          finger.samples.emplace_back((m->header.stamp - first).toSec(), m->wrench.force.x);
        });
  };
  const std::string node = "/deformable_collision/wrench/";
  ros::Subscriber left_subscriber =
      handle.subscribe<geometry_msgs::WrenchStamped>(node + "left_finger", 1000, record(left));
  ros::Subscriber right_subscriber =
      handle.subscribe<geometry_msgs::WrenchStamped>(node + "right_finger", 1000, record(right));
  // The whole course: closed at 2 s, open from 6 s to 8 s, then a second open.
  ASSERT_TRUE(
      waitFor([&] { return !right.samples.empty() && right.samples.back().first > 9.0; }, 60.0))
      << "no wrench of the fingers for 9 s";
  const double held_left = left.mean(3.0, 5.0);
  const double held_right = right.mean(3.0, 5.0);
  // Each finger is pushed outwards, the left one towards -x, by about 2 N (gripper scene).
  EXPECT_LT(held_left, -0.5);
  EXPECT_GT(held_right, 0.5);
  EXPECT_LT(std::abs(held_left + held_right), 0.05 * held_right);
  EXPECT_LT(std::abs(right.mean(8.5, 9.0)), 0.2 * held_right) << "the open fingers still press";
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
