// PublishQueue: every message published, in the order posted, on the queue's own thread;
// a full queue makes the poster wait instead of dropping; a message is let go once
// published; stop() publishes what is queued. Runs under ThreadSanitizer too.
#include "deformable_collision/ros/publish_queue.h"

#include <gtest/gtest.h>

#include <boost/make_shared.hpp>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace deformable_collision {
namespace {

struct Cloud {
  int sequence;
};
struct Markers {
  std::string name;
};

/// Records what it is asked to publish, from whichever thread asks, as "topic:content".
class FakePublisher {
 public:
  FakePublisher(std::string topic, std::vector<std::string>& log, std::mutex& mutex,
                std::chrono::microseconds delay = {})
      : topic_(std::move(topic)), log_(log), mutex_(mutex), delay_(delay) {}

  void publish(const boost::shared_ptr<Cloud>& cloud) const {
    record(std::to_string(cloud->sequence));
  }
  void publish(const boost::shared_ptr<Markers>& markers) const { record(markers->name); }

  std::thread::id lastThread() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_thread_;
  }

 private:
  void record(const std::string& content) const {
    std::this_thread::sleep_for(delay_);
    std::lock_guard<std::mutex> lock(mutex_);
    log_.push_back(topic_ + ":" + content);
    last_thread_ = std::this_thread::get_id();
  }

  std::string topic_;
  std::vector<std::string>& log_;
  std::mutex& mutex_;
  std::chrono::microseconds delay_;
  mutable std::thread::id last_thread_;
};

class PublishQueueTest : public ::testing::Test {
 protected:
  /// What the fake publishers recorded.
  std::vector<std::string> published() {
    std::lock_guard<std::mutex> lock(mutex);
    return log;
  }

  std::vector<std::string> log;
  std::mutex mutex;
};

TEST_F(PublishQueueTest, PublishesEveryMessageInOrderOnItsOwnThread) {
  FakePublisher clouds("clouds", log, mutex);
  FakePublisher markers("markers", log, mutex);
  PublishQueue<FakePublisher> queue(8);
  std::vector<std::string> expected;
  for (int cycle = 0; cycle < 50; ++cycle) {
    queue.post(markers, boost::make_shared<Markers>(Markers{"m" + std::to_string(cycle)}));
    expected.push_back("markers:m" + std::to_string(cycle));
    for (int object = 0; object < 3; ++object) {
      queue.post(clouds, boost::make_shared<Cloud>(Cloud{cycle * 3 + object}));
      expected.push_back("clouds:" + std::to_string(cycle * 3 + object));
    }
  }
  queue.drain();
  EXPECT_NE(clouds.lastThread(), std::this_thread::get_id());
  EXPECT_EQ(published(), expected);
}

TEST_F(PublishQueueTest, AFullQueueMakesThePosterWaitAndDropsNothing) {
  FakePublisher slow("slow", log, mutex, std::chrono::milliseconds(2));
  PublishQueue<FakePublisher> queue(2);
  for (int i = 0; i < 20; ++i) queue.post(slow, boost::make_shared<Cloud>(Cloud{i}));
  queue.drain();
  EXPECT_GT(queue.fullWaits(), 0u);
  const std::vector<std::string> done = published();
  ASSERT_EQ(done.size(), 20u);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(done[i], "slow:" + std::to_string(i));
}

TEST_F(PublishQueueTest, LetsAMessageGoOncePublished) {
  FakePublisher clouds("clouds", log, mutex);
  PublishQueue<FakePublisher> queue(4);
  const auto cloud = boost::make_shared<Cloud>(Cloud{7});
  queue.post(clouds, cloud);
  queue.drain();
  // The poster holds the only reference again: it may fill the message anew.
  EXPECT_EQ(cloud.use_count(), 1);
}

TEST_F(PublishQueueTest, StopPublishesWhatIsQueuedAndIgnoresLaterPosts) {
  FakePublisher slow("slow", log, mutex, std::chrono::microseconds(200));
  PublishQueue<FakePublisher> queue(16);
  for (int i = 0; i < 10; ++i) queue.post(slow, boost::make_shared<Cloud>(Cloud{i}));
  queue.stop();
  queue.post(slow, boost::make_shared<Cloud>(Cloud{10}));
  queue.stop();
  EXPECT_EQ(published().size(), 10u);
}

TEST(PublishQueue, RefusesNoSlots) {
  EXPECT_THROW(PublishQueue<FakePublisher>(0), std::invalid_argument);
}

}  // namespace
}  // namespace deformable_collision
