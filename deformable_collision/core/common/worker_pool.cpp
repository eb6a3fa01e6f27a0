#include "deformable_collision/core/common/worker_pool.h"

#include <chrono>
#include <stdexcept>
#include <string>

namespace deformable_collision {

WorkerPool::WorkerPool(int threads) {
  if (threads < 1 || threads > kMaxThreads) {
    throw std::invalid_argument("threads = " + std::to_string(threads) + " must be in [1, " +
                                std::to_string(kMaxThreads) + "]");
  }
  workers_.reserve(static_cast<std::size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) {
    workers_.emplace_back([this, t] { workerLoop(static_cast<std::size_t>(t)); });
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  started_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

void WorkerPool::run(std::size_t count, Call call, const void* context) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    call_ = call;
    context_ = context;
    count_ = count;
    next_.store(0, std::memory_order_relaxed);
    busy_workers_.store(static_cast<int>(workers_.size()), std::memory_order_relaxed);
    failure_ = nullptr;
    ++generation_;
  }
  started_.notify_all();
  work(0);
  // The workers' last iterations end about when the caller's do: waiting for them on the
  // condition variable would add a wake-up, tens of microseconds, to most loops.
  const auto spin_until = std::chrono::steady_clock::now() + kFinishSpin;
  while (busy_workers_.load(std::memory_order_acquire) != 0 &&
         std::chrono::steady_clock::now() < spin_until) {
  }
  std::unique_lock<std::mutex> lock(mutex_);
  finished_.wait(lock, [this] { return busy_workers_.load(std::memory_order_relaxed) == 0; });
  if (failure_) std::rethrow_exception(failure_);
}

void WorkerPool::work(std::size_t lane) {
  for (std::size_t i = next_.fetch_add(1); i < count_; i = next_.fetch_add(1)) {
    try {
      call_(context_, i, lane);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!failure_) failure_ = std::current_exception();
    }
  }
}

void WorkerPool::workerLoop(std::size_t lane) {
  std::uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      started_.wait(lock, [&] { return stopping_ || generation_ != seen; });
      if (stopping_) return;
      seen = generation_;
    }
    work(lane);
    bool last = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      last = busy_workers_.fetch_sub(1, std::memory_order_release) == 1;
    }
    if (last) finished_.notify_one();
  }
}

}  // namespace deformable_collision
