#pragma once

#include <Eigen/Core>
#include <optional>

namespace deformable_collision {

/// How far a registered model's surface is estimated to lie from the object's own (metres,
/// RMS over a side), on the side its last cloud's camera saw and on the side it did not
/// (docs/design.md, "Registration of unordered clouds"). An estimate, not a bound: it misses
/// what no view shows, such as a far side squeezed while the near one is not.
struct SurfaceError {
  /// The seen side: the RMS distance of the used cloud points to the model's surface (the
  /// camera's noise included).
  double seen_m = 0.0;
  /// The hidden side: seen_m plus twice the RMS disagreement of the clusters' fits at the
  /// model points facing away from the camera, where each cluster extrapolates its own fit.
  double hidden_m = 0.0;
  /// The camera's position the sides were told by; without one, seen_m = hidden_m, the
  /// disagreement taken over the whole model.
  std::optional<Eigen::Vector3d> viewpoint_m;

  /// The estimate at a surface point at `position_m` whose outward normal is `outward`:
  /// seen_m if it faces the viewpoint, hidden_m otherwise.
  double at(const Eigen::Vector3d& position_m, const Eigen::Vector3d& outward) const {
    if (!viewpoint_m) return hidden_m;
    return outward.dot(*viewpoint_m - position_m) > 0.0 ? seen_m : hidden_m;
  }
};

}  // namespace deformable_collision
