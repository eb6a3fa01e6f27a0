#pragma once
// What the fault rostests' clients share (faults.test, manager_respawn.test): the node's
// ~stats, its inputs and outputs, and the scene of faults_test.yaml.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <map>
#include <string>

#include "deformable_collision/GetContacts.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {

const std::string kNode = "/deformable_collision";

/// A 0.6 m floor of two layers, top at z = 0, and a cube resting on it.
inline Points floorPoints() { return grid(31, 31, 2, 0.02, {0.0, 0.0, -0.01}); }
inline Points cubePoints(double x) { return grid(4, 4, 4, 0.02, {x, 0.0, 0.04}); }

inline Eigen::Vector3d meanOf(const sensor_msgs::PointCloud2& cloud) {
  Points points;
  EXPECT_TRUE(readCloudPoints(cloud, NonFinitePoints::kDrop, 1 << 20, points).ok());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) sum += p;
  return sum / std::max<std::size_t>(points.size(), 1);
}

/// A client of the running node: its newest ~stats, its inputs and its deformed clouds.
class FaultTestFixture : public ::testing::Test {
 protected:
  using PointCloud2 = sensor_msgs::PointCloud2;

  void SetUp() override {
    stats_subscriber_ =
        handle_.subscribe<Stats>(kNode + "/stats", 10,
                                 boost::function<void(const Stats::ConstPtr&)>(
                                     [this](const Stats::ConstPtr& m) { stats_ = m; }));
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
    call.request.level = GetContacts::Request::RUNNING;
    return ros::service::call(kNode + "/get_contacts", call) && call.response.success &&
           call.response.message.find("has had no valid cloud yet") == std::string::npos;
  }

  /// Waits until the node has cycled `cycles` more times.
  bool cyclesPass(std::uint32_t cycles) {
    const std::uint64_t target = stats_->cycles + cycles;
    return waitFor([&] { return stats_->cycles >= target; });
  }

  ros::NodeHandle handle_;
  ros::Subscriber stats_subscriber_;
  std::map<std::string, ros::Subscriber> deformed_subscribers_;
  std::map<std::string, PointCloud2::ConstPtr> deformed_;
  Stats::ConstPtr stats_;
};

}  // namespace test
}  // namespace deformable_collision
