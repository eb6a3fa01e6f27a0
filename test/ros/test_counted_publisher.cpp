// CountedPublisher (rostest counted_publisher.test): its count follows subscribers in this
// process and in another (the launch file's `rostopic echo` of /counted/echoed) as they come
// and go, on the queue of the handle that advertised.
#include <gtest/gtest.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_msgs/UInt32.h>

#include <memory>
#include <vector>

#include "deformable_collision/ros/counted_publisher.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace {

using test::waitFor;
/// Counts change within milliseconds; a count that never comes fails in this time.
constexpr double kCountTimeoutS = 10.0;
using Received = boost::function<void(const std_msgs::UInt32::ConstPtr&)>;

/// A handle whose callbacks only run when the test serves its queue, as the node's cycle
/// serves its own.
class CountedPublisherTest : public ::testing::Test {
 protected:
  CountedPublisherTest() { handle_.setCallbackQueue(&queue_); }

  /// Serves the publisher's queue until its count is `count`.
  bool waitForCount(const CountedPublisher& publisher, std::uint32_t count) {
    return waitFor(
        [&] {
          queue_.callAvailable();
          return publisher.subscribers() == count;
        },
        kCountTimeoutS);
  }

  ros::CallbackQueue queue_;
  ros::NodeHandle handle_;
  ros::NodeHandle client_;
};

TEST_F(CountedPublisherTest, CountsSubscribersOfThisProcessAsTheyComeAndGo) {
  CountedPublisher publisher;
  publisher.advertise<std_msgs::UInt32>(handle_, "/counted/local", 1);
  std::vector<std::uint32_t> received;
  auto subscribe = [&] {
    return client_.subscribe<std_msgs::UInt32>(
        "/counted/local", 10, Received([&received](const std_msgs::UInt32::ConstPtr& m) {
          received.push_back(m->data);
        }));
  };
  auto first = std::make_unique<ros::Subscriber>(subscribe());
  ASSERT_TRUE(waitForCount(publisher, 1));
  EXPECT_TRUE(publisher.subscribed());
  // roscpp joins the subscribers of one topic in a process into one link: still one.
  auto second = std::make_unique<ros::Subscriber>(subscribe());
  std_msgs::UInt32 message;
  message.data = 7;
  publisher.publish(message);
  ASSERT_TRUE(waitFor([&] { return received.size() == 2; }));
  first.reset();
  queue_.callAvailable();
  EXPECT_EQ(publisher.subscribers(), 1u);
  publisher.publish(message);
  EXPECT_TRUE(waitFor([&] { return received.size() == 3; }));

  second.reset();
  ASSERT_TRUE(waitForCount(publisher, 0));
  EXPECT_FALSE(publisher.subscribed());
  // A subscriber after all had gone is counted again.
  second = std::make_unique<ros::Subscriber>(subscribe());
  EXPECT_TRUE(waitForCount(publisher, 1));
}

TEST_F(CountedPublisherTest, CountsASubscriberOfAnotherProcessWithThoseOfThisOne) {
  CountedPublisher publisher;
  publisher.advertise<std_msgs::UInt32>(handle_, "/counted/echoed", 1);
  ASSERT_TRUE(waitForCount(publisher, 1)) << "rostopic echo did not subscribe";
  auto local = std::make_unique<ros::Subscriber>(client_.subscribe<std_msgs::UInt32>(
      "/counted/echoed", 1, Received([](const std_msgs::UInt32::ConstPtr&) {})));
  ASSERT_TRUE(waitForCount(publisher, 2));
  local.reset();
  EXPECT_TRUE(waitForCount(publisher, 1));
}

TEST_F(CountedPublisherTest, CountsNothingWhileItsQueueIsNotServed) {
  CountedPublisher publisher;
  publisher.advertise<std_msgs::UInt32>(handle_, "/counted/unserved", 1);
  ros::Subscriber subscriber = client_.subscribe<std_msgs::UInt32>(
      "/counted/unserved", 1, Received([](const std_msgs::UInt32::ConstPtr&) {}));
  // The connection is made by roscpp's threads; its callback waits for the queue.
  ASSERT_TRUE(waitFor([&] { return !queue_.isEmpty(); }));
  EXPECT_EQ(publisher.subscribers(), 0u);
  EXPECT_TRUE(waitForCount(publisher, 1));
}

}  // namespace
}  // namespace deformable_collision

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "counted_publisher_test");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
