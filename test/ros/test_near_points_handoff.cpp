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

// The cycle puts while the reader takes: every take is one whole put, in order, and once
// the buffers have grown to the largest put, three circulate.
TEST(NearPointsHandoff, ACycleAndAReaderRunConcurrently) {
  NearPointsHandoff handoff;
  constexpr int kPuts = 20000;
  std::atomic<bool> done{false};
  std::thread cycle([&] {
    Points gathered;
    for (int k = 1; k <= kPuts; ++k) {
      gathered.assign(1 + k % 7, Eigen::Vector3d::Constant(k));
      handoff.put(gathered);
    }
    done = true;
  });
  Points taken;
  std::set<const Eigen::Vector3d*> buffers;
  double last = 0.0;
  const auto take = [&] {
    if (!handoff.take(taken)) return;
    ASSERT_FALSE(taken.empty());
    for (const auto& p : taken) ASSERT_EQ(p, taken.front());
    EXPECT_GT(taken.front().x(), last);
    last = taken.front().x();
    if (last > 100.0) buffers.insert(taken.data());
  };
  while (!done) take();
  cycle.join();
  take();
  EXPECT_EQ(last, kPuts) << "the last put is taken";
  EXPECT_LE(buffers.size(), 3u);
}

}  // namespace
}  // namespace deformable_collision
