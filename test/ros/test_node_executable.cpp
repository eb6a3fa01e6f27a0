// The node executable (rostest node_executable.test): demo.launch standalone:=true runs the
// gripper demo's config in a process of its own, which reads the scene's clouds, finds the
// fruit on the floor and in the jaws, and answers its services (contacts, the distance of
// the jaws across the fruit) and publishes the distances of its configured pairs. Every wait has a
// timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <algorithm>
#include <set>
#include <string>
#include <utility>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/DistanceArray.h"
#include "deformable_collision/GetContacts.h"
#include "deformable_collision/GetDistance.h"

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

  ros::ServiceClient distance = handle.serviceClient<GetDistance>(kNode + "/get_distance");
  ASSERT_TRUE(distance.waitForExistence(ros::Duration(10.0)));
  GetDistance jaws;
  jaws.request.object_a = "jaw_left";
  jaws.request.object_b = "jaw_right";
  jaws.request.level = GetDistance::Request::FINEST;
  jaws.request.max_distance_m = 1.0;
  // The jaws' clouds may come after the fruit has touched the floor (a loaded machine): the
  // distance is asked for until both jaws are there.
  const ros::WallTime jaws_deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  do {
    ASSERT_TRUE(distance.call(jaws));
    if (jaws.response.distance.found) break;
    ros::WallDuration(0.05).sleep();
  } while (ros::ok() && ros::WallTime::now() < jaws_deadline);
  ASSERT_TRUE(jaws.response.distance.found) << jaws.response.message;
  EXPECT_EQ(jaws.response.header.frame_id, "world");
  EXPECT_EQ(jaws.response.distance.error_bound_m, 0.0);
  // The jaws close from 20 to 12 cm apart on the fruit (demoKinematicPose).
  EXPECT_GT(jaws.response.distance.distance_m, 0.05) << jaws.response.message;
  EXPECT_LT(jaws.response.distance.distance_m, 0.21) << jaws.response.message;
  EXPECT_GT(jaws.response.distance.normal.x * jaws.response.distance.normal.x, 0.9)
      << "across the jaws, along x";
}

TEST(NodeExecutable, PublishesTheDistancesOfTheConfiguredPairs) {
  ros::NodeHandle handle;
  DistanceArray::ConstPtr last;
  const ros::Subscriber subscriber = handle.subscribe<DistanceArray>(
      kNode + "/distances", 10, [&](const DistanceArray::ConstPtr& m) { last = m; });
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  const auto allFound = [&] {
    return last && last->distances.size() == 2 && last->distances[0].found &&
           last->distances[1].found;
  };
  while (ros::ok() && !allFound() && ros::WallTime::now() < deadline) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_TRUE(allFound()) << "config/demo.yaml's two distance_pairs, within 0.1 m";
  EXPECT_EQ(last->header.frame_id, "world");
  for (const Distance& d : last->distances) {
    EXPECT_EQ(d.object_a, "fruit");
    EXPECT_LE(d.distance_m, 0.1);
    EXPECT_EQ(d.error_bound_m, 0.0) << "the finest level";
  }
  EXPECT_EQ(last->distances[0].object_b, "jaw_left");
  EXPECT_EQ(last->distances[1].object_b, "jaw_right");
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_node_executable");
  return RUN_ALL_TESTS();
}
