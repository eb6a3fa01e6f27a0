#pragma once

#include <ros/node_handle.h>

namespace deformable_collision {

inline constexpr const char* kCameraGripperSceneName = "camera_gripper";

/// Publishes scene camera_gripper (deformable_collision/scenes/camera_gripper_scene.h) until
/// ROS shuts down, at ~rate_hz:
/// - sponge/points: the depth camera's organized cloud (frame camera_optical; FLOAT32 x y z;
///   NaN where nothing was hit, where the camera dropped the pixel and outside the crop box
///   around the sponge, which keeps a few % of jaw points as outliers);
/// - ground_truth/sponge: the sponge's points in ~fixed_frame in model order, with the same
///   stamp, and a FLOAT32 field `visible` (1: the camera sees the point, 0: hidden);
/// - floor/points (~fixed_frame), jaw_left/points and jaw_right/points (their own frames);
/// - tf: camera_optical (sweeping along an arc over the sponge), jaw_left and jaw_right in
///   ~fixed_frame.
/// Parameters: ~points (model points; 0: 8000), ~camera_width_px (320), ~camera_height_px (240),
/// ~camera_noise_m (0.001), ~camera_dropout (0.02), ~rate_hz (10), ~fixed_frame (world);
/// ~model_file: a model file the ground truth must match in order (checked at start);
/// ~write_model: write the rest model there as a binary PLY in ~fixed_frame and exit.
/// Returns the process's exit code.
int runCameraGripperPublisher(ros::NodeHandle& node_handle, const ros::NodeHandle& private_handle);

}  // namespace deformable_collision
