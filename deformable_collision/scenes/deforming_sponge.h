#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// A soft sponge-like rounded box held across its width by two gripper jaws, whose
/// deformation is known in closed form: the ground truth a registration is scored against.
/// The sponge's frame is its rest centre: x along its length, y across (the jaws' axis),
/// z up.
struct DeformingSpongeConfig {
  Eigen::Vector3d size_m{0.10, 0.06, 0.04};  ///< Length, width, height at rest.
  double corner_radius_m = 0.008;            ///< Edges and corners rounded like a sponge's.
  std::size_t points = 20000;                ///< Surface samples of the model.
  double jaw_length_m = 0.04;                ///< The jaws' plates span |x| <= half of this.
  double jaw_thickness_m = 0.01;
  double max_squeeze_ratio = 0.3;              ///< The width lost between the jaws at most.
  double max_bend_rad = 30.0 * M_PI / 180.0;   ///< Angle between the two end faces at most.
  double max_twist_rad = 10.0 * M_PI / 180.0;  ///< Each end turned about the length at most.
  /// Height gained per width lost under the jaws: foam bulges a little, it is no fluid.
  double bulge_ratio = 0.3;
  std::uint64_t seed = 11;
};

/// The deformation at one moment; all zero is the rest shape.
struct SpongeDeformation {
  double squeeze_ratio = 0.0;
  double bend_rad = 0.0;
  double twist_rad = 0.0;
};

enum class JawSide { kLeft, kRight };  ///< Left at -y, right at +y.

/// The rest model: `points` samples spread uniformly at random over the rounded box's
/// surface (seeded, the same on every platform), in a fixed order: the model order. The
/// deformation squeezes the part between the jaws across its width (and less so beyond
/// them), bends the ends down about y beyond the jaws, and twists them about x in opposite
/// directions; the part between the jaws is only squeezed, so the jaws' flat inner faces
/// touch the sponge's sides there.
class DeformingSponge {
 public:
  /// @throw std::invalid_argument if the sizes, ratios or angles are out of range or the
  /// points too few (fewer than 100).
  explicit DeformingSponge(const DeformingSpongeConfig& config);

  const DeformingSpongeConfig& config() const { return config_; }
  const std::vector<Eigen::Vector3d>& restPoints() const { return rest_points_; }
  /// Outward unit normals of the rest surface at restPoints().
  const std::vector<Eigen::Vector3d>& restNormals() const { return rest_normals_; }
  /// sqrt(surface area / points): the samples' typical spacing at rest.
  double sampleSpacing() const { return sample_spacing_m_; }

  /// One squeeze-bend-release cycle over phase in [0, 1] (repeating beyond): at rest at 0
  /// and 1, the largest deformation of the configuration at 0.5, smooth in between.
  SpongeDeformation deformationAt(double phase) const;

  /// Where rest point `rest` (sponge frame) is under `deformation`.
  Eigen::Vector3d deformed(const Eigen::Vector3d& rest, const SpongeDeformation& deformation) const;
  /// All model points under `deformation`, in model order (resizes `positions`).
  void positions(const SpongeDeformation& deformation,
                 std::vector<Eigen::Vector3d>& positions) const;
  /// The deformed surface's unit normals, through the deformation's Jacobian.
  void normals(const SpongeDeformation& deformation, std::vector<Eigen::Vector3d>& normals) const;

  /// The pose of jaw `side` in the sponge frame: its plate's centre, axes as the sponge's;
  /// its inner face touches the squeezed side.
  Eigen::Isometry3d jawPose(JawSide side, const SpongeDeformation& deformation) const;
  /// Half extents of a jaw's plate: higher than the sponge ever bulges.
  Eigen::Vector3d jawHalfExtents() const;
  /// A jaw's plate as a grid of points `spacing_m` apart in the jaw's frame, its six faces.
  std::vector<Eigen::Vector3d> jawSurfacePoints(double spacing_m) const;

 private:
  void sampleSurface();

  DeformingSpongeConfig config_;
  std::vector<Eigen::Vector3d> rest_points_;
  std::vector<Eigen::Vector3d> rest_normals_;
  double sample_spacing_m_ = 0.0;
};

}  // namespace deformable_collision
