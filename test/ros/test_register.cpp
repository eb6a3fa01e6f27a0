// on_cloud: register in a nodelet (rostest register.test): a box whose model the test writes
// to a PLY file, or takes from the first cloud, moves rigidly while a depth camera circling
// it renders organized, noisy clouds with holes, published through tf from the camera's
// moving frame; ~deformed/box must follow the box's true motion, ~stats must report the
// registrations, and clouds that do not show the box must hold the model. Every wait is on
// an event with a timeout.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <unistd.h>

#include "deformable_collision/Stats.h"
#include "deformable_collision/ros/cloud_transform.h"
#include "deformable_collision/ros/deformable_collision_node.h"
#include "deformable_collision/ros/model_file.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

using sensor_msgs::PointCloud2;

const std::string kManager = "/register_manager";
const std::string kNode = "/register_node";
/// The clouds' frame: identity under test_camera, whose pose moves every frame.
const std::string kCameraOpticalFrame = "test_camera_optical";
/// The box's half extents: 8 x 5 x 3 cm, no two alike, so that every rotation shows.
const Eigen::Vector3d kHalfExtents(0.04, 0.025, 0.015);
constexpr int kFrames = 30;
/// Depth camera: 160 x 120 pixels, 2.9 mm per pixel at the box's 0.4 m.
constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr double kFocalPx = 140.0;
constexpr double kNoiseM = 0.001;
constexpr double kDropout = 0.05;
/// Tolerances of the registered model against the box's true pose, every model point
/// (seen and hidden side), after every frame.
constexpr double kMeanErrorM = 0.001;
constexpr double kMaxErrorM = 0.002;
/// The same for a model taken from the first cloud: one noisy view of three faces, without
/// the hidden ones. Measured 0.88 and 1.95 mm at worst over the 30 frames.
constexpr double kFirstCloudMeanErrorM = 0.0015;
constexpr double kFirstCloudMaxErrorM = 0.003;

/// The box's surface every 4 mm, in its own frame: the model file's points.
Points boxModel() {
  Points points;
  const Eigen::Vector3d& h = kHalfExtents;
  const double step = 0.004;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const int nu = static_cast<int>(std::round(2 * h[u] / step));
    const int nv = static_cast<int>(std::round(2 * h[v] / step));
    for (const double side : {-1.0, 1.0}) {
      // Edges belong to the faces of the lower axes, so that no point is written twice.
      for (int i = (u < axis ? 1 : 0); i <= nu - (u < axis ? 1 : 0); ++i) {
        for (int j = (v < axis ? 1 : 0); j <= nv - (v < axis ? 1 : 0); ++j) {
          Eigen::Vector3d p;
          p[axis] = side * h[axis];
          p[u] = -h[u] + i * 2 * h[u] / nu;
          p[v] = -h[v] + j * 2 * h[v] / nv;
          points.push_back(p);
        }
      }
    }
  }
  return points;
}

/// The box's true pose in the world at frame k: it slides 1.5 mm and turns 1 degree about
/// z and 0.5 degree about x per frame.
Eigen::Isometry3d boxPose(int k) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.0015 * k, 0.0008 * k, 0.05);
  pose.linear() = (Eigen::AngleAxisd(k * M_PI / 180.0, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(0.5 * k * M_PI / 180.0, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  return pose;
}

/// The camera's optical frame (z ahead, x right, y down) in the world at frame k: 0.4 m
/// from the box's start, above it, circling it by 1.5 degrees a frame from a corner's view
/// (the top and two sides): a box seen on two faces alone cannot show a slide along both.
Eigen::Isometry3d cameraPose(int k) {
  const double azimuth = (45.0 + k * 1.5) * M_PI / 180.0;
  const Eigen::Vector3d target(0.0, 0.0, 0.05);
  const Eigen::Vector3d eye =
      target + 0.4 * Eigen::Vector3d(std::cos(azimuth) * 0.8, std::sin(azimuth) * 0.8, 0.6);
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = z.cross(x);
  pose.linear().col(2) = z;
  pose.translation() = eye;
  return pose;
}

std::size_t finitePoints(const PointCloud2& cloud) {
  Points finite;
  EXPECT_TRUE(readCloudPoints(cloud, NonFinitePoints::kDrop, 1 << 20, finite).ok());
  return finite.size();
}

/// Distance along a ray (origin and direction in the box's frame) to the box, if it hits.
std::optional<double> rayHitsBox(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  double near = 0.0, far = std::numeric_limits<double>::infinity();
  for (int axis = 0; axis < 3; ++axis) {
    const double inverse = 1.0 / direction[axis];
    double t0 = (-kHalfExtents[axis] - origin[axis]) * inverse;
    double t1 = (kHalfExtents[axis] - origin[axis]) * inverse;
    if (t0 > t1) std::swap(t0, t1);
    near = std::max(near, t0);
    far = std::min(far, t1);
  }
  if (near > far) return std::nullopt;
  return near;
}

/// What the depth camera at `camera` sees of a box at `box`: an organized cloud in the
/// camera's frame, NaN where no box is or a pixel dropped out, depth noise along the ray.
PointCloud2 renderDepth(const Eigen::Isometry3d& camera, const Eigen::Isometry3d& box,
                        std::mt19937& random) {
  std::normal_distribution<double> noise(0.0, kNoiseM);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Eigen::Isometry3d camera_in_box = box.inverse() * camera;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Points pixels(static_cast<std::size_t>(kWidth) * kHeight, Eigen::Vector3d::Constant(nan));
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const Eigen::Vector3d ray =
          Eigen::Vector3d((u - kWidth / 2.0) / kFocalPx, (v - kHeight / 2.0) / kFocalPx, 1.0)
              .normalized();
      const std::optional<double> hit =
          rayHitsBox(camera_in_box.translation(), camera_in_box.linear() * ray);
      if (!hit || uniform(random) < kDropout) continue;
      pixels[static_cast<std::size_t>(v) * kWidth + u] = (*hit + noise(random)) * ray;
    }
  }
  PointCloud2 cloud;
  writeCloudPoints(pixels, cloud);
  cloud.height = kHeight;
  cloud.width = kWidth;
  cloud.row_step = cloud.point_step * kWidth;
  cloud.is_dense = false;
  return cloud;
}

struct ModelError {
  double mean_m = 0.0;
  double max_m = 0.0;
};

ModelError errorAgainst(const Points& published, const Points& truth) {
  ModelError error;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const double distance = (published[i] - truth[i]).norm();
    error.mean_m += distance / truth.size();
    error.max_m = std::max(error.max_m, distance);
  }
  return error;
}

/// The node's parameters: the box from `model_file` placed at frame box_start, or without
/// one from its first cloud, seen on `topic`.
XmlRpc::XmlRpcValue nodeParams(const std::string& topic,
                               const std::optional<std::string>& model_file) {
  XmlRpc::XmlRpcValue params;
  params["fixed_frame"] = "world";
  params["rate_hz"] = 50;
  params["contact_distance_m"] = 0.005;
  params["tf_wait_s"] = 2.0;
  params["register"]["iterations"] = 5;
  params["register"]["max_correspondence_m"] = 0.01;
  XmlRpc::XmlRpcValue& box = params["objects"][0];
  box["name"] = "box";
  box["topic"] = topic;
  box["dynamic"] = false;
  box["on_cloud"] = "register";
  box["mode"] = "linear";
  box["clusters"] = 4;
  if (model_file) {
    box["model_file"] = *model_file;
    box["model_frame"] = "box_start";
  }
  return params;
}

/// tf's topics, published as its broadcasters do, for all the tests. Advertised again by each
/// test, a publisher went while the manager kept its subscription (the earlier tests'
/// nodelets stay loaded): roscpp reconnected that subscription to the next test's publisher
/// by itself, and the master's late word that the old one had gone then dropped the
/// connection the test had waited for, so a camera pose sent then was lost and its cloud
/// rejected after tf_wait_s. A nodelet loaded later shares its manager's subscription.
class TfEnvironment : public ::testing::Environment {
 public:
  void SetUp() override {
    ros::NodeHandle handle;
    tf_ = handle.advertise<tf2_msgs::TFMessage>("/tf", 100);
    static_tf_ = handle.advertise<tf2_msgs::TFMessage>("/tf_static", 100, true);
  }
  void TearDown() override {
    tf_.shutdown();
    static_tf_.shutdown();
  }

  const ros::Publisher& tf() const { return tf_; }
  const ros::Publisher& staticTf() const { return static_tf_; }

  /// Adds `transform` to the latched static ones, replacing one of the same child frame, as
  /// tf2_ros's static broadcaster does.
  void sendStatic(const geometry_msgs::TransformStamped& transform) {
    auto& transforms = static_transforms_.transforms;
    transforms.erase(std::remove_if(transforms.begin(), transforms.end(),
                                    [&](const geometry_msgs::TransformStamped& t) {
                                      return t.child_frame_id == transform.child_frame_id;
                                    }),
                     transforms.end());
    transforms.push_back(transform);
    static_tf_.publish(static_transforms_);
  }

 private:
  ros::Publisher tf_;
  ros::Publisher static_tf_;
  tf2_msgs::TFMessage static_transforms_;
};

TfEnvironment* tf_environment = nullptr;  ///< Owned by gtest, set in main().

class RegisterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char directory[] = "/tmp/test_register_XXXXXX";
    ASSERT_NE(::mkdtemp(directory), nullptr);
    directory_ = directory;
    model_file_ = directory_ + "/box.ply";
    writeModelFile(model_file_, model_);
  }
  void TearDown() override {
    ::unlink(model_file_.c_str());
    ::rmdir(directory_.c_str());
  }

  /// Loads nodelet `node` seeing the camera on `topic` and waits until it is connected.
  void connectNode(const std::string& node, const std::string& topic,
                   const XmlRpc::XmlRpcValue& params) {
    camera_publisher_ = handle_.advertise<PointCloud2>(topic, 4);
    deformed_subscriber_ = handle_.subscribe<PointCloud2>(
        node + "/deformed/box", 10,
        boost::function<void(const PointCloud2::ConstPtr&)>(
            [this](const PointCloud2::ConstPtr& cloud) { deformed_ = cloud; }));
    stats_subscriber_ = handle_.subscribe<Stats>(
        node + "/stats", 100,
        boost::function<void(const Stats::ConstPtr&)>([this](const Stats::ConstPtr& stats) {
          if (stats->input_latency_ms > 0.0) applied_ = stats;
          last_stats_ = stats;
        }));
    // As a camera driver does, the optical frame hangs static under the moving camera: tf
    // then knows the clouds' frame from the node's start, and a cloud that comes before its
    // camera's pose waits for it instead of being dropped as in a frame tf does not know.
    tf_environment->sendStatic(toTransformStamped(Eigen::Isometry3d::Identity(), ros::Time::now(),
                                                  "test_camera", kCameraOpticalFrame));
    ASSERT_TRUE(loadNodelet(kManager, node, params)) << "the nodelet did not start";
    ASSERT_TRUE(waitFor([this] {
      return last_stats_ && camera_publisher_.getNumSubscribers() > 0 &&
             deformed_subscriber_.getNumPublishers() > 0 &&
             tf_environment->tf().getNumSubscribers() > 0 &&
             tf_environment->staticTf().getNumSubscribers() > 0;
    })) << "the nodelet did not connect";
  }

  /// Starts the node with the model file, then places the model's frame: the model waits
  /// for it.
  void startNode() {
    const std::string topic = "/register_test/camera_points";
    ASSERT_NO_FATAL_FAILURE(connectNode(kNode, topic, nodeParams(topic, model_file_)));
    EXPECT_EQ(last_stats_->objects, 0u) << "the model's frame is not known yet";
    tf_environment->sendStatic(
        toTransformStamped(boxPose(0), ros::Time::now(), "world", "box_start"));
    ASSERT_TRUE(waitFor([this] { return last_stats_->objects == 1u; }))
        << "the model was not placed once its frame came";
  }

  /// Publishes the camera's frame and its cloud with one stamp, and waits for the cycle that
  /// registered it; returns the model as ~deformed/box published it then.
  Points publishAndWait(const Eigen::Isometry3d& camera, PointCloud2 cloud) {
    const ros::Time stamp = ros::Time::now();
    tf2_msgs::TFMessage camera_pose;
    camera_pose.transforms.push_back(toTransformStamped(camera, stamp, "world", "test_camera"));
    tf_environment->tf().publish(camera_pose);
    cloud.header.frame_id = kCameraOpticalFrame;
    cloud.header.stamp = stamp;
    const std::uint64_t received = last_stats_->clouds_received;
    applied_.reset();
    camera_publisher_.publish(cloud);
    const bool registered = waitFor([&] {
      return applied_ && applied_->clouds_received > received && deformed_ &&
             deformed_->header.stamp >= applied_->header.stamp;
    });
    EXPECT_TRUE(registered) << "no cycle registered the cloud";
    EXPECT_EQ(last_stats_->clouds_rejected, 0u);
    Points published;
    if (registered) {
      EXPECT_TRUE(
          readCloudPoints(*deformed_, NonFinitePoints::kKeepAsNaN, 1 << 20, published).ok());
    }
    return published;
  }

  const RegistrationStats& registration() const { return applied_->registrations.at(0); }

  ros::NodeHandle handle_;
  ros::Publisher camera_publisher_;
  ros::Subscriber deformed_subscriber_;
  ros::Subscriber stats_subscriber_;
  PointCloud2::ConstPtr deformed_;
  Stats::ConstPtr applied_;  ///< The last stats of a cycle that applied a cloud.
  Stats::ConstPtr last_stats_;
  const Points model_ = boxModel();
  std::string directory_;
  std::string model_file_;
  std::mt19937 random_{20};
};

TEST_F(RegisterTest, FollowsTheBoxFromAMovingCameraAndHoldsOnCloudsWithoutIt) {
  ASSERT_NO_FATAL_FAILURE(startNode());
  ModelError worst;
  double registrations_ms = 0.0;
  for (int k = 1; k <= kFrames; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const PointCloud2 cloud = renderDepth(cameraPose(k), boxPose(k), random_);
    const Points published = publishAndWait(cameraPose(k), cloud);
    ASSERT_EQ(published.size(), model_.size()) << "the model's points, in the file's order";
    Points truth = model_;
    for (Eigen::Vector3d& p : truth) p = boxPose(k) * p;
    const ModelError error = errorAgainst(published, truth);
    worst.mean_m = std::max(worst.mean_m, error.mean_m);
    worst.max_m = std::max(worst.max_m, error.max_m);
    EXPECT_LE(error.mean_m, kMeanErrorM);
    EXPECT_LE(error.max_m, kMaxErrorM);
    ASSERT_EQ(applied_->registrations.size(), 1u);
    EXPECT_EQ(registration().object, "box");
    EXPECT_FALSE(registration().held);
    EXPECT_GT(registration().used_points, 0u);
    EXPECT_EQ(registration().cloud_points, finitePoints(cloud));
    // Fewer points than max_cloud_points: none thinned out.
    EXPECT_EQ(registration().used_points + registration().rejected_points,
              registration().cloud_points);
    EXPECT_GE(registration().max_residual_m, registration().mean_residual_m);
    EXPECT_LT(registration().mean_residual_m, 0.003);
    // The estimate: the RMS residual on the seen side, more on the hidden side.
    EXPECT_GE(registration().seen_error_m, registration().mean_residual_m);
    EXPECT_GE(registration().hidden_error_m, registration().seen_error_m);
    EXPECT_LT(registration().hidden_error_m, 0.01);
    EXPECT_EQ(registration().clouds_held, 0u);
    registrations_ms += registration().time_ms;
  }
  // The reader thread registers the clouds: its time on clouds holds every registration's.
  EXPECT_GE(1e3 * applied_->reader_busy_s, registrations_ms);
  std::printf(
      "[ MEASURED ] model against the true box over %d frames: worst mean %.2f mm, "
      "worst max %.2f mm; last cloud %u finite points, %u used, %u rejected, "
      "residual mean %.2f mm max %.2f mm, %.2f ms\n",
      kFrames, 1e3 * worst.mean_m, 1e3 * worst.max_m, registration().cloud_points,
      registration().used_points, registration().rejected_points,
      1e3 * registration().mean_residual_m, 1e3 * registration().max_residual_m,
      registration().time_ms);

  // Clouds that do not show the box: every pixel a hole (the box out of sight), and a box
  // 0.12 m beside it (another object, in view, 4 cm from the box at the closest). The model
  // stays where it was, and ~stats says so.
  const Eigen::Isometry3d camera = cameraPose(kFrames);
  const Points held_at = publishAndWait(camera, renderDepth(camera, boxPose(kFrames), random_));
  Eigen::Isometry3d beside = boxPose(kFrames);
  beside.translation() += 0.12 * camera.linear().col(0);
  const Eigen::Isometry3d out_of_sight(Eigen::Translation3d(0.0, 0.0, 100.0));
  const std::vector<PointCloud2> misses = {renderDepth(camera, out_of_sight, random_),
                                           renderDepth(camera, beside, random_)};
  ASSERT_EQ(finitePoints(misses[0]), 0u);
  ASSERT_GT(finitePoints(misses[1]), 100u) << "the other box is in view";
  std::uint64_t held = 0;
  for (const PointCloud2& miss : misses) {
    const Points published = publishAndWait(camera, miss);
    ASSERT_EQ(published, held_at) << "a held cloud leaves the model where it was";
    EXPECT_TRUE(registration().held);
    EXPECT_EQ(registration().clouds_held, ++held);
  }
  const Points back = publishAndWait(camera, renderDepth(camera, boxPose(kFrames), random_));
  EXPECT_FALSE(registration().held);
  EXPECT_EQ(registration().clouds_held, held);
  Points truth = model_;
  for (Eigen::Vector3d& p : truth) p = boxPose(kFrames) * p;
  EXPECT_LE(errorAgainst(back, truth).mean_m, kMeanErrorM);
}

TEST_F(RegisterTest, WithoutAModelFileTheFirstCloudIsTheModelAndLaterCloudsMoveIt) {
  const std::string topic = "/register_first_cloud/camera_points";
  ASSERT_NO_FATAL_FAILURE(
      connectNode("/register_first_cloud", topic, nodeParams(topic, std::nullopt)));
  EXPECT_EQ(last_stats_->objects, 0u) << "no model before the first cloud";
  const PointCloud2 first_cloud = renderDepth(cameraPose(0), boxPose(0), random_);
  const Points model = publishAndWait(cameraPose(0), first_cloud);
  EXPECT_EQ(last_stats_->objects, 1u);
  ASSERT_EQ(model.size(), finitePoints(first_cloud)) << "the first cloud's finite points";
  Points first_in_world;
  ASSERT_TRUE(readCloudPoints(first_cloud, NonFinitePoints::kDrop, 1 << 20, first_in_world).ok());
  for (Eigen::Vector3d& p : first_in_world) p = cameraPose(0) * p;
  EXPECT_LE(errorAgainst(model, first_in_world).max_m, 1e-6) << "in the cloud's order";
  // The model is one noisy view of three faces; each point must move with the box.
  ModelError worst;
  for (int k = 1; k <= kFrames; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const Points published =
        publishAndWait(cameraPose(k), renderDepth(cameraPose(k), boxPose(k), random_));
    ASSERT_EQ(published.size(), model.size());
    Points truth = model;
    for (Eigen::Vector3d& p : truth) p = boxPose(k) * boxPose(0).inverse() * p;
    const ModelError error = errorAgainst(published, truth);
    worst.mean_m = std::max(worst.mean_m, error.mean_m);
    worst.max_m = std::max(worst.max_m, error.max_m);
    EXPECT_LE(error.mean_m, kFirstCloudMeanErrorM);
    EXPECT_LE(error.max_m, kFirstCloudMaxErrorM);
    ASSERT_EQ(applied_->registrations.size(), 1u);
    EXPECT_FALSE(registration().held);
  }
  std::printf(
      "[ MEASURED ] first-cloud model against the true motion over %d frames: worst mean "
      "%.2f mm, worst max %.2f mm\n",
      kFrames, 1e3 * worst.mean_m, 1e3 * worst.max_m);
}

TEST_F(RegisterTest, AMissingModelFileStopsTheNodeAtStartNamingObjectAndPath) {
  const std::string missing = directory_ + "/missing.ply";
  ros::param::set("/register_bad_model", nodeParams("/register_test/camera_points", missing));
  try {
    DeformableCollisionNode node(ros::NodeHandle(), ros::NodeHandle("/register_bad_model"));
    FAIL() << "started";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "object 'box': model file '" + missing + "': no such file");
  }
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "register_test_client");
  ros::NodeHandle keep_alive;
  deformable_collision::test::tf_environment = new deformable_collision::test::TfEnvironment;
  testing::AddGlobalTestEnvironment(deformable_collision::test::tf_environment);
  return RUN_ALL_TESTS();
}
