#include "deformable_collision/ros/force_outputs.h"

#include <boost/make_shared.hpp>

#include "deformable_collision/ros/message_vectors.h"

namespace deformable_collision {
namespace {

visualization_msgs::Marker marker(const std_msgs::Header& header, const char* ns, int id,
                                  int type) {
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.color.a = 1.0;
  return m;
}

/// The force a pair's arrow shows: on its static or kinematic object if it has one (what a
/// sensor there reads, and an arrow that leaves the soft object instead of hiding in it),
/// else on its object a.
Eigen::Vector3d shownForce(const Scene& scene, const PairSummary& pair) {
  const auto fixed = [&](std::uint32_t object) {
    const ObjectKind kind = scene.objectConfig(object).kind;
    return kind == ObjectKind::kStatic || kind == ObjectKind::kKinematic;
  };
  return fixed(pair.object_b) && !fixed(pair.object_a) ? Eigen::Vector3d(-pair.force_n)
                                                       : pair.force_n;
}

}  // namespace

void fillContactSummaryArray(const Scene& scene, const std::vector<PairSummary>& summaries,
                             ContactSummaryArray& message) {
  message.pairs.resize(summaries.size());
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    const PairSummary& from = summaries[k];
    ContactSummary& to = message.pairs[k];
    to.object_a = scene.objectConfig(from.object_a).name;
    to.object_b = scene.objectConfig(from.object_b).name;
    to.contacts = static_cast<std::uint32_t>(from.contacts);
    to.centroid = toPointMessage(from.centroid_m);
    to.normal = toVectorMessage(from.normal);
    to.largest_depth_m = from.largest_depth_m;
    to.force_n = toVectorMessage(from.force_n);
    to.force_error_n = from.force_error_n;
    to.area_m2 = from.area_m2;
    to.registration_error_m = from.registration_error_m;
  }
}

void buildContactForceMarkers(const Scene& scene, const std::vector<PairSummary>& summaries,
                              double scale_m_per_n, const std_msgs::Header& header,
                              visualization_msgs::MarkerArray& markers) {
  visualization_msgs::Marker clear;
  clear.header = header;
  clear.action = visualization_msgs::Marker::DELETEALL;
  markers.markers.push_back(clear);
  auto points = marker(header, "contact_points", 0, visualization_msgs::Marker::SPHERE_LIST);
  points.scale.x = points.scale.y = points.scale.z = 0.5 * scene.config().contact_distance_m;
  points.color.r = points.color.g = points.color.b = 1.0;
  auto forces = marker(header, "contact_forces", 0, visualization_msgs::Marker::LINE_LIST);
  forces.scale.x = 0.001;
  forces.color.r = 1.0;
  forces.color.g = 0.5;
  for (const SceneContact& c : scene.contacts()) {
    points.points.push_back(toPointMessage(c.contact.position));
    forces.points.push_back(toPointMessage(c.contact.position));
    forces.points.push_back(toPointMessage(c.contact.position + scale_m_per_n * c.force_n));
  }
  markers.markers.push_back(points);
  markers.markers.push_back(forces);
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    auto arrow =
        marker(header, "pair_forces", static_cast<int>(k), visualization_msgs::Marker::ARROW);
    arrow.points.push_back(toPointMessage(summaries[k].centroid_m));
    arrow.points.push_back(
        toPointMessage(summaries[k].centroid_m + scale_m_per_n * shownForce(scene, summaries[k])));
    arrow.scale.x = 0.004;
    arrow.scale.y = 0.008;
    arrow.color.r = 1.0;
    markers.markers.push_back(arrow);
  }
}

void ForceOutputs::advertise(ros::NodeHandle& handle) {
  summary_publisher_.advertise<ContactSummaryArray>(handle, "contact_summary", 10);
  markers_publisher_.advertise<visualization_msgs::MarkerArray>(handle, "contact_markers", 1);
}

void ForceOutputs::publish(const Scene& scene, double scale_m_per_n, const std_msgs::Header& header,
                           PublishQueue<CountedPublisher>& queue) {
  if (!summary_publisher_.subscribed() && !markers_publisher_.subscribed()) return;
  summarizePairs(scene.contacts(), summaries_);
  if (summary_publisher_.subscribed()) {
    summary_message_.header = header;
    summary_message_.level = static_cast<std::uint8_t>(scene.stats().level);
    fillContactSummaryArray(scene, summaries_, summary_message_);
    summary_publisher_.publish(summary_message_);
  }
  if (markers_publisher_.subscribed()) {
    auto markers = boost::make_shared<visualization_msgs::MarkerArray>();
    buildContactForceMarkers(scene, summaries_, scale_m_per_n, header, *markers);
    queue.post(markers_publisher_, markers);
  }
}

}  // namespace deformable_collision
