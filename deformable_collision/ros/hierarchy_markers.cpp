#include "deformable_collision/ros/hierarchy_markers.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "deformable_collision/ros/message_vectors.h"

namespace deformable_collision {
namespace {

constexpr double kStepsPerOctave = 8.0;

std_msgs::ColorRGBA objectColor(std::size_t object, float alpha) {
  // Golden-ratio hues keep neighbouring indices apart however many objects there are.
  const double hue = std::fmod(0.12 + 0.618033988749895 * static_cast<double>(object), 1.0) * 6.0;
  const double saturation = 0.65, value = 0.95;
  const int sector = static_cast<int>(hue) % 6;
  const double f = hue - std::floor(hue);
  const double p = value * (1 - saturation), q = value * (1 - saturation * f),
               t = value * (1 - saturation * (1 - f));
  const double rgb[6][3] = {{value, t, p}, {q, value, p}, {p, value, t},
                            {p, q, value}, {t, p, value}, {value, p, q}};
  std_msgs::ColorRGBA color;
  color.r = static_cast<float>(rgb[sector][0]);
  color.g = static_cast<float>(rgb[sector][1]);
  color.b = static_cast<float>(rgb[sector][2]);
  color.a = alpha;
  return color;
}

std_msgs::ColorRGBA collidingColor() {
  std_msgs::ColorRGBA color;
  color.r = 1.0f;
  color.g = 0.1f;
  color.b = 0.1f;
  color.a = 0.85f;
  return color;
}

int radiusStep(double radius_m, double center_norm_m) {
  // Published points are float32: allow their rounding (2^-24 relative) and a little more.
  const double padded = radius_m * (1.0 + 1e-6) + 1e-7 * center_norm_m + 1e-9;
  return static_cast<int>(std::ceil(kStepsPerOctave * std::log2(padded)));
}

double stepRadius(int step) { return std::exp2(step / kStepsPerOctave); }

}  // namespace

double drawnRadius(double radius_m, double center_norm_m) {
  return stepRadius(radiusStep(radius_m, center_norm_m));
}

void HierarchyMarkers::build(Scene& scene, int level, const std::vector<SceneContact>& contacts,
                             bool colliding_only, const std_msgs::Header& header,
                             visualization_msgs::MarkerArray& markers) {
  markers.markers.clear();
  visualization_msgs::Marker clear;
  clear.header = header;
  clear.action = visualization_msgs::Marker::DELETEALL;
  markers.markers.push_back(clear);
  markColliding(scene, contacts);
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    drawObject(scene, o, level, colliding_only, header, markers);
  }
}

void HierarchyMarkers::markColliding(const Scene& scene,
                                     const std::vector<SceneContact>& contacts) {
  const std::size_t objects = scene.objectCount();
  colliding_.resize(objects);
  for (std::size_t o = 0; o < objects; ++o) colliding_[o].assign(scene.tree(o).nodeCount(), 0);
  for (const SceneContact& c : contacts) {
    colliding_[c.object_a][c.contact.node_a] = 1;
    colliding_[c.object_b][c.contact.node_b] = 1;
  }
  // A static or kinematic object meets an object at its leaves at its own leaves, below
  // the level drawn: its sphere there is in contact if one of its nodes is. Children
  // follow their parent in a tree's nodes, so a backward sweep sees them first.
  for (std::size_t o = 0; o < objects; ++o) {
    const SphereTree& tree = scene.tree(o);
    for (std::uint32_t n = tree.nodeCount(); n-- > 0;) {
      const SphereNode& node = tree.node(n);
      for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
        colliding_[o][n] |= colliding_[o][c];
      }
    }
  }
}

void HierarchyMarkers::drawObject(Scene& scene, std::size_t object, int level, bool colliding_only,
                                  const std_msgs::Header& header,
                                  visualization_msgs::MarkerArray& markers) {
  const SphereTree& tree = scene.tree(object);
  const std_msgs::ColorRGBA color = objectColor(object, 0.35f);
  const std_msgs::ColorRGBA hit = collidingColor();
  marker_of_step_.clear();
  stack_.assign(1, 0);
  while (!stack_.empty()) {
    const std::uint32_t n = stack_.back();
    stack_.pop_back();
    const SphereNode& node = tree.node(n);
    if (!endsDescentToLevel(node, level)) {
      for (std::uint32_t c = 0; c < node.child_count; ++c) stack_.push_back(node.first_child + c);
      continue;
    }
    const bool in_contact = colliding_[object][n] != 0;
    if (colliding_only && !in_contact) continue;
    const Sphere& sphere = scene.currentSphere(object, n);
    const int step = radiusStep(sphere.radius, sphere.center.norm());
    auto [slot, added] = marker_of_step_.emplace(step, markers.markers.size());
    if (added) {
      visualization_msgs::Marker marker;
      marker.header = header;
      marker.ns = scene.objectConfig(object).name;
      marker.id = step;
      marker.type = visualization_msgs::Marker::SPHERE_LIST;
      marker.action = visualization_msgs::Marker::ADD;
      marker.pose.orientation.w = 1.0;
      marker.scale.x = marker.scale.y = marker.scale.z = 2.0 * stepRadius(step);
      marker.color = color;
      markers.markers.push_back(std::move(marker));
    }
    visualization_msgs::Marker& marker = markers.markers[slot->second];
    marker.points.push_back(toPointMessage(sphere.center));
    marker.colors.push_back(in_contact ? hit : color);
  }
}

}  // namespace deformable_collision
