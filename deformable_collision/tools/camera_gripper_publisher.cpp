#include "deformable_collision/tools/camera_gripper_publisher.h"

#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_ros/transform_broadcaster.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <optional>
#include <string>

#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/model_file.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "deformable_collision/scenes/camera_gripper_scene.h"

namespace deformable_collision {
namespace {

constexpr const char* kCameraFrame = "camera_optical";
/// The model file stores float32: its points match the ground truth to their rounding.
constexpr double kModelFileToleranceM = 1e-6;
constexpr int kDefaultModelPoints = 8000;

struct CameraPublisherParams {
  CameraGripperConfig scene;
  double rate_hz = 10.0;
  std::string fixed_frame;
  std::string model_file;
  std::string write_model;
};

std::optional<CameraPublisherParams> readCameraParams(const ros::NodeHandle& handle) {
  CameraPublisherParams params;
  // 0, as the demo passes by default, is the count the model file holds.
  int points = handle.param("points", 0);
  if (points == 0) points = kDefaultModelPoints;
  params.scene.camera.width_px = handle.param("camera_width_px", 320);
  params.scene.camera.height_px = handle.param("camera_height_px", 240);
  params.scene.camera.horizontal_fov_rad = 1.0;  // about a Kinect's or a RealSense's
  params.scene.camera.noise_m = handle.param("camera_noise_m", 0.001);
  params.scene.camera.dropout_ratio = handle.param("camera_dropout", 0.02);
  params.rate_hz = handle.param("rate_hz", 10.0);
  params.fixed_frame = handle.param<std::string>("fixed_frame", "world");
  params.model_file = handle.param<std::string>("model_file", "");
  params.write_model = handle.param<std::string>("write_model", "");
  if (points < 100 || !(params.rate_hz >= 1.0 && params.rate_hz <= 60.0)) {
    ROS_FATAL("~points = %d must be >= 100 and ~rate_hz = %g in [1, 60]", points, params.rate_hz);
    return std::nullopt;
  }
  params.scene.sponge.points = static_cast<std::size_t>(points);
  return params;
}

/// The camera's image as an organized cloud: height rows of width points, NaN holes.
void writeOrganizedCloud(const std::vector<Eigen::Vector3f>& points, int width, int height,
                         sensor_msgs::PointCloud2& cloud) {
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(1, "xyz");
  modifier.resize(static_cast<std::size_t>(width) * height);
  cloud.width = static_cast<std::uint32_t>(width);
  cloud.height = static_cast<std::uint32_t>(height);
  cloud.row_step = cloud.width * cloud.point_step;
  cloud.is_dense = false;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (const auto& p : points) {
    *x = p.x();
    *y = p.y();
    *z = p.z();
    ++x, ++y, ++z;
  }
}

/// The ground truth: the model's points in order, each with its `visible` flag.
void writeGroundTruth(const std::vector<Eigen::Vector3d>& points,
                      const std::vector<std::uint8_t>& visible, sensor_msgs::PointCloud2& cloud) {
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2Fields(
      4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32, "z", 1,
      sensor_msgs::PointField::FLOAT32, "visible", 1, sensor_msgs::PointField::FLOAT32);
  modifier.resize(points.size());
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"),
      seen(cloud, "visible");
  for (std::size_t i = 0; i < points.size(); ++i, ++x, ++y, ++z, ++seen) {
    *x = static_cast<float>(points[i].x());
    *y = static_cast<float>(points[i].y());
    *z = static_cast<float>(points[i].z());
    *seen = visible[i] ? 1.0f : 0.0f;
  }
}

/// False, after saying why, when `path` does not hold the scene's rest model in order.
bool modelFileMatches(const std::string& path, const CameraGripperScene& scene) {
  const std::vector<Eigen::Vector3d> expected = scene.restModel();
  std::vector<Eigen::Vector3d> read;
  try {
    read = readModelFile(path);
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("~model_file: %s", e.what());
    return false;
  }
  double largest_m = 0.0;
  if (read.size() == expected.size()) {
    for (std::size_t i = 0; i < read.size(); ++i) {
      largest_m = std::max(largest_m, (read[i] - expected[i]).norm());
    }
  }
  if (read.size() != expected.size() || largest_m > kModelFileToleranceM) {
    ROS_FATAL(
        "~model_file %s holds %zu points, %g m from the scene's %zu rest points of "
        "~points: the ground truth would not be in its order",
        path.c_str(), read.size(), largest_m, expected.size());
    return false;
  }
  return true;
}

/// Publishes the clouds that do not change (floor, jaws) to whoever subscribed.
void publishFixedClouds(const CameraGripperScene& scene, const CameraPublisherParams& params,
                        const ros::Time& stamp, ros::Publisher& floor, ros::Publisher (&jaws)[2]) {
  const char* jaw_names[2] = {"jaw_left", "jaw_right"};
  for (int k = 0; k < 2; ++k) {
    if (jaws[k].getNumSubscribers() == 0) continue;
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    cloud->header.stamp = stamp;
    cloud->header.frame_id = jaw_names[k];
    writeCloudPoints(scene.jawPoints(), *cloud);
    jaws[k].publish(cloud);
  }
  if (floor.getNumSubscribers() == 0) return;
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header.stamp = stamp;
  cloud->header.frame_id = params.fixed_frame;
  writeCloudPoints(scene.floorPoints(), *cloud);
  floor.publish(cloud);
}

/// The camera's and the jaws' frames at `time_s`, stamped `now`: sent before the clouds, so
/// that a listener can place the clouds as soon as they arrive.
void publishFrames(const CameraGripperScene& scene, const std::string& fixed_frame, double time_s,
                   const ros::Time& now, tf2_ros::TransformBroadcaster& broadcaster) {
  broadcaster.sendTransform(
      toTransformStamped(scene.cameraPose(time_s), now, fixed_frame, kCameraFrame));
  broadcaster.sendTransform(
      toTransformStamped(scene.jawPose(JawSide::kLeft, time_s), now, fixed_frame, "jaw_left"));
  broadcaster.sendTransform(
      toTransformStamped(scene.jawPose(JawSide::kRight, time_s), now, fixed_frame, "jaw_right"));
}

/// The camera's organized cloud of the sponge and the sponge's ground truth, as rendered.
void publishCameraClouds(const CameraGripperScene& scene, const CameraPublisherParams& params,
                         const ros::Time& now, ros::Publisher& camera_cloud,
                         ros::Publisher& ground_truth) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header.stamp = now;
  cloud->header.frame_id = kCameraFrame;
  writeOrganizedCloud(scene.cloud(), params.scene.camera.width_px, params.scene.camera.height_px,
                      *cloud);
  camera_cloud.publish(cloud);
  auto truth = boost::make_shared<sensor_msgs::PointCloud2>();
  truth->header.stamp = now;
  truth->header.frame_id = params.fixed_frame;
  writeGroundTruth(scene.groundTruth(), scene.groundTruthVisible(), *truth);
  ground_truth.publish(truth);
}

}  // namespace

int runCameraGripperPublisher(ros::NodeHandle& node_handle, const ros::NodeHandle& private_handle) {
  const std::optional<CameraPublisherParams> params = readCameraParams(private_handle);
  if (!params) return 1;
  std::optional<CameraGripperScene> scene;
  try {
    scene.emplace(params->scene);
    if (!params->write_model.empty()) {
      writeModelFile(params->write_model, scene->restModel());
      ROS_INFO("wrote the sponge's %zu rest points to %s", scene->restModel().size(),
               params->write_model.c_str());
      return 0;
    }
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("scene %s: %s", kCameraGripperSceneName, e.what());
    return 1;
  }
  if (!params->model_file.empty() && !modelFileMatches(params->model_file, *scene)) return 1;

  ros::Publisher camera_cloud = node_handle.advertise<sensor_msgs::PointCloud2>("sponge/points", 2);
  ros::Publisher ground_truth =
      node_handle.advertise<sensor_msgs::PointCloud2>("ground_truth/sponge", 2);
  ros::Publisher floor = node_handle.advertise<sensor_msgs::PointCloud2>("floor/points", 2);
  ros::Publisher jaws[2] = {node_handle.advertise<sensor_msgs::PointCloud2>("jaw_left/points", 2),
                            node_handle.advertise<sensor_msgs::PointCloud2>("jaw_right/points", 2)};
  tf2_ros::TransformBroadcaster broadcaster;
  const auto& camera = params->scene.camera;
  ROS_INFO(
      "scene_publisher: scene %s, %zu model points, camera %d x %d, noise %g m, dropout %g, "
      "%.1f Hz",
      kCameraGripperSceneName, params->scene.sponge.points, camera.width_px, camera.height_px,
      camera.noise_m, camera.dropout_ratio, params->rate_hz);

  const ros::Time start = ros::Time::now();
  ros::Rate rate(params->rate_hz);
  while (ros::ok()) {
    const ros::Time now = ros::Time::now();
    const double time_s = (now - start).toSec();
    scene->render(time_s);
    publishFrames(*scene, params->fixed_frame, time_s, now, broadcaster);
    publishCameraClouds(*scene, *params, now, camera_cloud, ground_truth);
    publishFixedClouds(*scene, *params, now, floor, jaws);
    ros::spinOnce();
    rate.sleep();
  }
  return 0;
}

}  // namespace deformable_collision
