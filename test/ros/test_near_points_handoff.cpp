#include "deformable_collision/ros/near_points_handoff.h"

#include <gtest/gtest.h>

#include <atomic>
#include <set>
#include <thread>
#include <vector>

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

TEST(NearPointsHandoff, PassesTheNewestOnceAndTheBufferItself) {
  NearPointsHandoff handoff;
  Points taken;
  EXPECT_FALSE(handoff.take(taken)) << "nothing was put";
  Points first(3, Eigen::Vector3d::Constant(1.0));
  Points second(5, Eigen::Vector3d::Constant(2.0));
  const Eigen::Vector3d* second_data = second.data();
  handoff.put(first);
  handoff.put(second);
  EXPECT_EQ(second.size(), 3u) << "the put buffer comes back with the one it replaced";
  ASSERT_TRUE(handoff.take(taken));
  EXPECT_EQ(taken.data(), second_data);
  EXPECT_EQ(taken, Points(5, Eigen::Vector3d::Constant(2.0)));
  EXPECT_FALSE(handoff.take(taken)) << "each is taken once";
  EXPECT_EQ(taken.data(), second_data) << "a take without a newer one leaves the buffer";
}

// The cycle puts while the reader takes: every take is one whole put, in order, and the
// three buffers, grown to the largest put before the threads start, are the only ones seen
// however the two threads are scheduled.
TEST(NearPointsHandoff, ACycleAndAReaderRunConcurrently) {
  constexpr int kPuts = 20000;
  constexpr std::size_t kLargestPut = 7;
  NearPointsHandoff handoff;
  Points gathered, taken, spare;
  for (Points* buffer : {&gathered, &taken, &spare}) buffer->reserve(kLargestPut);
  const std::set<const Eigen::Vector3d*> grown{gathered.data(), taken.data(), spare.data()};
  handoff.put(spare);
  ASSERT_TRUE(handoff.take(taken)) << "the handoff's own buffer is now a grown one";
  std::atomic<bool> done{false};
  std::thread cycle([&] {
    for (int k = 1; k <= kPuts; ++k) {
      gathered.assign(1 + k % kLargestPut, Eigen::Vector3d::Constant(k));
      handoff.put(gathered);
    }
    done = true;
  });
  std::set<const Eigen::Vector3d*> buffers;
  double last = 0.0;
  const auto take = [&] {
    if (!handoff.take(taken)) return;
    ASSERT_FALSE(taken.empty());
    for (const auto& p : taken) ASSERT_EQ(p, taken.front());
    EXPECT_GT(taken.front().x(), last);
    last = taken.front().x();
    buffers.insert(taken.data());
  };
  while (!done) take();
  cycle.join();
  take();
  EXPECT_EQ(last, kPuts) << "the last put is taken";
  for (const auto* buffer : buffers) EXPECT_EQ(grown.count(buffer), 1u) << "a fourth buffer";
}

}  // namespace
}  // namespace deformable_collision
