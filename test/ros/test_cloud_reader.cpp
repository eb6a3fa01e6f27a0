#include "deformable_collision/ros/cloud_reader.h"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <thread>

#include "deformable_collision/ros/point_cloud_conversion.h"
#include "deformable_collision/scenes/zoo_shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

constexpr std::size_t kRegistered = 4;
constexpr std::size_t kTracked = 2;
constexpr int kClouds = 6;
/// Where the registered objects' camera is in the world.
const Eigen::Vector3d kCamera(0.0, -0.45, 0.0);

NodeConfig readerConfig() {
  NodeConfig config;
  config.tf_wait_s = 5.0;
  for (std::size_t i = 0; i < kRegistered + kTracked; ++i) {
    ObjectParams object;
    object.topic = "object_" + std::to_string(i);
    object.on_cloud = i < kRegistered ? OnCloud::kRegister : OnCloud::kTrack;
    object.object.name = object.topic;
    object.object.kind = ObjectKind::kTracked;
    object.object.shape.mode = DeformationMode::kLinear;
    object.object.shape.clusters = 3;
    config.objects.push_back(object);
  }
  return config;
}

/// Object `i`'s cloud `k`: a zoo shape squeezed a little more each cloud, in the world; after
/// the first, a registered object's is the half its camera sees, in the camera's frame.
sensor_msgs::PointCloud2ConstPtr objectCloud(std::size_t i, int k, const char* frame = "world") {
  const Points rest = zooShapeSurface(kZooShapes[i % kZooShapes.size()], 1500, 3 + i).points;
  const bool seen = i < kRegistered && k > 0;
  Points points;
  for (const auto& p : rest) {
    if (seen && p.y() > 0.0) continue;
    points.emplace_back(p.x() + 0.002 * k, (1.0 - 0.01 * k) * p.y(), p.z());
    if (seen) points.back() -= kCamera;
  }
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  writeCloudPoints(points, *cloud, sensor_msgs::PointField::FLOAT64);
  cloud->header.frame_id = seen ? "camera" : frame;
  return cloud;
}

/// A reader with its own scene and slots, and the cycle's part done by the test: the first
/// cloud of a registered object is put in the scene, with its registration for the reader.
class ReaderBench {
 public:
  explicit ReaderBench(const NodeConfig& config)
      : config_(config),
        scene_(config_.scene),
        slots_(config_.objects.size()),
        handoff_(std::vector<bool>(config_.objects.size(), true)),
        reader_(config_, slots_, scene_, handoff_, tf_buffer_, [] {}),
        taken_(config_.objects.size()) {
    for (std::size_t i = 0; i < slots_.size(); ++i) slots_[i].params = config_.objects[i];
  }

  CloudReader& reader() { return reader_; }
  /// Until this, the registered objects' clouds wait for the camera's transform.
  void placeCamera() {
    geometry_msgs::TransformStamped pose;
    pose.header.frame_id = "world";
    pose.child_frame_id = "camera";
    pose.transform.translation.x = kCamera.x();
    pose.transform.translation.y = kCamera.y();
    pose.transform.translation.z = kCamera.z();
    pose.transform.rotation.w = 1.0;
    tf_buffer_.setTransform(pose, "test", true);
  }
  ObjectSlot& slot(std::size_t i) { return slots_[i]; }

  /// Reads every object's first cloud and adds the registered ones to the scene.
  void start() {
    for (std::size_t i = 0; i < slots_.size(); ++i) reader_.onCloud(objectCloud(i, 0), i);
    handoff_.takeForCycle(taken_, objects_);
    ASSERT_EQ(objects_.size(), slots_.size());
    for (const std::size_t i : objects_) {
      const std::size_t index = scene_.addObject(std::move(taken_[i].prepared));
      if (i >= kRegistered) continue;
      slots_[i].fitter.emplace(scene_.registrationFitter(index));
      slots_[i].exists = true;
    }
  }

  /// The newest fitted points of every object; fails for one not fitted.
  std::vector<Points> fitted() {
    handoff_.takeForCycle(taken_, objects_);
    std::vector<Points> points(slots_.size());
    for (const std::size_t i : objects_) {
      EXPECT_TRUE(taken_[i].fitted) << "object " << i;
      points[i] = taken_[i].points;
    }
    return points;
  }

 private:
  NodeConfig config_;
  Scene scene_;
  std::vector<ObjectSlot> slots_;
  CloudHandoff handoff_;
  tf2_ros::Buffer tf_buffer_;
  CloudReader reader_;
  std::vector<ReadCloud> taken_;
  std::vector<std::size_t> objects_;
};

class CloudReaderTest : public ::testing::Test {
 protected:
  void SetUp() override { ros::Time::init(); }
};

// The node reads each object's clouds on one of `threads` threads, in order, and the retry
// timer's callback runs on another: the fits are those of reading them all on one, also when
// the registered objects' clouds first wait for their camera's transform.
TEST_F(CloudReaderTest, ObjectsReadOnSeveralThreadsAreFittedAsOnOne) {
  const NodeConfig config = readerConfig();
  ReaderBench serial(config);
  serial.start();
  serial.placeCamera();
  for (int k = 1; k <= kClouds; ++k) {
    for (std::size_t i = 0; i < config.objects.size(); ++i) {
      serial.reader().onCloud(objectCloud(i, k), i);
    }
  }
  const std::vector<Points> expected = serial.fitted();

  ReaderBench parallel(config);
  parallel.start();
  std::atomic<bool> reading{true};
  std::thread retries([&] {
    while (reading) parallel.reader().retryAwaitingClouds();
  });
  std::vector<std::thread> objects;
  for (std::size_t i = 0; i < config.objects.size(); ++i) {
    objects.emplace_back([&, i] {
      for (int k = 1; k <= kClouds; ++k) parallel.reader().onCloud(objectCloud(i, k), i);
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  parallel.placeCamera();
  for (auto& thread : objects) thread.join();
  reading = false;
  retries.join();
  parallel.reader().retryAwaitingClouds();  // What still waits, now that tf has its pose.
  const std::vector<Points> points = parallel.fitted();
  for (std::size_t i = 0; i < config.objects.size(); ++i) {
    ASSERT_EQ(points[i].size(), expected[i].size()) << "object " << i;
    for (std::size_t p = 0; p < points[i].size(); ++p) {
      ASSERT_EQ(points[i][p], expected[i][p]) << "object " << i << ", point " << p;
    }
  }
  EXPECT_EQ(parallel.reader().cloudsRejected(), 0u);
  EXPECT_EQ(parallel.reader().cloudsReceived(), serial.reader().cloudsReceived());
}

// Another thread may read ROS time after a jump back and put its cloud in the wait before
// the jump's clouds are dropped: only the clouds from before the jump go.
TEST_F(CloudReaderTest, AJumpBackOfRosTimeDropsOnlyTheCloudsFromBeforeIt) {
  ros::Time::setNow(ros::Time(100.0));
  ReaderBench bench(readerConfig());
  bench.start();
  const std::size_t waiting = kRegistered;  // A tracked object, in a frame tf has not had.
  bench.reader().onCloud(objectCloud(waiting, 1, "camera"), waiting);
  EXPECT_EQ(bench.slot(waiting).clouds_dropped, 0u) << "tf may still be filling: it waits";

  ros::Time::setNow(ros::Time(50.0));
  bench.reader().onCloud(objectCloud(0, 1), 0);
  EXPECT_EQ(bench.slot(waiting).clouds_dropped, 1u) << "its transform was of the time before";

  bench.reader().onCloud(objectCloud(waiting, 2, "camera"), waiting);
  ros::Time::setNow(ros::Time(50.5));
  bench.reader().onCloud(objectCloud(0, 2), 0);
  EXPECT_EQ(bench.slot(waiting).clouds_dropped, 1u) << "a cloud from after the jump waits on";
  EXPECT_EQ(bench.slot(0).clouds_dropped, 0u);
}

// On sim time a cloud can come before the first /clock: its tf_wait_s starts with ROS time.
TEST_F(CloudReaderTest, ACloudFromBeforeRosTimeStartedWaitsFromItsStart) {
  ros::Time::setNow(ros::Time(0.0));
  ReaderBench bench(readerConfig());
  const std::size_t object = kRegistered;
  bench.reader().onCloud(objectCloud(object, 0, "camera"), object);
  ros::Time::setNow(ros::Time(1000.0));
  bench.reader().retryAwaitingClouds();
  ros::Time::setNow(ros::Time(1004.0));
  bench.reader().retryAwaitingClouds();
  EXPECT_EQ(bench.slot(object).clouds_dropped, 0u) << "4 s of its 5 s of tf_wait_s";
  ros::Time::setNow(ros::Time(1005.5));
  bench.reader().retryAwaitingClouds();
  EXPECT_EQ(bench.slot(object).clouds_dropped, 1u);
}

}  // namespace
}  // namespace deformable_collision
