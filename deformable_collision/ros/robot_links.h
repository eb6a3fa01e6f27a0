#pragma once

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

#include "deformable_collision/core/robot/surface_sampling.h"

namespace urdf {
class ModelInterface;
}  // namespace urdf

namespace deformable_collision {

/// A robot description (URDF) whose links' collision geometry becomes points.
class RobotLinks {
 public:
  /// Parses the URDF in `urdf_xml`.
  /// @throw std::invalid_argument if urdf::Model cannot parse it (its reasons go to the log).
  explicit RobotLinks(const std::string& urdf_xml);

  /// The surface points of link `link`'s collision geometry, in the link's frame: each of
  /// its <collision> elements (box, cylinder, sphere, or a mesh scaled by its `scale`)
  /// sampled by `sampling` (sampleBoxSurface() and the others) and placed by its <origin>.
  /// @throw std::invalid_argument whose message names the link: it is not in the robot, has
  /// no collision geometry, a mesh cannot be read, or all its elements together would take
  /// more than sampling.max_points points.
  std::vector<Eigen::Vector3d> sampleSurface(const std::string& link,
                                             const SurfaceSampling& sampling) const;

 private:
  /// urdf's types stay out of this header, which the node's includes.
  std::shared_ptr<const urdf::ModelInterface> model_;
};

}  // namespace deformable_collision
