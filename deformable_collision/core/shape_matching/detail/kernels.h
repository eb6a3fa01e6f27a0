#pragma once

// Internal to the core: the per-point kernels of shape matching, shared by the body, the fit
// and the AVX-512 kernels. They are written on scalars because GCC leaves small Eigen
// assignment loops out of line, which costs a step three times as much.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "deformable_collision/core/shape_matching/shape_matching.h"

namespace deformable_collision::detail {

template <DeformationMode Mode>
constexpr int kFeatureCount = Mode == DeformationMode::kQuadratic ? 9 : 3;

/// Calls action(std::integral_constant<DeformationMode, mode>{}), so that the per-point
/// kernels are compiled per mode.
template <typename Action>
void withMode(DeformationMode mode, Action&& action) {
  switch (mode) {
    case DeformationMode::kRigid:
      action(std::integral_constant<DeformationMode, DeformationMode::kRigid>{});
      break;
    case DeformationMode::kLinear:
      action(std::integral_constant<DeformationMode, DeformationMode::kLinear>{});
      break;
    case DeformationMode::kQuadratic:
      action(std::integral_constant<DeformationMode, DeformationMode::kQuadratic>{});
      break;
  }
}

/// The first K quadratic features of q (q itself unless K is 9).
template <int K>
Eigen::Matrix<double, K, 1> featuresOf(const Eigen::Vector3d& q) {
  if constexpr (K == 9) {
    return quadraticFeatures(q);
  } else {
    return q;
  }
}

/// featuresOf into a plain array.
template <int K>
inline void featureArray(const Eigen::Vector3d& q, double (&f)[K]) {
  f[0] = q.x();
  f[1] = q.y();
  f[2] = q.z();
  if constexpr (K == 9) {
    f[3] = q.x() * q.x();
    f[4] = q.y() * q.y();
    f[5] = q.z() * q.z();
    f[6] = q.x() * q.y();
    f[7] = q.y() * q.z();
    f[8] = q.z() * q.x();
  }
}

/// The mass a cluster's slot lends it: an exclusive point's whole mass or a shared point's share.
inline double slotWeightKg(const Cluster& cluster, std::size_t slot, double point_mass_kg) {
  return slot < cluster.exclusive_count ? point_mass_kg
                                        : cluster.shared_weights_kg[slot - cluster.exclusive_count];
}

/// Weighted sums over a cluster's points, taken relative to a reference point near the
/// cluster (its last centre of mass) so that coordinates far from the origin lose no
/// precision.
template <int K>
struct Moments {
  double offset[3] = {};
  double offset_features[3][K] = {};
  double momentum[3] = {};
  double angular_momentum[3] = {};
  double second_moment[3][3] = {};
};

/// What a pass over slots sums besides the offsets and their products with the features.
enum class MomentTerms {
  kMomentum,         ///< The momentum: what the undamped step needs.
  kMomentumAndSpin,  ///< The momentum, angular momentum and second moment: all of ClusterSums.
  /// The second moment; every velocity is zero and none is read, so the momenta stay zero:
  /// a fit to observed points, which stops them, reads the velocities for nothing.
  kAtRest,
};

/// The terms the step sums: only the damping needs the spin.
template <bool Damped>
inline constexpr MomentTerms kStepTerms =
    Damped ? MomentTerms::kMomentumAndSpin : MomentTerms::kMomentum;

/// The rows and columns of the second moment's upper triangle; the moment is symmetric.
constexpr int kUpperRow[6] = {0, 0, 0, 1, 1, 2};
constexpr int kUpperColumn[6] = {0, 1, 2, 1, 2, 2};
constexpr int kParts = 8;

/// The sum of eight parts, always added up in this order.
inline double sumOfParts(const double (&parts)[kParts]) {
  return ((parts[0] + parts[1]) + (parts[2] + parts[3])) +
         ((parts[4] + parts[5]) + (parts[6] + parts[7]));
}

/// Up to eight slots' terms for PartialMoments::addLanes, one slot per lane: weights w,
/// offsets p from the reference, velocities v and features f.
template <int K>
struct SlotLanes {
  double w[kParts];
  double p[3][kParts];
  double v[3][kParts];
  double f[K][kParts];

  /// Lane n: a slot's features, and its point at x with velocity u (null: not read).
  void set(int n, const double (&features)[K], const double* x, const double* u,
           const Eigen::Vector3d& reference) {
    for (int c = 0; c < K; ++c) f[c][n] = features[c];
    for (int r = 0; r < 3; ++r) {
      p[r][n] = x[r] - reference[r];
      if (u != nullptr) v[r][n] = u[r];
    }
  }
};

/// Moments of a range of a cluster's slots in eight interleaved parts: the range's n-th
/// slot goes to part n % 8. The wide kernels sum eight slots per instruction this way and
/// the portable code sums the same way, lane by lane, so that both give the same bits.
template <int K>
struct PartialMoments {
  double offset[3][kParts] = {};
  double offset_features[3][K][kParts] = {};
  double momentum[3][kParts] = {};
  double angular_momentum[3][kParts] = {};
  double second_moment[6][kParts] = {};  ///< The upper triangle, see kUpperRow.

  /// Adds the first `lanes` of a block of slots, lane n to part n: `Terms` of them. The spin
  /// terms feed only the damping. Unweighted, the weights are not read: a weight of 1 would
  /// multiply nothing.
  template <bool Weighted, MomentTerms Terms>
  void addLanes(int lanes, const SlotLanes<K>& slots) {
    const auto& w = slots.w;
    const auto& p = slots.p;
    const auto& v = slots.v;
    const auto& f = slots.f;
    double wp[3][kParts];
    for (int r = 0; r < 3; ++r) {
      for (int n = 0; n < lanes; ++n) {
        wp[r][n] = Weighted ? w[n] * p[r][n] : p[r][n];
        offset[r][n] += wp[r][n];
      }
      for (int c = 0; c < K; ++c) {
        for (int n = 0; n < lanes; ++n) offset_features[r][c][n] += wp[r][n] * f[c][n];
      }
    }
    if constexpr (Terms != MomentTerms::kAtRest) {
      for (int r = 0; r < 3; ++r) {
        for (int n = 0; n < lanes; ++n) momentum[r][n] += Weighted ? w[n] * v[r][n] : v[r][n];
      }
    }
    if constexpr (Terms == MomentTerms::kMomentumAndSpin) {
      for (int r = 0; r < 3; ++r) {
        const int a = (r + 1) % 3;
        const int b = (r + 2) % 3;
        for (int n = 0; n < lanes; ++n) {
          const double spin = p[a][n] * v[b][n] - p[b][n] * v[a][n];
          angular_momentum[r][n] += Weighted ? w[n] * spin : spin;
        }
      }
    }
    if constexpr (Terms != MomentTerms::kMomentum) {
      for (int e = 0; e < 6; ++e) {
        for (int n = 0; n < lanes; ++n) {
          second_moment[e][n] += wp[kUpperRow[e]][n] * p[kUpperColumn[e]][n];
        }
      }
    }
  }

  Moments<K> total() const {
    Moments<K> m;
    for (int r = 0; r < 3; ++r) {
      m.offset[r] = sumOfParts(offset[r]);
      m.momentum[r] = sumOfParts(momentum[r]);
      m.angular_momentum[r] = sumOfParts(angular_momentum[r]);
      for (int c = 0; c < K; ++c) m.offset_features[r][c] = sumOfParts(offset_features[r][c]);
    }
    for (int e = 0; e < 6; ++e) {
      const double sum = sumOfParts(second_moment[e]);
      m.second_moment[kUpperRow[e]][kUpperColumn[e]] = sum;
      m.second_moment[kUpperColumn[e]][kUpperRow[e]] = sum;
    }
    return m;
  }
};

/// g = T q~ + t on plain arrays, for the per-point kernels.
template <int K>
struct GoalKernel {
  double transform[3][K];
  double translation[3];
  GoalKernel(const Eigen::Matrix<double, 3, 9>& transform_in,
             const Eigen::Vector3d& translation_in) {
    for (int r = 0; r < 3; ++r) {
      translation[r] = translation_in[r];
      for (int c = 0; c < K; ++c) transform[r][c] = transform_in(r, c);
    }
  }
  explicit GoalKernel(const ClusterDeformation& deformation)
      : GoalKernel(deformation.transform, deformation.translation) {}
  void goalFromFeatures(const double (&f)[K], double (&out)[3]) const {
    for (int r = 0; r < 3; ++r) {
      double g = translation[r];
      for (int c = 0; c < K; ++c) g += transform[r][c] * f[c];
      out[r] = g;
    }
  }
  void goal(const Eigen::Vector3d& rest_offset, double (&out)[3]) const {
    double f[K];
    featureArray<K>(rest_offset, f);
    goalFromFeatures(f, out);
  }
};

/// Squared distance from a point to its goal under `kernel`. Eigen sums the squares as the
/// wide kernels do, (x^2 + y^2) + z^2, and lets GCC compute two rows of the goal at once.
template <int K>
double squaredGoalDistance(const GoalKernel<K>& kernel, const Eigen::Vector3d& rest_offset,
                           const Eigen::Vector3d& x) {
  double goal[3];
  kernel.goal(rest_offset, goal);
  return (Eigen::Vector3d(goal[0], goal[1], goal[2]) - x).squaredNorm();
}

/// One step's move of a point towards its goal g: v += damping (u - v), with u the
/// object's rigid velocity at the point, then v += pull (g - x) + kick and x += dt v.
struct StepMotion {
  double dt_s = 0.0;
  double pull = 0.0;
  double damping = 0.0;
  double kick[3] = {};
  double object_center[3] = {};
  double object_velocity[3] = {};
  double object_spin[3] = {};
  /// Made first, as if made before the step.
  DeferredMove deferred;

  template <bool Damped>
  void move(const double (&goal)[3], double* x, double* v) const {
    deferred.apply(x, v);
    double target[3] = {};
    if constexpr (Damped) {
      const double d[3] = {x[0] - object_center[0], x[1] - object_center[1],
                           x[2] - object_center[2]};
      const double* s = object_spin;
      target[0] = object_velocity[0] + (s[1] * d[2] - s[2] * d[1]);
      target[1] = object_velocity[1] + (s[2] * d[0] - s[0] * d[2]);
      target[2] = object_velocity[2] + (s[0] * d[1] - s[1] * d[0]);
    }
    for (int r = 0; r < 3; ++r) {
      if constexpr (Damped) v[r] += damping * (target[r] - v[r]);
      v[r] += pull * (goal[r] - x[r]) + kick[r];
      x[r] += dt_s * v[r];
    }
  }
};

/// Sums `Terms` of slots [begin, end) of `cluster`, eight at a time with the wide vectors if
/// asked; `weights` is null for exclusive slots, whose weight the caller applies.
template <int K, MomentTerms Terms>
Moments<K> accumulate(const Cluster& cluster, std::size_t begin, std::size_t end,
                      const double* weights, const std::vector<Eigen::Vector3d>& positions,
                      const std::vector<Eigen::Vector3d>& velocities,
                      const Eigen::Vector3d& reference, VectorWidth width);

/// The moments of the whole cluster as stored sums about `reference`: all of them, or at
/// rest (MomentTerms::kAtRest: the velocities are zero and not read).
template <int K, MomentTerms Terms>
ClusterSums clusterSums(const Cluster& cluster, double point_mass_kg,
                        const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<Eigen::Vector3d>& velocities,
                        const Eigen::Vector3d& reference, VectorWidth width);

/// Adds `scale` times raw sums to stored sums.
template <int K>
void addScaled(const Moments<K>& m, double scale, ClusterSums& sums) {
  for (int r = 0; r < 3; ++r) {
    sums.offset[r] += scale * m.offset[r];
    sums.momentum[r] += scale * m.momentum[r];
    sums.angular_momentum[r] += scale * m.angular_momentum[r];
    for (int c = 0; c < K; ++c) sums.offset_features(r, c) += scale * m.offset_features[r][c];
    for (int c = 0; c < 3; ++c) sums.second_moment(r, c) += scale * m.second_moment[r][c];
  }
}

}  // namespace deformable_collision::detail
