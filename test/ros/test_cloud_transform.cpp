#include "deformable_collision/ros/cloud_transform.h"

#include <gtest/gtest.h>

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
  const CloudTransformLookup lookup = lookUpCloudTransform(buffer_, "world", "camera", ros::Time(10.5));
  ASSERT_EQ(lookup.status, CloudTransformStatus::kFound) << lookup.error;
  EXPECT_DOUBLE_EQ(lookup.transform.translation.z, 10.5);
}

TEST_F(CloudTransformTest, AStampAfterOrBeforeTheKnownPosesIsNotYet) {
  for (double t : {12.0, 9.0}) {
    const CloudTransformLookup lookup = lookUpCloudTransform(buffer_, "world", "camera", ros::Time(t));
    EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet) << t;
    EXPECT_FALSE(lookup.error.empty()) << t;
  }
}

TEST_F(CloudTransformTest, AKnownFrameNotJoinedToTheTargetIsNotYet) {
  const CloudTransformLookup lookup = lookUpCloudTransform(buffer_, "world", "wrist", ros::Time(10.0));
  EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet);
  EXPECT_FALSE(lookup.error.empty());
}

TEST_F(CloudTransformTest, AFrameNoTransformNamesIsUnknown) {
  for (const char* frame : {"nowhere", "/camera"}) {
    const CloudTransformLookup lookup = lookUpCloudTransform(buffer_, "world", frame, ros::Time(10.5));
    EXPECT_EQ(lookup.status, CloudTransformStatus::kUnknownFrame) << frame;
    EXPECT_FALSE(lookup.error.empty()) << frame;
  }
}

TEST_F(CloudTransformTest, AnUnknownTargetFrameIsNotYetForAKnownCloudFrame) {
  const CloudTransformLookup lookup = lookUpCloudTransform(buffer_, "map", "camera", ros::Time(10.5));
  EXPECT_EQ(lookup.status, CloudTransformStatus::kNotYet);
}

TEST(CloudTransform, AnEmptyBufferKnowsNoFrame) {
  const tf2::BufferCore empty;
  EXPECT_EQ(lookUpCloudTransform(empty, "world", "camera", ros::Time(0)).status,
            CloudTransformStatus::kUnknownFrame);
}

}  // namespace
}  // namespace deformable_collision
