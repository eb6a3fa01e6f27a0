#pragma once
// What the rostests' client nodes share: point grids, clouds, waiting on events, and loading
// the nodelet into a test's manager.

#include <gtest/gtest.h>
#include <nodelet/NodeletLoad.h>
#include <ros/ros.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <functional>
#include <string>
#include <vector>

#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {
namespace test {

using Points = std::vector<Eigen::Vector3d>;

constexpr double kTimeoutS = 30.0;

/// nx x ny x nz points `spacing` apart, centred at `center`.
inline Points grid(int nx, int ny, int nz, double spacing, const Eigen::Vector3d& center) {
  Points points;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      for (int k = 0; k < nz; ++k) {
        points.push_back(center + spacing * Eigen::Vector3d(i - (nx - 1) / 2.0, j - (ny - 1) / 2.0,
                                                            k - (nz - 1) / 2.0));
      }
    }
  }
  return points;
}

inline sensor_msgs::PointCloud2 cloudOf(const Points& points, const std::string& frame) {
  sensor_msgs::PointCloud2 cloud;
  writeCloudPoints(points, cloud);
  cloud.header.frame_id = frame;
  cloud.header.stamp = ros::Time::now();
  return cloud;
}

/// Spins until `done` or the timeout; returns `done()`.
inline bool waitFor(const std::function<bool()>& done, double timeout_s = kTimeoutS) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    ros::spinOnce();
    if (done()) return true;
    ros::WallDuration(0.002).sleep();
  }
  return done();
}

/// Loads the nodelet into `manager` under `name` with `params`; whether it started.
inline bool loadNodelet(const std::string& manager, const std::string& name,
                        const XmlRpc::XmlRpcValue& params) {
  ros::param::set(name, params);
  nodelet::NodeletLoad load;
  load.request.name = name;
  load.request.type = "deformable_collision/DeformableCollisionNodelet";
  EXPECT_TRUE(ros::service::waitForService(manager + "/load_nodelet", ros::Duration(kTimeoutS)));
  EXPECT_TRUE(ros::service::call(manager + "/load_nodelet", load));
  return load.response.success;
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
  /// Whether it has ended by itself; its exit status is then `status`.
  bool ended(int& status) {
    if (pid_ <= 0 || waitpid(pid_, &status, WNOHANG) != pid_) return false;
    pid_ = -1;
    return true;
  }

 private:
  pid_t pid_ = -1;
};

}  // namespace test
}  // namespace deformable_collision
