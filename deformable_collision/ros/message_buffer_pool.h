#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include <boost/shared_array.hpp>

namespace deformable_collision {

/// Buffers to serialise large messages into, reused from one publication to the next.
///
/// roscpp serialises a message for its subscribers in other processes into a buffer of its
/// own, `new[]`-ed at each publication and freed once the last subscriber's link has sent it,
/// often on another thread. For the load test's `~contacts` (16k contacts, 1.1 to 1.65 MB) at
/// 100 Hz that is a large allocation every cycle, and glibc's heap, once its dynamic mmap
/// threshold has risen past that size, keeps such buffers: resident memory then steps up by
/// one buffer whenever one more is in flight at once than ever before. This pool hands out
/// buffers whose deleter gives them back to it, so in steady state a publication allocates no
/// buffer and touches no new page.
///
/// The pool keeps `kept_buffers` buffers, mapped together when the first is needed, each as
/// large as the largest message so far and a quarter more, with all its pages resident: a
/// later peak of messages in flight finds them ready, so resident memory does not step up
/// then. A message larger than a free buffer grows every free buffer first; one acquired
/// while all kept buffers are out is mapped for that message only and unmapped once returned,
/// so a burst of messages in flight (a slow subscriber) leaves no resident memory behind.
///
/// Thread-safe: buffers may be acquired on one thread and returned on others, also after the
/// pool itself is gone (the returned buffers' deleters share its state).
class MessageBufferPool {
 public:
  /// @throw std::invalid_argument if `kept_buffers` is 0.
  explicit MessageBufferPool(std::size_t kept_buffers);
  ~MessageBufferPool();
  MessageBufferPool(const MessageBufferPool&) = delete;
  MessageBufferPool& operator=(const MessageBufferPool&) = delete;

  /// A buffer of at least `bytes` bytes (its content undefined) that returns to the pool when
  /// the last copy of the shared array is destroyed.
  /// @throw std::bad_alloc if the memory cannot be mapped.
  boost::shared_array<std::uint8_t> acquire(std::size_t bytes);

  /// Buffers the pool keeps, out or free: 0 before the first acquire(), then kept_buffers.
  std::size_t keptBuffers() const;
  /// Buffers mapped for one message because `kept_buffers` were out, since construction.
  std::size_t transientBuffers() const;
  /// Kept buffers replaced by larger ones (a message larger than they), since construction.
  std::size_t replacedBuffers() const;

 private:
  struct State;
  struct ReturnToPool;
  std::shared_ptr<State> state_;
};

}  // namespace deformable_collision
