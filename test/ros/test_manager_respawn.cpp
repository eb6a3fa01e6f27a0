// The nodelet manager killed (rostest manager_respawn.test): SIGKILL to the pid the manager
// gives through its XML-RPC getPid; roslaunch respawns it and the nodelet, and the new node
// cycles and gets its latched clouds again. Every wait is on an event with a timeout.
#include <gtest/gtest.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <signal.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <filesystem>
#include <optional>

#include "fault_test_fixture.h"

namespace deformable_collision {
namespace test {
namespace {

const std::string kManager = "/respawn_manager";

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

using ManagerRespawnTest = FaultTestFixture;

TEST_F(ManagerRespawnTest, TheManagerKilledIsRespawnedAndTheNodeComesBack) {
  // Latched, as a driver's static clouds often are: the new node gets them on connecting.
  ros::Publisher floor = input("/faults/floor", true);
  floor.publish(cloudOf(floorPoints(), "world"));
  ASSERT_TRUE(waitFor([&] { return hasShape("floor"); }));
  const std::optional<int> manager = pidOfNode(kManager);
  ASSERT_TRUE(manager) << "no pid for " << kManager;
  const std::uint64_t cycles = stats_->cycles;
  ASSERT_EQ(kill(*manager, SIGKILL), 0);

  ASSERT_TRUE(waitFor(
      [&] {
        const auto now = pidOfNode(kManager);
        return now && *now != *manager;
      },
      60.0))
      << "the manager was not respawned";
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
  ros::init(argc, argv, "manager_respawn_client");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
