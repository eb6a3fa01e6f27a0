#include "deformable_collision/tools/scene_messages.h"

#include <boost/make_shared.hpp>

#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {

void makeSceneMessages(DemoScene kind, const Scene& scene, double time_s, const ros::Time& stamp,
                       const SceneFrames& frames, const std::vector<bool>& wanted,
                       SceneMessages& messages) {
  messages.frames.transforms.clear();
  messages.clouds.assign(scene.objectCount(), nullptr);
  const bool own_cloud_frame = frames.cloud_frame != frames.fixed_frame;
  if (own_cloud_frame) {
    messages.frames.transforms.push_back(
        toTransformStamped(frames.cloud_frame_pose, stamp, frames.fixed_frame, frames.cloud_frame));
  }
  const Eigen::Isometry3d to_cloud_frame = frames.cloud_frame_pose.inverse();
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < scene.objectCount(); ++i) {
    const auto& object = scene.objectConfig(i);
    const bool kinematic = object.kind == ObjectKind::kKinematic;
    if (kinematic) {
      // A kinematic object is its rest shape in its own frame, moved by tf.
      const auto pose = demoKinematicPose(kind, object.name, time_s);
      messages.frames.transforms.push_back(toTransformStamped(
          pose.value_or(Eigen::Isometry3d::Identity()), stamp, frames.fixed_frame, object.name));
    }
    if (!wanted[i]) continue;
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    cloud->header.stamp = stamp;
    cloud->header.frame_id = kinematic ? object.name : frames.cloud_frame;
    points = kinematic ? scene.body(i).restPositions() : scene.body(i).positions();
    if (!kinematic && own_cloud_frame) {
      for (auto& p : points) p = to_cloud_frame * p;
    }
    writeCloudPoints(points, *cloud);
    messages.clouds[i] = cloud;
  }
}

}  // namespace deformable_collision
