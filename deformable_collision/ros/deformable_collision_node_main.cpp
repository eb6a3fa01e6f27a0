// The node as a process of its own (rosrun deformable_collision deformable_collision_node),
// the same class the nodelet holds; its parameters are private (~), as the nodelet's.
#include <ros/ros.h>

#include <exception>

#include "deformable_collision/ros/deformable_collision_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "deformable_collision");
  try {
    deformable_collision::DeformableCollisionNode node(ros::NodeHandle(), ros::NodeHandle("~"));
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("not started: %s", e.what());
    return 1;
  }
  return 0;
}
