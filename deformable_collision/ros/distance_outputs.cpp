#include "deformable_collision/ros/distance_outputs.h"

#include <algorithm>
#include <optional>

namespace deformable_collision {
namespace {

std::optional<std::size_t> sceneIndex(const std::vector<NamedObject>& objects,
                                      const std::string& name) {
  for (const NamedObject& object : objects) {
    if (object.name == name) return object.scene_index;
  }
  return std::nullopt;
}

}  // namespace

void DistanceOutputs::advertise(ros::NodeHandle& handle) {
  if (!pairs_.empty()) publisher_.advertise<DistanceArray>(handle, "distances", 10);
}

void DistanceOutputs::publish(Scene& scene, const std::vector<NamedObject>& objects,
                              const std_msgs::Header& header) {
  if (!publisher_.subscribed()) return;
  message_.header = header;
  message_.distances.resize(pairs_.size());
  for (std::size_t k = 0; k < pairs_.size(); ++k) {
    const DistancePairParams& pair = pairs_[k];
    Distance& distance = message_.distances[k];
    const std::optional<std::size_t> a = sceneIndex(objects, pair.object_a);
    const std::optional<std::size_t> b = sceneIndex(objects, pair.object_b);
    // The finest, or the level asked for if the objects that came since reach it.
    const int level = pair.level < 0 ? scene.maxLevel() : std::min(pair.level, scene.maxLevel());
    if (a && b) {
      fillDistance(scene, *a, *b, level, pair.max_distance_m, distance);
      continue;
    }
    distance = Distance();
    distance.object_a = pair.object_a;
    distance.object_b = pair.object_b;
    distance.level = static_cast<std::uint8_t>(level);
  }
  publisher_.publish(message_);
}

}  // namespace deformable_collision
