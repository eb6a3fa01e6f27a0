#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "deformable_collision/core/registration/surface_error.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision {

/// The fixed amount of work one cloud costs, and what counts as a match. Units in the names.
struct RegistrationConfig {
  /// Rounds of "match the cloud to the model, refit the clusters" per cloud (>= 1).
  int iterations = 5;
  /// A cloud point farther than this from the model's nearest point is not the object
  /// (table, hand, background) and is left out (> 0).
  double max_correspondence_m = 0.01;
  /// The cloud is thinned to at most this many points, evenly over its order (>= 1).
  std::size_t max_cloud_points = 2000;
  /// The model is matched through at most this many of its points, spread evenly over the
  /// rest shape; the others follow their clusters' fits (>= 1).
  std::size_t max_model_points = 1000;
  /// Fewer matches than this fraction of the thinned cloud means the cloud does not show
  /// the object: the model is held where it was ([0, 1]).
  double min_match_ratio = 0.2;
  /// Scene::registerCloud: a cloud point closer than the scene's contact distance to another
  /// object of the scene (the gripper's jaws, the table) is that object's, not this one's,
  /// and is left out.
  bool exclude_near_other_objects = true;
};

/// Tells the cloud points that belong to something else than the registered object.
class CloudPointFilter {
 public:
  virtual bool excludes(const Eigen::Vector3d& point_m) = 0;

 protected:
  ~CloudPointFilter() = default;
};

/// @throw std::invalid_argument naming the first bad value of `config`.
void validateRegistrationConfig(const RegistrationConfig& config);

/// What registering one cloud did.
struct RegistrationReport {
  bool held = false;                ///< Too few matches: the model was left where it was.
  std::size_t cloud_points = 0;     ///< Finite points of the cloud.
  std::size_t used_points = 0;      ///< Thinned cloud points matched in the last round.
  std::size_t rejected_points = 0;  ///< Thinned cloud points left out in the last round.
  /// Thinned cloud points the filter said were not the object's (left out of the above).
  std::size_t excluded_points = 0;
  double mean_residual_m = 0.0;  ///< Over the used points, from the final model.
  double max_residual_m = 0.0;   ///< Over the used points, from the final model.
  SurfaceError surface_error;    ///< The final model's estimated error, seen and hidden.
  double time_ms = 0.0;          ///< Steady-clock time of the whole registration.
};

/// Correspondence-free registration of a shape-matching model to an unordered, partial,
/// noisy cloud (a depth camera's view of the object), by non-rigid ICP whose deformation
/// model is the body's own clustered shape matching (docs/design.md, registration).
/// Each round matches every thinned cloud point to its nearest model point (a kd-tree over
/// the model's matching points at their current positions, NearestPointIndex), drops matches
/// beyond max_correspondence_m and beyond a robust multiple of the median distance, moves
/// the model rigidly by the matches' best rotation and translation, and registers the body
/// (ShapeMatchingBody::track) on the matched model points' targets: every cluster is fitted
/// on what the camera sees of it, and the points it does not see follow their cluster's
/// fit, so the hidden side is completed by the model. A cluster the camera does not see at
/// all moves with the object's rigid motion. What the cloud's fits turned or shifted the whole
/// object in a direction its matches hardly see (a round object's roll) is taken back, so
/// the model does not drift where nothing holds it. The body's fit residuals, and so the sphere
/// hierarchy's bounds, come from track() as for any registration.
class CloudRegistration {
 public:
  /// @throw std::invalid_argument naming the bad value (validateRegistrationConfig).
  explicit CloudRegistration(const RegistrationConfig& config);
  ~CloudRegistration();
  CloudRegistration(CloudRegistration&&) noexcept;
  CloudRegistration& operator=(CloudRegistration&&) noexcept;

  /// Fits `body` to `cloud_m` (any size and order; non-finite points are skipped),
  /// starting from the body's current state. With `viewpoint_m`, the camera's position in
  /// the cloud's frame, only model points whose surface faces the camera are matched: the
  /// far side of a thin object and the hidden faces next to a seen edge stay out. A cloud with too
  /// few matches (none, all NaN, another object's, far away) leaves the body unchanged and says so
  /// in `held`. Steady state (the same body, clouds no larger than before) allocates nothing.
  /// `filter`, if given, leaves out the thinned cloud points it excludes. The report estimates
  /// the final model's surface error on the side the camera sees and on the other.
  RegistrationReport registerCloud(ShapeMatchingBody& body,
                                   const std::vector<Eigen::Vector3d>& cloud_m,
                                   const std::optional<Eigen::Vector3d>& viewpoint_m = std::nullopt,
                                   CloudPointFilter* filter = nullptr);

  const RegistrationConfig& config() const { return config_; }
  /// Changes the work per cloud from the next cloud on: rounds, and the cloud thinned to.
  /// @throw std::invalid_argument unless both are >= 1; nothing changes then.
  void setWorkPerCloud(int iterations, std::size_t max_cloud_points);

 private:
  struct Workspace;
  RegistrationConfig config_;
  std::unique_ptr<Workspace> workspace_;
};

}  // namespace deformable_collision
