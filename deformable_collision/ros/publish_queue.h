#pragma once

#include <boost/shared_ptr.hpp>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace deformable_collision {

/// A thread that publishes the messages the cycle hands it, in the order handed. Publishing
/// to a subscriber in another process (rviz) serialises the message and writes it to a
/// socket before publish() returns: for the hierarchy's markers and the deformed clouds of a
/// large scene that is the larger part of their cost, and it leaves the cycle's thread. A
/// message is built from the scene by the cycle and not changed once handed over.
///
/// `Publisher` needs `publish(const boost::shared_ptr<M>&) const` for each message type
/// handed; the publishers must outlive stop(). Handing over allocates nothing: the queue's
/// slots are made once, and a post that finds them all taken waits for the oldest one to be
/// published rather than drop or reorder a message.
template <class Publisher>
class PublishQueue {
 public:
  /// @throw std::invalid_argument if capacity is 0.
  explicit PublishQueue(std::size_t capacity) : slots_(checkedCapacity(capacity)) {
    thread_ = std::thread([this] { publishLoop(); });
  }
  ~PublishQueue() { stop(); }
  PublishQueue(const PublishQueue&) = delete;
  PublishQueue& operator=(const PublishQueue&) = delete;

  /// Publishes `message` on `publisher` after every message handed before it.
  template <class Message>
  void post(const Publisher& publisher, const boost::shared_ptr<Message>& message) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (count_ == slots_.size()) ++full_waits_;
    published_.wait(lock, [this] { return count_ < slots_.size() || stopping_; });
    if (stopping_) return;
    Slot& slot = slots_[(first_ + count_) % slots_.size()];
    slot.publisher = &publisher;
    slot.message = message;
    slot.publish = &publishAs<Message>;
    ++count_;
    lock.unlock();
    posted_.notify_one();
  }

  /// Returns once every message handed so far has been published.
  void drain() {
    std::unique_lock<std::mutex> lock(mutex_);
    published_.wait(lock, [this] { return count_ == 0 || stopping_; });
  }

  /// Publishes what is queued, then ends the thread; later posts are ignored.
  void stop() {
    if (!thread_.joinable()) return;
    drain();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    posted_.notify_one();
    published_.notify_all();
    thread_.join();
  }

  /// Posts that found every slot taken and waited.
  std::uint64_t fullWaits() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return full_waits_;
  }

 private:
  struct Slot {
    const Publisher* publisher = nullptr;
    boost::shared_ptr<const void> message;
    void (*publish)(const Publisher&, const boost::shared_ptr<const void>&) = nullptr;
  };

  static std::size_t checkedCapacity(std::size_t capacity) {
    if (capacity == 0) throw std::invalid_argument("a publish queue needs at least one slot");
    return capacity;
  }

  template <class Message>
  static void publishAs(const Publisher& publisher, const boost::shared_ptr<const void>& message) {
    publisher.publish(
        boost::const_pointer_cast<Message>(boost::static_pointer_cast<const Message>(message)));
  }

  void publishLoop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      posted_.wait(lock, [this] { return count_ > 0 || stopping_; });
      if (count_ == 0) return;
      Slot& slot = slots_[first_];
      lock.unlock();
      slot.publish(*slot.publisher, slot.message);
      // Released here, not when the slot is next written: the cycle may reuse a message
      // nobody else holds.
      slot.message.reset();
      lock.lock();
      first_ = (first_ + 1) % slots_.size();
      --count_;
      published_.notify_all();
    }
  }

  std::vector<Slot> slots_;
  mutable std::mutex mutex_;
  std::condition_variable posted_;
  std::condition_variable published_;
  std::size_t first_ = 0;  ///< The oldest message's slot.
  /// Messages queued, the one being published included: its slot is not written meanwhile.
  std::size_t count_ = 0;
  bool stopping_ = false;
  std::uint64_t full_waits_ = 0;
  std::thread thread_;
};

}  // namespace deformable_collision
