// The node executable (rostest node_executable.test): demo.launch standalone:=true runs the
// gripper demo's config in a process of its own, which reads the scene's clouds, finds the
// fruit on the floor and in the jaws, and answers its services. Every wait has a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <algorithm>
#include <set>
#include <string>
#include <utility>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/GetContacts.h"

namespace deformable_collision {
namespace test {
namespace {

const std::string kNode = "/deformable_collision";

/// The object pairs in contact, each with its names in order.
std::set<std::pair<std::string, std::string>> pairsOf(const ContactArray& contacts) {
  std::set<std::pair<std::string, std::string>> pairs;
  for (const Contact& c : contacts.contacts) pairs.insert(std::minmax(c.object_a, c.object_b));
  return pairs;
}

TEST(NodeExecutable, RunsTheGripperDemoWithoutAManager) {
  ros::NodeHandle handle;
  std::set<std::pair<std::string, std::string>> seen;
  const ros::Subscriber subscriber = handle.subscribe<ContactArray>(
      kNode + "/contacts", 10, [&](const ContactArray::ConstPtr& contacts) {
        const auto pairs = pairsOf(*contacts);
        seen.insert(pairs.begin(), pairs.end());
      });
  const std::pair<std::string, std::string> on_floor("floor", "fruit");
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::ok() && !seen.count(on_floor) && ros::WallTime::now() < deadline) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  EXPECT_TRUE(seen.count(on_floor)) << "no contact of the fruit with the floor within 60 s";

  ros::V_string nodes;
  ASSERT_TRUE(ros::master::getNodes(nodes));
  EXPECT_NE(std::find(nodes.begin(), nodes.end(), kNode), nodes.end());
  EXPECT_EQ(std::find(nodes.begin(), nodes.end(), "/deformable_collision_manager"), nodes.end())
      << "standalone:=true starts no manager";

  ros::ServiceClient client = handle.serviceClient<GetContacts>(kNode + "/get_contacts");
  ASSERT_TRUE(client.waitForExistence(ros::Duration(10.0)));
  GetContacts query;
  query.request.object_a = "fruit";
  query.request.level = -1;
  ASSERT_TRUE(client.call(query));
  EXPECT_TRUE(query.response.success) << query.response.message;
  EXPECT_FALSE(query.response.contacts.contacts.empty());
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_node_executable");
  return RUN_ALL_TESTS();
}
