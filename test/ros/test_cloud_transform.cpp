#include "deformable_collision/ros/cloud_transform.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

namespace deformable_collision {
namespace {

/// A buffer that knows `camera` in `world` at t = 10 s and t = 11 s, and a `wrist` frame
/// whose tree is not joined to the world's.
class CloudTransformTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (double t : {10.0, 11.0}) {
      geometry_msgs::TransformStamped camera;
      camera.header.stamp = ros::Time(t);
      camera.header.frame_id = "world";
      camera.child_frame_id = "camera";
      camera.transform.translation.z = t;
      camera.transform.rotation.w = 1.0;
      ASSERT_TRUE(buffer_.setTransform(camera, "test"));
    }
    geometry_msgs::TransformStamped wrist;
    wrist.header.stamp = ros::Time(10.0);
    wrist.header.frame_id = "arm";
    wrist.child_frame_id = "wrist";
    wrist.transform.rotation.w = 1.0;
    ASSERT_TRUE(buffer_.setTransform(wrist, "test"));
  }

  tf2::BufferCore buffer_;
};

TEST_F(CloudTransformTest, FindsTheTransformAtTheStamp) {
  const CloudTransformLookup lookup =
      lookUpCloudTransform(buffer_, "world", "camera", ros::Time(10.5));
  ASSERT_EQ(lookup.status, CloudTransformStatus::kFound) << lookup.error;
  EXPECT_DOUBLE_EQ(lookup.transform.translation.z, 10.5);
}

TEST_F(CloudTransformTest, AStampAfterOrBeforeTheKnownPosesIsNotYet) {
  for (double t : {12.0, 9.0}) {
    const CloudTransformLookup lookup =
        lookUpCloudTransform(buffer_, "world", "camera", ros::Time(t));
    EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet) << t;
    EXPECT_FALSE(lookup.error.empty()) << t;
  }
}

TEST_F(CloudTransformTest, AKnownFrameNotJoinedToTheTargetIsNotYet) {
  const CloudTransformLookup lookup =
      lookUpCloudTransform(buffer_, "world", "wrist", ros::Time(10.0));
  EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet);
  EXPECT_FALSE(lookup.error.empty());
}

TEST_F(CloudTransformTest, AFrameNoTransformNamesIsUnknown) {
  for (const char* frame : {"nowhere", "/camera"}) {
    const CloudTransformLookup lookup =
        lookUpCloudTransform(buffer_, "world", frame, ros::Time(10.5));
    EXPECT_EQ(lookup.status, CloudTransformStatus::kUnknownFrame) << frame;
    EXPECT_FALSE(lookup.error.empty()) << frame;
  }
}

TEST_F(CloudTransformTest, AnUnknownTargetFrameIsNotYetForAKnownCloudFrame) {
  const CloudTransformLookup lookup =
      lookUpCloudTransform(buffer_, "map", "camera", ros::Time(10.5));
  EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet);
}

TEST(CloudTransform, AnEmptyBufferKnowsNoFrame) {
  const tf2::BufferCore empty;
  EXPECT_EQ(lookUpCloudTransform(empty, "world", "camera", ros::Time(0)).status,
            CloudTransformStatus::kUnknownFrame);
}

struct FarCoordinateCase {
  const char* name;
  Eigen::Vector3d point;
  const char* problem;  ///< What the message names; empty: no problem.
};

TEST(FarCoordinateProblem, NamesTheFirstCoordinateBeyondTheBound) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const FarCoordinateCase cases[] = {
      {"near", {1.0, -2.0, 3.0}, ""},
      {"on_the_bound", {-10.0, 10.0, 0.0}, ""},
      {"unobserved", {nan, nan, nan}, ""},
      {"far_z", {0.0, 0.0, -10.5}, "point 1 has z = -10.5 m"},
      {"infinite_y", {0.0, inf, 0.0}, "point 1 has y = inf m"},
      {"one_nan_coordinate", {nan, 0.0, 0.0}, "point 1 has x = nan m"},
  };
  for (const FarCoordinateCase& c : cases) {
    const std::vector<Eigen::Vector3d> points = {Eigen::Vector3d(0.5, 0.5, 0.5), c.point};
    const std::string problem = farCoordinateProblem(points, 10.0, "camera");
    if (std::string(c.problem).empty()) {
      EXPECT_EQ(problem, "") << c.name;
    } else {
      EXPECT_NE(problem.find(c.problem), std::string::npos) << c.name << ": " << problem;
      EXPECT_NE(problem.find("'camera'"), std::string::npos) << c.name << ": " << problem;
    }
  }
}

}  // namespace
}  // namespace deformable_collision
