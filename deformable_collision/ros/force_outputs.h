#pragma once

#include <ros/ros.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <vector>

#include "deformable_collision/ContactSummaryArray.h"
#include "deformable_collision/core/response/contact_totals.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/counted_publisher.h"
#include "deformable_collision/ros/publish_queue.h"

namespace deformable_collision {

/// Fills a ~contact_summary message from the pairs' summaries, naming the objects.
void fillContactSummaryArray(const Scene& scene, const std::vector<PairSummary>& summaries,
                             ContactSummaryArray& message);

/// Builds ~contact_markers: the contacts' positions (a SPHERE_LIST), each contact's force on
/// its object a as a segment from its position (a LINE_LIST) and each pair's total force as
/// an arrow from its centroid (on its static or kinematic object, if it has one), with
/// `scale_m_per_n` metres per newton; the first marker deletes the last array's.
void buildContactForceMarkers(const Scene& scene, const std::vector<PairSummary>& summaries,
                              double scale_m_per_n, const std_msgs::Header& header,
                              visualization_msgs::MarkerArray& markers);

/// The cycle's ~contact_summary and ~contact_markers, each built only while someone
/// subscribes. Used by the cycle's thread alone.
class ForceOutputs {
 public:
  /// Advertises both on `handle`, whose queue must be the cycle's (CountedPublisher).
  void advertise(ros::NodeHandle& handle);
  /// The summary is published at once (a controller's input), the markers through `queue`.
  void publish(const Scene& scene, double scale_m_per_n, const std_msgs::Header& header,
               PublishQueue<CountedPublisher>& queue);

 private:
  CountedPublisher summary_publisher_;
  CountedPublisher markers_publisher_;
  std::vector<PairSummary> summaries_;
  ContactSummaryArray summary_message_;
};

}  // namespace deformable_collision
