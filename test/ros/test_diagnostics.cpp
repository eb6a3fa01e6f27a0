// A client of the nodelet reads /diagnostics while its inputs fail and recover
// (diagnostics.test, diagnostics_test.yaml).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <map>
#include <string>

#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using diagnostic_msgs::DiagnosticStatus;

const std::string kCamera = "deformable_collision: object camera";
const std::string kCycle = "deformable_collision: cycle";

class Diagnostics : public ::testing::Test {
 protected:
  void SetUp() override {
    subscriber_ = handle_.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 10,
        boost::function<void(const diagnostic_msgs::DiagnosticArray::ConstPtr&)>(
            [this](const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
              for (const DiagnosticStatus& status : array->status) {
                statuses_[status.name] = status;
                ++updates_[status.name];
              }
            }));
    camera_ = handle_.advertise<sensor_msgs::PointCloud2>("/diagnostics_test/camera", 2);
    heavy_ = handle_.advertise<sensor_msgs::PointCloud2>("/diagnostics_test/heavy", 2);
    ASSERT_TRUE(waitFor(
        [this] { return camera_.getNumSubscribers() > 0 && heavy_.getNumSubscribers() > 0; }));
    camera_timer_ =
        handle_.createWallTimer(ros::WallDuration(0.1), [this](const ros::WallTimerEvent&) {
          camera_.publish(cloudOf(grid(5, 5, 2, 0.02, {1.0, 0.0, 0.0}), "world"));
        });
  }

  /// Waits for a status of `name` at `level` published after this call; its message.
  std::string waitForLevel(const std::string& name, std::uint8_t level) {
    const std::size_t seen = updates_[name];
    const bool reached =
        waitFor([&] { return updates_[name] > seen && statuses_[name].level == level; });
    EXPECT_TRUE(reached) << name << " never reached level " << int(level)
                         << "; last: " << int(statuses_[name].level) << " '"
                         << statuses_[name].message << "'";
    return statuses_[name].message;
  }

  ros::NodeHandle handle_;
  ros::Subscriber subscriber_;
  ros::Publisher camera_, heavy_;
  ros::WallTimer camera_timer_;
  std::map<std::string, DiagnosticStatus> statuses_;
  std::map<std::string, std::size_t> updates_;
};

TEST_F(Diagnostics, AStoppedCameraWarnsThenIsAnErrorUntilItComesBack) {
  waitForLevel(kCamera, DiagnosticStatus::OK);
  camera_timer_.stop();
  EXPECT_NE(waitForLevel(kCamera, DiagnosticStatus::WARN).find("no cloud for"), std::string::npos);
  EXPECT_NE(waitForLevel(kCamera, DiagnosticStatus::ERROR).find("no cloud for"), std::string::npos);
  camera_timer_.start();
  waitForLevel(kCamera, DiagnosticStatus::OK);
}

TEST_F(Diagnostics, AMalformedCloudWarnsForItsPeriod) {
  waitForLevel(kCamera, DiagnosticStatus::OK);
  sensor_msgs::PointCloud2 cloud = cloudOf(grid(5, 5, 2, 0.02, {1.0, 0.0, 0.0}), "world");
  cloud.data.pop_back();
  camera_.publish(cloud);
  EXPECT_NE(waitForLevel(kCamera, DiagnosticStatus::WARN).find("clouds dropped"),
            std::string::npos);
  waitForLevel(kCamera, DiagnosticStatus::OK);
}

TEST_F(Diagnostics, OverrunningCyclesAreAnErrorUntilTheCyclesKeepToTheRate) {
  // Shape matching of 400k points takes milliseconds: far beyond 1 / 500 Hz.
  heavy_.publish(cloudOf(grid(100, 100, 40, 0.01, {0.0, 0.0, 1.0}), "world"));
  EXPECT_NE(waitForLevel(kCycle, DiagnosticStatus::ERROR).find("cycles overran"),
            std::string::npos);
  heavy_.publish(cloudOf(grid(4, 4, 4, 0.01, {0.0, 0.0, 1.0}), "world"));
  waitForLevel(kCycle, DiagnosticStatus::OK);
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_diagnostics");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
