#pragma once
// What scene_publisher publishes and scene_bag records of a built-in scene at one instant.

#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {

/// Where a scene's clouds are given: the kinematic objects' clouds are always their rest
/// shapes in their own frames; the others' in `cloud_frame`, at `cloud_frame_pose` in
/// `fixed_frame` (a camera's frame), or in `fixed_frame` itself if the names are equal.
struct SceneFrames {
  std::string fixed_frame = "world";
  std::string cloud_frame = "world";
  Eigen::Isometry3d cloud_frame_pose = Eigen::Isometry3d::Identity();
};

/// One instant of a built-in scene as messages, reused from one instant to the next.
struct SceneMessages {
  /// The poses of the kinematic objects' frames, and the cloud frame's if it has its own.
  tf2_msgs::TFMessage frames;
  /// Per object; empty for an object that was not asked for.
  std::vector<sensor_msgs::PointCloud2::Ptr> clouds;
};

/// Fills `messages` with `scene` (built-in `kind`) at `time_s`, stamped `stamp`: every
/// frame, and the clouds of the objects whose `wanted` entry is true.
void makeSceneMessages(DemoScene kind, const Scene& scene, double time_s, const ros::Time& stamp,
                       const SceneFrames& frames, const std::vector<bool>& wanted,
                       SceneMessages& messages);

}  // namespace deformable_collision
