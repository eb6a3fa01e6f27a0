#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace deformable_collision {

/// Worker threads, started once, that run the iterations of a loop together with the
/// calling thread. A loop allocates nothing. Iterations are handed out one at a time in no
/// fixed order, so a loop gives the same result on any number of threads only if each
/// iteration writes what no other reads or writes.
class WorkerPool {
 public:
  /// `threads` running each loop, the caller included: threads - 1 workers.
  /// @throw std::invalid_argument unless threads is in [1, kMaxThreads].
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  static constexpr int kMaxThreads = 64;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls body(i) for every i in [0, count) and returns when all calls have returned. With
  /// one thread, or one iteration, the caller makes every call. The first exception a call
  /// throws is thrown here once all have returned; the other iterations still run.
  template <typename Body>
  void forEach(std::size_t count, const Body& body) {
    forEachOnLane(count, [&body](std::size_t i, std::size_t) { body(i); });
  }

  /// forEach(), calling body(i, lane): `lane` is in [0, threads()) and no two calls at once
  /// share one, so that a call may use the lane's scratch (the caller is lane 0).
  template <typename Body>
  void forEachOnLane(std::size_t count, const Body& body) {
    if (workers_.empty() || count < 2) {
      for (std::size_t i = 0; i < count; ++i) body(i, 0);
      return;
    }
    run(
        count,
        [](const void* context, std::size_t i, std::size_t lane) {
          (*static_cast<const Body*>(context))(i, lane);
        },
        &body);
  }

 private:
  using Call = void (*)(const void* context, std::size_t index, std::size_t lane);
  /// How long a caller done with its iterations spins for the workers before it sleeps.
  static constexpr std::chrono::microseconds kFinishSpin{50};

  void run(std::size_t count, Call call, const void* context);
  /// Takes iterations until none is left, on `lane`.
  void work(std::size_t lane);
  void workerLoop(std::size_t lane);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable started_;
  std::condition_variable finished_;
  // The loop in progress, set under mutex_ before its generation is announced.
  Call call_ = nullptr;
  const void* context_ = nullptr;
  std::size_t count_ = 0;
  std::atomic<std::size_t> next_{0};
  std::uint64_t generation_ = 0;
  /// Workers still in the loop in progress; written under mutex_, read by a caller that
  /// spins for them.
  std::atomic<int> busy_workers_{0};
  bool stopping_ = false;
  std::exception_ptr failure_;
};

}  // namespace deformable_collision
