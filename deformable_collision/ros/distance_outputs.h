#pragma once

#include <ros/ros.h>
#include <std_msgs/Header.h>

#include <vector>

#include "deformable_collision/DistanceArray.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/contact_service.h"
#include "deformable_collision/ros/counted_publisher.h"
#include "deformable_collision/ros/node_config.h"

namespace deformable_collision {

/// ~distances: after each cycle, the closest points of each of `distance_pairs`, computed
/// only while someone subscribes. Used by the cycle's thread alone.
class DistanceOutputs {
 public:
  explicit DistanceOutputs(std::vector<DistancePairParams> pairs) : pairs_(std::move(pairs)) {}

  /// Advertises ~distances on `handle` (the cycle's queue) if there are pairs.
  void advertise(ros::NodeHandle& handle);
  /// Publishes each pair's closest points on the scene's current state; a pair with an
  /// object that has had no cloud yet is not found.
  void publish(Scene& scene, const std::vector<NamedObject>& objects,
               const std_msgs::Header& header);

 private:
  std::vector<DistancePairParams> pairs_;
  CountedPublisher publisher_;
  DistanceArray message_;
};

}  // namespace deformable_collision
