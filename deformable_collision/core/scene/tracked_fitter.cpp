#include "deformable_collision/core/scene/tracked_fitter.h"

namespace deformable_collision {

std::size_t TrackedFitter::fit(std::vector<Eigen::Vector3d>& points_m, TrackedFit& fit) {
  // The cloud goes into the body to be fitted and comes back: the body keeps its own buffer.
  const std::size_t unobserved = body_.trackSwapping(points_m);
  body_.giveTrackedState(points_m, fit.state);
  fit.rest_shape = rest_shape_;
  return unobserved;
}

}  // namespace deformable_collision
