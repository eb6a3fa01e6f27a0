#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {

/// The fit of a tracked object's cloud made apart from its scene (TrackedFitter::fit), for
/// Scene::observeFitted; the fitted points stay in the cloud's buffer.
struct TrackedFit {
  TrackedState state;
  /// The rest shape it was fitted to: each object a scene makes (added or reset) has a
  /// number of its own; 0 for none.
  std::uint64_t rest_shape = 0;
};

/// Fits a tracked object's clouds on another thread than its scene's: a copy of the object's
/// body (Scene::PreparedObject::trackedFitter, Scene::trackedFitter), whose fits
/// Scene::observeFitted takes over without copying the points. Each fit carries on from the
/// fitter's last one (the clusters' centres as the sums' reference, the rotations as warm
/// starts), as the object's body would from its own: the object then reaches the state that
/// observe() of the same clouds would give it, bit for bit, as long as every cloud it takes
/// goes through the fitter.
class TrackedFitter {
 public:
  /// Fits `points_m` (in the order of the rest shape, non-finite for unobserved points; see
  /// ShapeMatchingBody::track): `fit` gets the clusters' sums and fits, and `points_m` the
  /// fitted points (the cloud's, its holes filled in) in the same buffer, to hand to
  /// Scene::observeFitted with `fit`. Copies no point of a cloud without holes; once `fit`
  /// has held a fit of this object, nothing is allocated.
  /// @return the number of unobserved points.
  /// @throw std::invalid_argument if the size differs; nothing changes then.
  std::size_t fit(std::vector<Eigen::Vector3d>& points_m, TrackedFit& fit);
  std::size_t pointCount() const { return body_.pointCount(); }

 private:
  friend class Scene;
  TrackedFitter(const ShapeMatchingBody& body, std::uint64_t rest_shape)
      : body_(body.trackingCopy()), rest_shape_(rest_shape) {}

  ShapeMatchingBody body_;
  std::uint64_t rest_shape_;
};

}  // namespace deformable_collision
