#include "deformable_collision/ros/message_buffer_pool.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <new>
#include <stdexcept>
#include <vector>

namespace deformable_collision {
namespace {

struct Mapping {
  std::uint8_t* data = nullptr;
  std::size_t capacity = 0;
};

// Mapped directly rather than taken from the heap: unmapping gives the pages back at once,
// whatever the allocator's thresholds are at the time.
Mapping mapAtLeast(std::size_t bytes) {
  static const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t capacity = (bytes + page - 1) / page * page;
  void* data = mmap(nullptr, capacity, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (data == MAP_FAILED) throw std::bad_alloc();
  return {static_cast<std::uint8_t*>(data), capacity};
}

// A kept buffer has all its pages resident from the start: resident memory does not grow
// later, when a message first reaches them.
Mapping mapTouched(std::size_t bytes) {
  const Mapping mapping = mapAtLeast(bytes);
  std::memset(mapping.data, 0, mapping.capacity);
  return mapping;
}

void unmap(const Mapping& mapping) { munmap(mapping.data, mapping.capacity); }

}  // namespace

struct MessageBufferPool::State {
  explicit State(std::size_t limit) : kept_limit(limit) { free.reserve(limit); }

  std::mutex mutex;
  const std::size_t kept_limit;
  std::vector<Mapping> free;  // reserved for every kept buffer: returning one allocates nothing
  std::size_t kept = 0;
  std::size_t largest_bytes = 0;  // of the messages so far
  std::size_t transient = 0;
  std::size_t replaced = 0;
  bool pool_alive = true;
};

struct MessageBufferPool::ReturnToPool {
  std::shared_ptr<State> state;
  Mapping mapping;
  bool kept;

  void operator()(std::uint8_t*) const {
    std::lock_guard<std::mutex> lock(state->mutex);
    if (kept && state->pool_alive) {
      state->free.push_back(mapping);
    } else {
      unmap(mapping);
    }
  }
};

MessageBufferPool::MessageBufferPool(std::size_t kept_buffers) {
  if (kept_buffers == 0) throw std::invalid_argument("MessageBufferPool: kept_buffers is 0");
  state_ = std::make_shared<State>(kept_buffers);
}

MessageBufferPool::~MessageBufferPool() {
  std::lock_guard<std::mutex> lock(state_->mutex);
  for (const Mapping& mapping : state_->free) unmap(mapping);
  state_->free.clear();
  state_->pool_alive = false;
}

boost::shared_array<std::uint8_t> MessageBufferPool::acquire(std::size_t bytes) {
  Mapping mapping;
  bool kept = true;
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    State& state = *state_;
    state.largest_bytes = std::max(state.largest_bytes, bytes);
    const std::size_t kept_bytes = state.largest_bytes + state.largest_bytes / 4;
    // Every free buffer too small for the largest message so far grows now, rather than when
    // it is next needed: a later peak of messages in flight finds its buffers resident then.
    for (Mapping& free : state.free) {
      if (free.capacity >= state.largest_bytes) continue;
      const Mapping larger = mapTouched(kept_bytes);
      unmap(free);
      free = larger;
      ++state.replaced;
    }
    if (state.free.empty() && state.kept < state.kept_limit) {
      for (; state.kept < state.kept_limit; ++state.kept) {
        state.free.push_back(mapTouched(kept_bytes));
      }
    }
    if (!state.free.empty()) {
      mapping = state.free.back();
      state.free.pop_back();
    } else {
      mapping = mapAtLeast(bytes);
      kept = false;
      ++state.transient;
    }
  }
  return boost::shared_array<std::uint8_t>(mapping.data, ReturnToPool{state_, mapping, kept});
}

std::size_t MessageBufferPool::keptBuffers() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->kept;
}

std::size_t MessageBufferPool::transientBuffers() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->transient;
}

std::size_t MessageBufferPool::replacedBuffers() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->replaced;
}

}  // namespace deformable_collision
