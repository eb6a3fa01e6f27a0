// WorkerPool: every iteration runs once, on any number of threads, loop after loop; no two
// calls at once share a lane; a throwing iteration is reported once all have returned.
#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include "deformable_collision/core/common/worker_pool.h"

namespace deformable_collision {
namespace {

TEST(WorkerPool, RunsEveryIterationOnceOnAnyNumberOfThreads) {
  for (const int threads : {1, 2, 3, 8}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (const std::size_t count : {0u, 1u, 2u, 7u, 1000u}) {
      std::vector<std::atomic<int>> calls(count);
      for (int loop = 0; loop < 20; ++loop) {
        pool.forEach(count, [&](std::size_t i) { calls[i].fetch_add(1); });
      }
      for (std::size_t i = 0; i < count; ++i) {
        ASSERT_EQ(calls[i].load(), 20) << threads << " threads, " << count << " iterations";
      }
    }
  }
}

// A lane is a call's scratch: it is in range, and a call finds its lane free.
TEST(WorkerPool, NoTwoCallsAtOnceShareALane) {
  for (const int threads : {1, 2, 4}) {
    WorkerPool pool(threads);
    std::vector<std::atomic<bool>> busy(static_cast<std::size_t>(threads));
    std::atomic<int> clashes{0}, out_of_range{0}, calls{0};
    pool.forEachOnLane(2000, [&](std::size_t i, std::size_t lane) {
      if (lane >= busy.size()) {
        ++out_of_range;
        return;
      }
      if (busy[lane].exchange(true)) ++clashes;
      volatile double x = static_cast<double>(i);
      for (int k = 0; k < 200; ++k) x = x * 1.0000001 + 0.5;
      busy[lane].store(false);
      ++calls;
    });
    EXPECT_EQ(out_of_range.load(), 0) << threads << " threads";
    EXPECT_EQ(clashes.load(), 0) << threads << " threads";
    EXPECT_EQ(calls.load(), 2000) << threads << " threads";
  }
}

// Each iteration writes its own slot: the results do not depend on the thread count.
TEST(WorkerPool, IterationsOnTheirOwnDataGiveTheSameResults) {
  std::vector<double> one(4096), four(4096);
  const auto work = [](std::vector<double>& out) {
    return [&out](std::size_t i) {
      double x = static_cast<double>(i);
      for (int k = 0; k < 50; ++k) x = x * 1.0000001 + 0.5;
      out[i] = x;
    };
  };
  WorkerPool(1).forEach(one.size(), work(one));
  WorkerPool(4).forEach(four.size(), work(four));
  EXPECT_EQ(one, four);
}

TEST(WorkerPool, ThrowsTheFirstFailureOnceAllIterationsReturned) {
  WorkerPool pool(3);
  std::atomic<int> done{0};
  EXPECT_THROW(pool.forEach(100,
                            [&](std::size_t i) {
                              if (i % 10 == 3) throw std::runtime_error("iteration failed");
                              done.fetch_add(1);
                            }),
               std::runtime_error);
  EXPECT_EQ(done.load(), 90);
  // The pool still works after a failure.
  std::atomic<int> after{0};
  pool.forEach(50, [&](std::size_t) { after.fetch_add(1); });
  EXPECT_EQ(after.load(), 50);
}

TEST(WorkerPool, RefusesThreadCountsOutOfRange) {
  EXPECT_THROW(WorkerPool(0), std::invalid_argument);
  EXPECT_THROW(WorkerPool(WorkerPool::kMaxThreads + 1), std::invalid_argument);
}

}  // namespace
}  // namespace deformable_collision
