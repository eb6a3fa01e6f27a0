#pragma once

#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// Radius a sphere is drawn with: `radius_m` rounded up to the next of a geometric series
/// of radii (ratio 2^(1/8)), so that spheres of similar size share one SPHERE_LIST marker.
/// Never smaller than the true radius, with a margin for the float32 rounding of published
/// points at `center_norm_m` from the origin.
double drawnRadius(double radius_m, double center_norm_m);

/// Builds the ~hierarchy MarkerArray: the spheres of one level of every object, one
/// namespace per object (its name), one SPHERE_LIST marker per drawn radius (scale = the
/// drawn diameter, points = the centres), coloured by object, spheres in a contact
/// highlighted. The first marker deletes the previous array's markers.
class HierarchyMarkers {
 public:
  /// Spheres of `level` (leaves above it stand for themselves), on the current state.
  /// `contacts` mark the colliding spheres, and a sphere over a colliding one below `level`
  /// (a static object's leaves in a contact); with `colliding_only` only those are drawn.
  void build(Scene& scene, int level, const std::vector<SceneContact>& contacts,
             bool colliding_only, const std_msgs::Header& header,
             visualization_msgs::MarkerArray& markers);

 private:
  /// Marks the nodes in `contacts` and their ancestors in colliding_.
  void markColliding(const Scene& scene, const std::vector<SceneContact>& contacts);
  /// Appends `object`'s spheres of `level` to the markers of their radius steps.
  void drawObject(Scene& scene, std::size_t object, int level, bool colliding_only,
                  const std_msgs::Header& header, visualization_msgs::MarkerArray& markers);

  std::vector<std::vector<std::uint8_t>> colliding_;  ///< Per object, per node.
  std::vector<std::uint32_t> stack_;
  std::map<int, std::size_t> marker_of_step_;  ///< An object's marker of each radius step.
};

}  // namespace deformable_collision
