#pragma once

#include <cstdint>
#include <string>

#include <ros/ros.h>

namespace deformable_collision {

/// A publisher that knows whether anyone subscribes without asking roscpp at each cycle:
/// ros::Publisher::getNumSubscribers() searches all of the process's publications for the
/// topic by name, under roscpp's topic lock, so a node of 300 objects asking for each
/// object's ~deformed/<object> made 300 searches of 300 names a cycle, contending with the
/// threads that receive clouds. The subscribers are counted by the publisher's connect and
/// disconnect callbacks instead, which roscpp calls once per subscriber link (in this
/// process or another) on the queue of the handle that advertised: advertise on the queue of
/// the thread that calls subscribed(), and the count needs no lock.
///
/// The callbacks hold `this`: a CountedPublisher neither moves nor copies once advertised.
class CountedPublisher {
 public:
  CountedPublisher() = default;
  CountedPublisher(const CountedPublisher&) = delete;
  CountedPublisher& operator=(const CountedPublisher&) = delete;

  template <class Message>
  void advertise(ros::NodeHandle& handle, const std::string& topic, std::uint32_t queue_size) {
    publisher_ = handle.advertise<Message>(
        topic, queue_size, [this](const ros::SingleSubscriberPublisher&) { ++subscribers_; },
        [this](const ros::SingleSubscriberPublisher&) { --subscribers_; });
  }

  /// The subscribers connected when the handle's queue last ran its callbacks.
  std::uint32_t subscribers() const { return subscribers_; }
  bool subscribed() const { return subscribers_ > 0; }

  template <class Message>
  void publish(const Message& message) const {
    publisher_.publish(message);
  }

 private:
  ros::Publisher publisher_;
  std::uint32_t subscribers_ = 0;
};

}  // namespace deformable_collision
