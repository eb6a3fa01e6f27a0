#include "deformable_collision/ros/message_buffer_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "deformable_collision/ros/contact_array_serialization.h"

namespace deformable_collision {
namespace {

using Buffer = boost::shared_array<std::uint8_t>;

TEST(MessageBufferPool, RefusesToKeepNoBuffer) {
  EXPECT_THROW(MessageBufferPool(0), std::invalid_argument);
}

TEST(MessageBufferPool, AReturnedBufferServesTheNextMessage) {
  MessageBufferPool pool(1);
  EXPECT_EQ(pool.keptBuffers(), 0u);
  Buffer first = pool.acquire(10000);
  std::memset(first.get(), 0xab, 10000);
  const std::uint8_t* const address = first.get();
  first.reset();
  const Buffer second = pool.acquire(9000);
  EXPECT_EQ(second.get(), address);
  EXPECT_EQ(pool.keptBuffers(), 1u);
  EXPECT_EQ(pool.transientBuffers(), 0u);
  EXPECT_EQ(pool.replacedBuffers(), 0u);
}

TEST(MessageBufferPool, BuffersOutBeyondTheKeptOnesAreTransient) {
  MessageBufferPool pool(2);
  Buffer a = pool.acquire(5000);
  EXPECT_EQ(pool.keptBuffers(), 2u);  // both mapped at the first message
  Buffer b = pool.acquire(5000);
  const std::set<const std::uint8_t*> kept{a.get(), b.get()};
  Buffer c = pool.acquire(5000);
  std::memset(c.get(), 1, 5000);
  EXPECT_EQ(kept.count(c.get()), 0u);
  EXPECT_EQ(pool.keptBuffers(), 2u);
  EXPECT_EQ(pool.transientBuffers(), 1u);

  c.reset();  // unmapped, not kept
  a.reset();
  b.reset();
  const Buffer d = pool.acquire(5000);
  const Buffer e = pool.acquire(5000);
  EXPECT_EQ(kept, (std::set<const std::uint8_t*>{d.get(), e.get()}));
  EXPECT_EQ(pool.keptBuffers(), 2u);
  EXPECT_EQ(pool.transientBuffers(), 1u);
}

TEST(MessageBufferPool, ATooSmallBufferIsReplacedWithHeadroom) {
  MessageBufferPool pool(1);
  pool.acquire(1000).reset();
  Buffer larger = pool.acquire(100000);
  std::memset(larger.get(), 2, 100000);
  EXPECT_EQ(pool.replacedBuffers(), 1u);
  const std::uint8_t* const address = larger.get();
  larger.reset();
  // A message a fifth larger still fits the quarter of headroom.
  Buffer fifth_larger = pool.acquire(120000);
  std::memset(fifth_larger.get(), 3, 120000);
  EXPECT_EQ(fifth_larger.get(), address);
  EXPECT_EQ(pool.replacedBuffers(), 1u);
  EXPECT_EQ(pool.keptBuffers(), 1u);
}

// A larger message grows the free buffers together, and one that was out when it came grows
// with the next message after its return: then every kept buffer fits the larger messages.
TEST(MessageBufferPool, KeptBuffersGrowToTheLargestMessage) {
  MessageBufferPool pool(3);
  Buffer out = pool.acquire(1000);
  Buffer larger = pool.acquire(200000);
  EXPECT_EQ(pool.replacedBuffers(), 2u);
  out.reset();
  larger.reset();
  pool.acquire(1000).reset();
  EXPECT_EQ(pool.replacedBuffers(), 3u);
  std::vector<Buffer> all;
  for (int i = 0; i < 3; ++i) {
    all.push_back(pool.acquire(200000));
    std::memset(all.back().get(), 6, 200000);
  }
  EXPECT_EQ(pool.replacedBuffers(), 3u);
  EXPECT_EQ(pool.transientBuffers(), 0u);
}

TEST(MessageBufferPool, BuffersOutliveThePool) {
  auto pool = std::make_unique<MessageBufferPool>(1);
  Buffer kept = pool->acquire(4096);
  Buffer transient = pool->acquire(4096);
  pool.reset();
  std::memset(kept.get(), 4, 4096);
  std::memset(transient.get(), 5, 4096);
  kept.reset();
  transient.reset();
}

// Messages serialised on one thread, sent and freed on another, as roscpp does: every
// buffer holds its own message until it is returned, and no more are kept than allowed.
TEST(MessageBufferPool, BuffersComeBackFromAnotherThread) {
  constexpr std::size_t kKept = 3;
  constexpr int kMessages = 2000;
  MessageBufferPool pool(kKept);
  std::mutex mutex;
  std::vector<std::pair<Buffer, std::uint8_t>> in_flight;
  std::atomic<bool> done{false};
  std::atomic<int> corrupted{0};
  std::thread sender([&] {
    for (;;) {
      std::vector<std::pair<Buffer, std::uint8_t>> taken;
      {
        std::lock_guard<std::mutex> lock(mutex);
        taken.swap(in_flight);
      }
      for (const auto& [buffer, tag] : taken) {
        for (std::size_t i = 0; i < 3000; i += 97) {
          if (buffer[i] != tag) ++corrupted;
        }
      }
      if (taken.empty() && done) return;
      std::this_thread::yield();
    }
  });
  for (int message = 0; message < kMessages; ++message) {
    const auto tag = static_cast<std::uint8_t>(message);
    Buffer buffer = pool.acquire(3000 + static_cast<std::size_t>(message % 7) * 100);
    std::memset(buffer.get(), tag, 3000);
    std::lock_guard<std::mutex> lock(mutex);
    in_flight.emplace_back(std::move(buffer), tag);
  }
  done = true;
  sender.join();
  EXPECT_EQ(corrupted, 0);
  EXPECT_LE(pool.keptBuffers(), kKept);
}

TEST(ContactArraySerialization, RoundTripsAndReusesItsBuffer) {
  ContactArray message;
  message.header.stamp = ros::Time(12, 345);
  message.header.frame_id = "world";
  message.level = 4;
  for (int i = 0; i < 50; ++i) {
    Contact contact;
    contact.object_a = "fruit";
    contact.object_b = "jaw_" + std::to_string(i % 2);
    contact.sphere_a = static_cast<std::uint32_t>(i);
    contact.sphere_b = static_cast<std::uint32_t>(1000 + i);
    contact.level = 4;
    contact.position.x = 1e5 + 0.001 * i;
    contact.normal.z = 1.0;
    contact.depth = 0.0005 * i;
    message.contacts.push_back(contact);
  }

  ros::SerializedMessage serialized = ros::serialization::serializeMessage(message);
  ASSERT_EQ(serialized.num_bytes, ros::serialization::serializationLength(message) + 4);
  ContactArray decoded;
  ros::serialization::deserializeMessage(serialized, decoded);
  EXPECT_EQ(decoded, message);

  const std::uint8_t* const address = serialized.buf.get();
  serialized = ros::SerializedMessage();
  const ros::SerializedMessage again = ros::serialization::serializeMessage(message);
  EXPECT_EQ(again.buf.get(), address);
}

}  // namespace
}  // namespace deformable_collision
