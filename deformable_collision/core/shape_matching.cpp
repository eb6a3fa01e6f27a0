#include "deformable_collision/core/shape_matching.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

#include "deformable_collision/core/clustering.h"
#include "deformable_collision/core/linear_algebra.h"

namespace deformable_collision {
namespace {

template <DeformationMode Mode>
constexpr int kFeatureCount = Mode == DeformationMode::kQuadratic ? 9 : 3;

template <int K>
Eigen::Matrix<double, K, 1> featuresOf(const Eigen::Vector3d& q) {
  if constexpr (K == 9) {
    return quadraticFeatures(q);
  } else {
    return q;
  }
}

// The per-point kernels below are written on scalars: with Eigen expressions GCC left
// small assignment loops out of line, which tripled the cost of a step.

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

  /// Lane n: a slot's features, and its point at x with velocity u.
  void set(int n, const double (&features)[K], const double* x, const double* u,
           const Eigen::Vector3d& reference) {
    for (int c = 0; c < K; ++c) f[c][n] = features[c];
    for (int r = 0; r < 3; ++r) {
      p[r][n] = x[r] - reference[r];
      v[r][n] = u[r];
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

  /// Adds the first `lanes` of a block of slots, lane n to part n. Momentum feeds the
  /// centre-of-mass prediction; spin terms feed the damping. Unweighted, the weights are not
  /// read: a weight of 1 would multiply nothing.
  template <bool Weighted, bool WithMomentum, bool WithSpin>
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
    if constexpr (WithMomentum) {
      for (int r = 0; r < 3; ++r) {
        for (int n = 0; n < lanes; ++n) momentum[r][n] += Weighted ? w[n] * v[r][n] : v[r][n];
      }
      if constexpr (WithSpin) {
        for (int r = 0; r < 3; ++r) {
          const int a = (r + 1) % 3;
          const int b = (r + 2) % 3;
          for (int n = 0; n < lanes; ++n) {
            const double spin = p[a][n] * v[b][n] - p[b][n] * v[a][n];
            angular_momentum[r][n] += Weighted ? w[n] * spin : spin;
          }
        }
        for (int e = 0; e < 6; ++e) {
          for (int n = 0; n < lanes; ++n) {
            second_moment[e][n] += wp[kUpperRow[e]][n] * p[kUpperColumn[e]][n];
          }
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
  GoalKernel(const Eigen::Matrix<double, 3, 9>& transform_in, const Eigen::Vector3d& translation_in) {
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

  template <bool Damped>
  void move(const double (&goal)[3], double* x, double* v) const {
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

// The wide kernels take the goal kernel, the motion and the reference by value: a local
// whose address went out of line could alias the points the portable loops then write, and
// those loops would read it again after every point.
// The gathers below take a point's index times 3 as a 32-bit offset in doubles.
constexpr std::size_t kMostWidePoints = std::size_t{1} << 29;
static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "points are packed triples");

#if defined(__GNUC__) && defined(__x86_64__)
// GCC 12's AVX-512 intrinsics pass a deliberately undefined operand that its own
// uninitialised-use warnings then report (GCC bug 105593).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#if !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

/// a x b, component `row`, as the portable code computes it: a[i] b[j] - a[j] b[i].
__attribute__((target("avx512f"))) inline __m512d crossComponent(int row, const __m512d (&a)[3],
                                                                 const __m512d (&b)[3]) {
  const int i = (row + 1) % 3;
  const int j = (row + 2) % 3;
  return _mm512_sub_pd(_mm512_mul_pd(a[i], b[j]), _mm512_mul_pd(a[j], b[i]));
}

/// Offsets, in doubles, of the points of the cluster's eight slots from `slot` on.
__attribute__((target("avx512f"))) inline __m256i pointOffsets(const Cluster& cluster,
                                                               std::size_t slot) {
  const __m256i points =
      _mm256_loadu_si256(reinterpret_cast<const __m256i*>(cluster.points.data() + slot));
  return _mm256_add_epi32(points, _mm256_add_epi32(points, points));
}

/// The features of the cluster's eight slots from `slot` on, each as featureArray gives it.
template <int K>
__attribute__((target("avx512f"))) inline void wideFeatures(const Cluster& cluster,
                                                            std::size_t slot, __m512d (&f)[K]) {
  // Eight packed triples, split into their x, y and z.
  const double* rest = cluster.rest_offsets[slot].data();
  const __m512d a = _mm512_loadu_pd(rest);
  const __m512d b = _mm512_loadu_pd(rest + 8);
  const __m512d c = _mm512_loadu_pd(rest + 16);
  // Coordinate r of slot n sits at 3 n + r: first taken from a and b, then the rest from c.
  const __m512i from_a_and_b[3] = {_mm512_setr_epi64(0, 3, 6, 9, 12, 15, 0, 0),
                                   _mm512_setr_epi64(1, 4, 7, 10, 13, 0, 0, 0),
                                   _mm512_setr_epi64(2, 5, 8, 11, 14, 0, 0, 0)};
  const __m512i from_c[3] = {_mm512_setr_epi64(0, 1, 2, 3, 4, 5, 10, 13),
                             _mm512_setr_epi64(0, 1, 2, 3, 4, 8, 11, 14),
                             _mm512_setr_epi64(0, 1, 2, 3, 4, 9, 12, 15)};
  for (int r = 0; r < 3; ++r) {
    f[r] = _mm512_permutex2var_pd(_mm512_permutex2var_pd(a, from_a_and_b[r], b), from_c[r], c);
  }
  if constexpr (K == 9) {
    f[3] = _mm512_mul_pd(f[0], f[0]);
    f[4] = _mm512_mul_pd(f[1], f[1]);
    f[5] = _mm512_mul_pd(f[2], f[2]);
    f[6] = _mm512_mul_pd(f[0], f[1]);
    f[7] = _mm512_mul_pd(f[1], f[2]);
    f[8] = _mm512_mul_pd(f[2], f[0]);
  }
}

/// Eight consecutive slots of a cluster, from `slot` on: the offsets of their points, their
/// features and their goals, each computed as GoalKernel::goal does.
template <int K>
struct WideGoals {
  __m256i point_offsets;
  __m512d features[K];
  __m512d goal[3];

  __attribute__((target("avx512f"))) WideGoals(const GoalKernel<K>& kernel,
                                                const Cluster& cluster, std::size_t slot) {
    point_offsets = pointOffsets(cluster, slot);
    wideFeatures<K>(cluster, slot, features);
    for (int r = 0; r < 3; ++r) {
      __m512d g = _mm512_set1_pd(kernel.translation[r]);
      for (int c = 0; c < K; ++c) {
        g = _mm512_add_pd(g, _mm512_mul_pd(_mm512_set1_pd(kernel.transform[r][c]), features[c]));
      }
      goal[r] = g;
    }
  }
};

/// PartialMoments with its eight parts in the lanes of wide vectors.
template <int K>
struct WideMoments {
  __m512d offset[3];
  __m512d offset_features[3][K];
  __m512d momentum[3];
  __m512d angular_momentum[3];
  __m512d second_moment[6];

  __attribute__((target("avx512f"))) WideMoments() {
    for (int r = 0; r < 3; ++r) {
      offset[r] = momentum[r] = angular_momentum[r] = _mm512_setzero_pd();
      for (int c = 0; c < K; ++c) offset_features[r][c] = _mm512_setzero_pd();
    }
    for (int e = 0; e < 6; ++e) second_moment[e] = _mm512_setzero_pd();
  }

  /// PartialMoments::addLanes for eight slots, one per part.
  template <bool Weighted, bool WithMomentum, bool WithSpin>
  __attribute__((target("avx512f"))) void add(__m512d w, const __m512d (&p)[3],
                                               const __m512d (&v)[3], const __m512d (&f)[K]) {
    __m512d wp[3];
    for (int r = 0; r < 3; ++r) {
      wp[r] = Weighted ? _mm512_mul_pd(w, p[r]) : p[r];
      offset[r] = _mm512_add_pd(offset[r], wp[r]);
      for (int c = 0; c < K; ++c) {
        offset_features[r][c] = _mm512_add_pd(offset_features[r][c], _mm512_mul_pd(wp[r], f[c]));
      }
    }
    if constexpr (WithMomentum) {
      for (int r = 0; r < 3; ++r) {
        momentum[r] = _mm512_add_pd(momentum[r], Weighted ? _mm512_mul_pd(w, v[r]) : v[r]);
      }
      if constexpr (WithSpin) {
        for (int r = 0; r < 3; ++r) {
          const __m512d spin = crossComponent(r, p, v);
          angular_momentum[r] =
              _mm512_add_pd(angular_momentum[r], Weighted ? _mm512_mul_pd(w, spin) : spin);
        }
        for (int e = 0; e < 6; ++e) {
          second_moment[e] = _mm512_add_pd(second_moment[e],
                                           _mm512_mul_pd(wp[kUpperRow[e]], p[kUpperColumn[e]]));
        }
      }
    }
  }

  /// Writes the parts to `sums`, which hold nothing yet.
  __attribute__((target("avx512f"))) void storeTo(PartialMoments<K>& sums) const {
    for (int r = 0; r < 3; ++r) {
      _mm512_storeu_pd(sums.offset[r], offset[r]);
      _mm512_storeu_pd(sums.momentum[r], momentum[r]);
      _mm512_storeu_pd(sums.angular_momentum[r], angular_momentum[r]);
      for (int c = 0; c < K; ++c) {
        _mm512_storeu_pd(sums.offset_features[r][c], offset_features[r][c]);
      }
    }
    for (int e = 0; e < 6; ++e) _mm512_storeu_pd(sums.second_moment[e], second_moment[e]);
  }
};

/// The first slots of [begin, end), eight at a time, into `sums` (which hold nothing yet);
/// returns the first slot left for the portable code.
template <int K, bool WithMomentum, bool WithSpin>
__attribute__((target("avx512f"))) std::size_t accumulateAvx512(
    const Cluster& cluster, std::size_t begin, std::size_t end, const double* weights,
    const Eigen::Vector3d* positions, const Eigen::Vector3d* velocities,
    const Eigen::Vector3d reference, PartialMoments<K>& sums) {
  WideMoments<K> moments;
  std::size_t slot = begin;
  for (; slot + 8 <= end; slot += 8) {
    const __m256i offsets = pointOffsets(cluster, slot);
    __m512d f[K];
    wideFeatures<K>(cluster, slot, f);
    __m512d p[3];
    __m512d v[3];
    for (int r = 0; r < 3; ++r) {
      const __m512d x = _mm512_i32gather_pd(offsets, positions->data() + r, 8);
      p[r] = _mm512_sub_pd(x, _mm512_set1_pd(reference[r]));
      v[r] = WithMomentum ? _mm512_i32gather_pd(offsets, velocities->data() + r, 8)
                          : _mm512_setzero_pd();
    }
    if (weights != nullptr) {
      moments.template add<true, WithMomentum, WithSpin>(_mm512_loadu_pd(weights + (slot - begin)),
                                                         p, v, f);
    } else {
      moments.template add<false, WithMomentum, WithSpin>(_mm512_setzero_pd(), p, v, f);
    }
  }
  moments.storeTo(sums);
  return slot;
}

/// The cluster's first exclusive slots, eight at a time: each point makes the step's move
/// (StepMotion::move) and is added to `sums` (which hold nothing yet). Returns the first
/// slot left for the portable code.
template <int K, bool Damped>
__attribute__((target("avx512f"))) std::size_t moveExclusiveAvx512(
    const GoalKernel<K> kernel, const Cluster& cluster, const StepMotion motion,
    Eigen::Vector3d* positions, Eigen::Vector3d* velocities, const Eigen::Vector3d reference,
    PartialMoments<K>& sums) {
  double* xs = positions->data();
  double* vs = velocities->data();
  WideMoments<K> moments;
  std::size_t slot = 0;
  // A cluster holds a point once, so the eight slots scatter to eight different points.
  for (; slot + 8 <= cluster.exclusive_count; slot += 8) {
    const WideGoals<K> wide(kernel, cluster, slot);
    __m512d x[3];
    __m512d v[3];
    for (int r = 0; r < 3; ++r) {
      x[r] = _mm512_i32gather_pd(wide.point_offsets, xs + r, 8);
      v[r] = _mm512_i32gather_pd(wide.point_offsets, vs + r, 8);
    }
    __m512d target[3];
    if constexpr (Damped) {
      __m512d spin[3];
      __m512d d[3];
      for (int r = 0; r < 3; ++r) {
        spin[r] = _mm512_set1_pd(motion.object_spin[r]);
        d[r] = _mm512_sub_pd(x[r], _mm512_set1_pd(motion.object_center[r]));
      }
      for (int r = 0; r < 3; ++r) {
        target[r] = _mm512_add_pd(_mm512_set1_pd(motion.object_velocity[r]),
                                  crossComponent(r, spin, d));
      }
    }
    __m512d p[3];
    for (int r = 0; r < 3; ++r) {
      if constexpr (Damped) {
        v[r] = _mm512_add_pd(
            v[r], _mm512_mul_pd(_mm512_set1_pd(motion.damping), _mm512_sub_pd(target[r], v[r])));
      }
      const __m512d pull =
          _mm512_mul_pd(_mm512_set1_pd(motion.pull), _mm512_sub_pd(wide.goal[r], x[r]));
      v[r] = _mm512_add_pd(v[r], _mm512_add_pd(pull, _mm512_set1_pd(motion.kick[r])));
      x[r] = _mm512_add_pd(x[r], _mm512_mul_pd(_mm512_set1_pd(motion.dt_s), v[r]));
      _mm512_i32scatter_pd(xs + r, wide.point_offsets, x[r], 8);
      _mm512_i32scatter_pd(vs + r, wide.point_offsets, v[r], 8);
      p[r] = _mm512_sub_pd(x[r], _mm512_set1_pd(reference[r]));
    }
    moments.template add<false, true, Damped>(_mm512_setzero_pd(), p, v, wide.features);
  }
  moments.storeTo(sums);
  return slot;
}

/// Adds the goals of the cluster's shared slots to `goal_sums`, eight at a time; returns
/// the first slot left for the portable code.
template <int K>
__attribute__((target("avx512f"))) std::size_t addSharedGoalsAvx512(const GoalKernel<K> kernel,
                                                                    const Cluster& cluster,
                                                                    Eigen::Vector3d* goal_sums) {
  double* sums = goal_sums->data();
  std::size_t slot = cluster.exclusive_count;
  for (; slot + 8 <= cluster.points.size(); slot += 8) {
    const WideGoals<K> wide(kernel, cluster, slot);
    for (int r = 0; r < 3; ++r) {
      const __m512d sum = _mm512_i32gather_pd(wide.point_offsets, sums + r, 8);
      _mm512_i32scatter_pd(sums + r, wide.point_offsets, _mm512_add_pd(sum, wide.goal[r]), 8);
    }
  }
  return slot;
}

/// The largest squaredGoalDistance over the cluster's slots, eight at a time, with the
/// first slot left for the portable code.
template <int K>
__attribute__((target("avx512f"))) std::pair<double, std::size_t> largestSquaredGoalDistanceAvx512(
    const GoalKernel<K> kernel, const Cluster& cluster, const Eigen::Vector3d* positions) {
  const double* coordinates = positions->data();
  __m512d largest = _mm512_setzero_pd();
  std::size_t slot = 0;
  for (; slot + 8 <= cluster.points.size(); slot += 8) {
    const WideGoals<K> wide(kernel, cluster, slot);
    __m512d squared = _mm512_setzero_pd();
    for (int r = 0; r < 3; ++r) {
      const __m512d x = _mm512_i32gather_pd(wide.point_offsets, coordinates + r, 8);
      const __m512d e = _mm512_sub_pd(wide.goal[r], x);
      squared = r == 0 ? _mm512_mul_pd(e, e) : _mm512_add_pd(squared, _mm512_mul_pd(e, e));
    }
    // As std::max(largest, squared) in the portable code: a NaN distance is passed over.
    largest = _mm512_max_pd(squared, largest);
  }
  return {_mm512_reduce_max_pd(largest), slot};
}

#pragma GCC diagnostic pop
#endif

/// Sums slots [begin, end) of `cluster`; `weights` is null for exclusive slots, whose
/// weight the caller applies.
template <int K, bool WithMomentum, bool WithSpin>
Moments<K> accumulate(const Cluster& cluster, std::size_t begin, std::size_t end,
                      const double* weights, const std::vector<Eigen::Vector3d>& positions,
                      const std::vector<Eigen::Vector3d>& velocities,
                      const Eigen::Vector3d& reference, [[maybe_unused]] bool wide_vectors) {
  PartialMoments<K> sums;
  std::size_t j = begin;
#if defined(__GNUC__) && defined(__x86_64__)
  if (wide_vectors) {
    j = accumulateAvx512<K, WithMomentum, WithSpin>(cluster, begin, end, weights, positions.data(),
                                                    velocities.data(), reference, sums);
  }
#endif
  // The wide vectors took whole blocks of eight, so slot j + n goes to part n.
  for (; j < end; j += kParts) {
    const int lanes = static_cast<int>(std::min<std::size_t>(kParts, end - j));
    SlotLanes<K> slots;
    for (int n = 0; n < lanes; ++n) {
      const std::uint32_t i = cluster.points[j + n];
      double features[K];
      featureArray<K>(cluster.rest_offsets[j + n], features);
      slots.set(n, features, positions[i].data(), velocities[i].data(), reference);
      if (weights != nullptr) slots.w[n] = weights[j + n - begin];
    }
    if (weights != nullptr) {
      sums.template addLanes<true, WithMomentum, WithSpin>(lanes, slots);
    } else {
      sums.template addLanes<false, WithMomentum, WithSpin>(lanes, slots);
    }
  }
  return sums.total();
}

/// Moments of the whole cluster, in kg-weighted units.
template <int K, bool WithMomentum, bool WithSpin>
Moments<K> clusterMoments(const Cluster& cluster, double point_mass_kg,
                          const std::vector<Eigen::Vector3d>& positions,
                          const std::vector<Eigen::Vector3d>& velocities,
                          const Eigen::Vector3d& reference, bool wide_vectors) {
  Moments<K> exclusive = accumulate<K, WithMomentum, WithSpin>(
      cluster, 0, cluster.exclusive_count, nullptr, positions, velocities, reference, wide_vectors);
  const Moments<K> shared = accumulate<K, WithMomentum, WithSpin>(
      cluster, cluster.exclusive_count, cluster.points.size(), cluster.shared_weights_kg.data(),
      positions, velocities, reference, wide_vectors);
  for (int r = 0; r < 3; ++r) {
    exclusive.offset[r] = point_mass_kg * exclusive.offset[r] + shared.offset[r];
    exclusive.momentum[r] = point_mass_kg * exclusive.momentum[r] + shared.momentum[r];
    exclusive.angular_momentum[r] =
        point_mass_kg * exclusive.angular_momentum[r] + shared.angular_momentum[r];
    for (int c = 0; c < K; ++c) {
      exclusive.offset_features[r][c] =
          point_mass_kg * exclusive.offset_features[r][c] + shared.offset_features[r][c];
    }
    for (int c = 0; c < 3; ++c) {
      exclusive.second_moment[r][c] =
          point_mass_kg * exclusive.second_moment[r][c] + shared.second_moment[r][c];
    }
  }
  return exclusive;
}

/// Moments of the whole cluster as stored sums.
template <int K, bool WithMomentum, bool WithSpin>
ClusterSums clusterSums(const Cluster& cluster, double point_mass_kg,
                        const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<Eigen::Vector3d>& velocities,
                        const Eigen::Vector3d& reference, bool wide_vectors) {
  const Moments<K> m = clusterMoments<K, WithMomentum, WithSpin>(
      cluster, point_mass_kg, positions, velocities, reference, wide_vectors);
  ClusterSums sums;
  sums.reference = reference;
  for (int r = 0; r < 3; ++r) {
    sums.offset[r] = m.offset[r];
    sums.momentum[r] = m.momentum[r];
    sums.angular_momentum[r] = m.angular_momentum[r];
    for (int c = 0; c < K; ++c) sums.offset_features(r, c) = m.offset_features[r][c];
    for (int c = 0; c < 3; ++c) sums.second_moment(r, c) = m.second_moment[r][c];
  }
  return sums;
}

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

/// Registers a cluster on its sums: sets the centre of mass, updates the warm-started
/// rotation and returns the least-squares transform (R alone for a rigid cluster).
template <DeformationMode Mode, int K = kFeatureCount<Mode>>
Eigen::Matrix<double, 3, K> fitCluster(const Cluster& cluster, const ClusterSums& sums,
                                       ClusterDeformation& deformation) {
  const double mass = cluster.total_weight_kg;
  const Eigen::Vector3d shift = sums.offset / mass;
  const Eigen::Matrix<double, 3, K> moment_pq =
      sums.offset_features.template leftCols<K>() -
      mass * shift * cluster.mean_features.template head<K>().transpose();
  extractRotation(moment_pq.template leftCols<3>(), deformation.rotation);
  deformation.center_of_mass = sums.reference + shift;
  const Eigen::Matrix3d rotation = deformation.rotation.toRotationMatrix();
  if constexpr (Mode == DeformationMode::kRigid) {
    return rotation;
  } else {
    return moment_pq * cluster.moment_inverse.template topLeftCorner<K, K>() +
           rotation * cluster.null_completion.template leftCols<K>();
  }
}

template <int K>
void setGoalTransform(const Cluster& cluster, const Eigen::Matrix<double, 3, K>& transform,
                      ClusterDeformation& deformation) {
  deformation.transform.setZero();
  deformation.transform.template leftCols<K>() = transform;
  deformation.translation =
      deformation.center_of_mass - transform * cluster.mean_features.template head<K>();
}

/// @throw std::invalid_argument unless `values` has one finite vector per point.
void requireOnePerPoint(const std::vector<Eigen::Vector3d>& values, std::size_t points,
                        const char* what, const char* plural) {
  if (values.size() != points) {
    throw std::invalid_argument("got " + std::to_string(values.size()) + " " + plural +
                                " for an object of " + std::to_string(points) + " points");
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i].allFinite()) {
      throw std::invalid_argument(std::string(what) + " " + std::to_string(i) + " is not finite");
    }
  }
}

std::string describe(const char* field, double value, const char* requirement) {
  std::ostringstream out;
  out << "ShapeMatchingConfig." << field << " = " << value << " " << requirement;
  return out.str();
}

void validate(const std::vector<Eigen::Vector3d>& rest_points, const ShapeMatchingConfig& c) {
  if (rest_points.empty()) throw std::invalid_argument("rest shape has no points");
  for (std::size_t i = 0; i < rest_points.size(); ++i) {
    if (!rest_points[i].allFinite()) {
      std::ostringstream out;
      out << "rest point " << i << " = (" << rest_points[i].transpose() << ") is not finite";
      throw std::invalid_argument(out.str());
    }
  }
  const auto in_unit_interval = [](double v) { return v >= 0.0 && v <= 1.0; };
  if (!(c.mass_kg > 0.0) || !std::isfinite(c.mass_kg)) {
    throw std::invalid_argument(describe("mass_kg", c.mass_kg, "must be finite and > 0"));
  }
  if (!in_unit_interval(c.stiffness)) {
    throw std::invalid_argument(describe("stiffness", c.stiffness, "is outside [0, 1]"));
  }
  if (!in_unit_interval(c.beta)) {
    throw std::invalid_argument(describe("beta", c.beta, "is outside [0, 1]"));
  }
  if (!in_unit_interval(c.damping)) {
    throw std::invalid_argument(describe("damping", c.damping, "is outside [0, 1]"));
  }
  if (c.clusters < 1 || static_cast<std::size_t>(c.clusters) > rest_points.size()) {
    std::ostringstream out;
    out << "ShapeMatchingConfig.clusters = " << c.clusters << " must be in [1, "
        << rest_points.size() << "] (the number of points)";
    throw std::invalid_argument(out.str());
  }
  if (!(c.cluster_overlap_ratio >= 0.0) || !std::isfinite(c.cluster_overlap_ratio)) {
    throw std::invalid_argument(
        describe("cluster_overlap_ratio", c.cluster_overlap_ratio, "must be finite and >= 0"));
  }
}

/// Pseudo-inverse of a feature moment matrix into the top-left block of `inverse`, and the
/// completion N that lets unspanned directions follow the rotation (see Cluster).
template <int K>
void invertFeatureMoment(const Eigen::Matrix<double, K, K>& moment, double radius_m,
                         Eigen::Matrix<double, 9, 9>& inverse,
                         Eigen::Matrix<double, 3, 9>& completion) {
  inverse.setZero();
  completion.setZero();
  if constexpr (K == 3) {
    const auto result = pseudoInverseSymmetric<3>(moment);
    inverse.topLeftCorner<3, 3>() = result.inverse;
    completion.leftCols<3>() = result.null_projector;
  } else {
    // Linear and quadratic features differ in units by a length; scaling them by the
    // cluster radius keeps the eigenvalue cut-off meaningful from 1e-4 m to 1e4 m.
    const double s = radius_m > 0.0 ? radius_m : 1.0;
    Eigen::Matrix<double, 9, 1> unscale;
    unscale << 1 / s, 1 / s, 1 / s, 1 / (s * s), 1 / (s * s), 1 / (s * s), 1 / (s * s),
        1 / (s * s), 1 / (s * s);
    const Eigen::Matrix<double, 9, 9> scaled =
        unscale.asDiagonal() * moment * unscale.asDiagonal();
    const auto result = pseudoInverseSymmetric<9>(scaled);
    inverse = unscale.asDiagonal() * result.inverse * unscale.asDiagonal();
    completion = s * result.null_projector.topRows<3>() * unscale.asDiagonal();
  }
}

double slotWeightKg(const Cluster& cluster, std::size_t slot, double point_mass_kg) {
  return slot < cluster.exclusive_count ? point_mass_kg
                                        : cluster.shared_weights_kg[slot - cluster.exclusive_count];
}

/// Fills the rest-shape moments of a cluster whose points, weights and offsets are set.
void precomputeMoments(Cluster& cluster, DeformationMode mode, double point_mass_kg) {
  double second_moment = 0.0;
  Eigen::Matrix<double, 9, 1> feature_sum = Eigen::Matrix<double, 9, 1>::Zero();
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    feature_sum += slotWeightKg(cluster, j, point_mass_kg) * quadraticFeatures(cluster.rest_offsets[j]);
    second_moment += slotWeightKg(cluster, j, point_mass_kg) * cluster.rest_offsets[j].squaredNorm();
  }
  cluster.mean_features = feature_sum / cluster.total_weight_kg;
  for (const auto& q : cluster.rest_offsets) {
    const double norm = mode == DeformationMode::kQuadratic ? quadraticFeatures(q).norm() : q.norm();
    cluster.max_feature_norm = std::max(cluster.max_feature_norm, norm);
  }

  if (mode == DeformationMode::kLinear) {
    Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Vector3d q = cluster.rest_offsets[j] - cluster.mean_features.head<3>();
      moment.noalias() += slotWeightKg(cluster, j, point_mass_kg) * q * q.transpose();
    }
    invertFeatureMoment<3>(moment, 1.0, cluster.moment_inverse, cluster.null_completion);
  } else if (mode == DeformationMode::kQuadratic) {
    Eigen::Matrix<double, 9, 9> moment = Eigen::Matrix<double, 9, 9>::Zero();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Matrix<double, 9, 1> f =
          quadraticFeatures(cluster.rest_offsets[j]) - cluster.mean_features;
      moment.noalias() += slotWeightKg(cluster, j, point_mass_kg) * f * f.transpose();
    }
    invertFeatureMoment<9>(moment, std::sqrt(second_moment / cluster.total_weight_kg),
                           cluster.moment_inverse, cluster.null_completion);
  }
}

/// Fits a cluster on the slots whose points were observed (`seen`), with the moment
/// matrices of that subset: points left at stale positions would drag the fit. A cluster
/// with no observed point keeps its last transform.
template <DeformationMode Mode, typename Seen, int K = kFeatureCount<Mode>>
void fitObservedSubset(const Cluster& cluster, double point_mass_kg,
                       const std::vector<Eigen::Vector3d>& positions, const Seen& seen,
                       ClusterDeformation& deformation) {
  using Features = Eigen::Matrix<double, K, 1>;
  const Eigen::Vector3d reference = deformation.center_of_mass;
  double mass = 0.0;
  Features feature_sum = Features::Zero();
  Eigen::Vector3d offset_sum = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    if (!seen(cluster.points[j])) continue;
    const double w = slotWeightKg(cluster, j, point_mass_kg);
    mass += w;
    feature_sum += w * featuresOf<K>(cluster.rest_offsets[j]);
    offset_sum += w * (positions[cluster.points[j]] - reference);
  }
  if (!(mass > 0.0)) return;
  const Features mean_features = feature_sum / mass;
  const Eigen::Vector3d center = reference + offset_sum / mass;
  Eigen::Matrix<double, 3, K> moment_pq = Eigen::Matrix<double, 3, K>::Zero();
  Eigen::Matrix<double, K, K> moment_qq = Eigen::Matrix<double, K, K>::Zero();
  double second_moment = 0.0;
  for (std::size_t j = 0; j < cluster.points.size(); ++j) {
    if (!seen(cluster.points[j])) continue;
    const double w = slotWeightKg(cluster, j, point_mass_kg);
    const Features f = featuresOf<K>(cluster.rest_offsets[j]) - mean_features;
    moment_pq.noalias() += w * (positions[cluster.points[j]] - center) * f.transpose();
    moment_qq.noalias() += w * f * f.transpose();
    second_moment += w * f.template head<3>().squaredNorm();
  }
  extractRotation(moment_pq.template leftCols<3>(), deformation.rotation);
  const Eigen::Matrix3d rotation = deformation.rotation.toRotationMatrix();
  Eigen::Matrix<double, 3, K> transform;
  if constexpr (Mode == DeformationMode::kRigid) {
    transform = rotation;
  } else {
    Eigen::Matrix<double, 9, 9> inverse;
    Eigen::Matrix<double, 3, 9> completion;
    invertFeatureMoment<K>(moment_qq, std::sqrt(second_moment / mass), inverse, completion);
    transform = moment_pq * inverse.template topLeftCorner<K, K>() +
                rotation * completion.template leftCols<K>();
  }
  deformation.transform.setZero();
  deformation.transform.template leftCols<K>() = transform;
  deformation.translation = center - transform * mean_features;
  deformation.center_of_mass =
      deformation.translation + transform * cluster.mean_features.template head<K>();
}

/// Linear transform to a goal: the (volume-preserving) fit blended with the rotation.
/// The fit is taken as R S (polar form), and the eigenvalues of the stretch S are clamped
/// from below at a tenth of the largest before the volume is normalised: a flattened or
/// inverted fit then yields a proper, bounded goal that varies continuously with the
/// points. Dividing by cbrt(det A) as printed, with a switch to R at det <= 0, lets an
/// overshooting object pass through flat into inversion, and the goal's jumps there feed
/// energy in (measured: an undamped cube at beta 0.7 grew 700-fold in 3000 steps).
Eigen::Matrix3d linearGoalTransform(const Eigen::Matrix3d& fit,
                                    const Eigen::Quaterniond& rotation, double beta,
                                    bool preserve_volume) {
  const Eigen::Matrix3d r = rotation.toRotationMatrix();
  if (!preserve_volume) return beta * fit + (1.0 - beta) * r;
  // R rotates A_pq = A A_qq; the stretch of A itself needs A's own polar rotation, which is
  // close to R, so R is the warm start.
  Eigen::Quaterniond fit_rotation = rotation;
  extractRotation(fit, fit_rotation);
  const Eigen::Matrix3d fit_r = fit_rotation.toRotationMatrix();
  const Eigen::Matrix3d unsymmetric_stretch = fit_r.transpose() * fit;
  const Eigen::Matrix3d stretch = 0.5 * (unsymmetric_stretch + unsymmetric_stretch.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(stretch);
  Eigen::Vector3d principal = solver.eigenvalues();
  const double largest = principal.cwiseAbs().maxCoeff();
  Eigen::Matrix3d volume_preserving = r;
  if (largest > 0.0 && std::isfinite(largest)) {
    principal = principal.cwiseMax(0.1 * largest);
    principal /= std::cbrt(principal.prod());
    volume_preserving =
        fit_r * solver.eigenvectors() * principal.asDiagonal() * solver.eigenvectors().transpose();
  }
  return beta * volume_preserving + (1.0 - beta) * r;
}

}  // namespace

std::optional<DeformationMode> parseDeformationMode(const std::string& name) {
  if (name == "rigid") return DeformationMode::kRigid;
  if (name == "linear") return DeformationMode::kLinear;
  if (name == "quadratic") return DeformationMode::kQuadratic;
  return std::nullopt;
}

const char* toString(DeformationMode mode) {
  switch (mode) {
    case DeformationMode::kRigid:
      return "rigid";
    case DeformationMode::kLinear:
      return "linear";
    case DeformationMode::kQuadratic:
      return "quadratic";
  }
  return "unknown";
}

ShapeMatchingBody::ShapeMatchingBody(std::vector<Eigen::Vector3d> rest_points,
                                     const ShapeMatchingConfig& config,
                                     bool use_wide_vectors)
    : config_(config) {
  validate(rest_points, config);
  wide_vectors_ =
      use_wide_vectors && wideVectorsAvailable() && rest_points.size() <= kMostWidePoints;
  const std::size_t n = rest_points.size();
  point_mass_kg_ = config.mass_kg / static_cast<double>(n);
  rest_positions_ = std::move(rest_points);
  positions_ = rest_positions_;
  velocities_.assign(n, Eigen::Vector3d::Zero());
  goal_sums_.assign(n, Eigen::Vector3d::Zero());

  auto memberships =
      partitionIntoClusters(rest_positions_, config.clusters, config.cluster_overlap_ratio);
  membership_counts_.assign(n, 0);
  for (const auto& members : memberships) {
    for (const auto i : members) ++membership_counts_[i];
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    if (membership_counts_[i] > 1) shared_points_.push_back(i);
  }

  clusters_.resize(memberships.size());
  for (std::size_t k = 0; k < memberships.size(); ++k) {
    Cluster& cluster = clusters_[k];
    const auto& members = memberships[k];
    for (const auto i : members) {
      if (membership_counts_[i] == 1) cluster.points.push_back(i);
    }
    cluster.exclusive_count = cluster.points.size();
    for (const auto i : members) {
      if (membership_counts_[i] > 1) {
        cluster.points.push_back(i);
        cluster.shared_weights_kg.push_back(point_mass_kg_ / membership_counts_[i]);
      }
    }
    const std::size_t size = cluster.points.size();
    // Summing offsets from one of the cluster's points keeps x_cm^0 exact far from the origin.
    const Eigen::Vector3d anchor = rest_positions_[cluster.points.front()];
    Eigen::Vector3d weighted_offset_sum = Eigen::Vector3d::Zero();
    for (std::size_t j = 0; j < size; ++j) {
      const double weight = slotWeightKg(cluster, j, point_mass_kg_);
      cluster.total_weight_kg += weight;
      weighted_offset_sum += weight * (rest_positions_[cluster.points[j]] - anchor);
    }
    cluster.rest_center_of_mass = anchor + weighted_offset_sum / cluster.total_weight_kg;
    cluster.rest_offsets.resize(size);
    for (std::size_t j = 0; j < size; ++j) {
      cluster.rest_offsets[j] = rest_positions_[cluster.points[j]] - cluster.rest_center_of_mass;
    }
    precomputeMoments(cluster, config.mode, point_mass_kg_);
  }

  point_slot_offsets_.assign(n + 1, 0);
  for (const auto& cluster : clusters_) {
    for (const auto i : cluster.points) ++point_slot_offsets_[i + 1];
  }
  for (std::size_t i = 0; i < n; ++i) point_slot_offsets_[i + 1] += point_slot_offsets_[i];
  point_slots_.resize(point_slot_offsets_[n]);
  {
    std::vector<std::uint32_t> filled(point_slot_offsets_.begin(), point_slot_offsets_.end() - 1);
    for (std::uint32_t k = 0; k < clusters_.size(); ++k) {
      for (std::uint32_t slot = 0; slot < clusters_[k].points.size(); ++slot) {
        point_slots_[filled[clusters_[k].points[slot]]++] = {k, slot};
      }
    }
  }
  displaced_moments_scratch_.assign(clusters_.size(), DisplacedMoments{});

  deformations_.resize(clusters_.size());
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    deformations_[k].center_of_mass = clusters_[k].rest_center_of_mass;
  }
  cluster_sums_.resize(clusters_.size());
  goal_transforms_.assign(clusters_.size(), Eigen::Matrix<double, 3, 9>::Zero());
  goal_translations_.assign(clusters_.size(), Eigen::Vector3d::Zero());
  setPositions(positions_);
}

void ShapeMatchingBody::step(double dt_s, const Eigen::Vector3d& acceleration_mps2) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) {
    throw std::invalid_argument("time step dt_s = " + std::to_string(dt_s) +
                                " must be finite and > 0");
  }
  if (!acceleration_mps2.allFinite()) {
    throw std::invalid_argument("external acceleration is not finite");
  }
  const bool damped = config_.damping > 0.0;
  withMode([&](auto mode) {
    constexpr DeformationMode kMode = decltype(mode)::value;
    damped ? simulate<kMode, true>(dt_s, acceleration_mps2)
           : simulate<kMode, false>(dt_s, acceleration_mps2);
  });
}

std::size_t ShapeMatchingBody::track(const std::vector<Eigen::Vector3d>& observed_points) {
  if (observed_points.size() != positions_.size()) {
    throw std::invalid_argument("tracked cloud has " + std::to_string(observed_points.size()) +
                                " points, the object has " + std::to_string(positions_.size()));
  }
  std::size_t unobserved = 0;
  for (std::size_t i = 0; i < positions_.size(); ++i) {
    if (observed_points[i].allFinite()) {
      positions_[i] = observed_points[i];
    } else {
      ++unobserved;
    }
  }
  const auto* fill_in = unobserved > 0 ? &observed_points : nullptr;
  withMode([&](auto mode) { registerPositions<decltype(mode)::value>(fill_in); });
  return unobserved;
}

void ShapeMatchingBody::setPositions(const std::vector<Eigen::Vector3d>& positions) {
  requireOnePerPoint(positions, positions_.size(), "position", "positions");
  track(positions);
}


template <typename Action>
void ShapeMatchingBody::withMode(Action&& action) {
  switch (config_.mode) {
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

Eigen::Vector3d ShapeMatchingBody::meanVelocity() const {
  // Each cluster holds a share of its points' masses; the shares add up to the object.
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
  for (const auto& sums : cluster_sums_) momentum += sums.momentum;
  return momentum / config_.mass_kg;
}

void ShapeMatchingBody::moveRigidly(const Eigen::Vector3d& offset_m,
                                    const Eigen::Vector3d& velocity_change_mps) {
  if (!offset_m.allFinite()) throw std::invalid_argument("translation is not finite");
  if (!velocity_change_mps.allFinite()) {
    throw std::invalid_argument("velocity change is not finite");
  }
  // Local pointers and copies: written through one vector's data, the other's pointer and
  // the arguments would otherwise be read again for every point.
  Eigen::Vector3d* positions = positions_.data();
  Eigen::Vector3d* velocities = velocities_.data();
  const Eigen::Vector3d offset = offset_m;
  const Eigen::Vector3d change = velocity_change_mps;
  for (std::size_t i = 0, count = positions_.size(); i < count; ++i) {
    positions[i] += offset;
    velocities[i] += change;
  }
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const Cluster& cluster = clusters_[k];
    ClusterSums& sums = cluster_sums_[k];
    const double mass = cluster.total_weight_kg;
    // Moved first, then pushed: the move's angular momentum takes the momentum before the
    // push, and the push's the offset after the move.
    sums.second_moment += sums.offset * offset_m.transpose() + offset_m * sums.offset.transpose() +
                          mass * offset_m * offset_m.transpose();
    sums.angular_momentum += offset_m.cross(sums.momentum);
    sums.offset_features += (mass * offset_m) * cluster.mean_features.transpose();
    sums.offset += mass * offset_m;
    deformations_[k].center_of_mass += offset_m;
    deformations_[k].translation += offset_m;
    sums.momentum += mass * velocity_change_mps;
    sums.angular_momentum += sums.offset.cross(velocity_change_mps);
  }
}

void ShapeMatchingBody::setVelocities(const std::vector<Eigen::Vector3d>& velocities) {
  requireOnePerPoint(velocities, velocities_.size(), "velocity", "velocities");
  velocities_ = velocities;
  withMode([&](auto mode) { sumCurrentState<decltype(mode)::value>(); });
}

void ShapeMatchingBody::displacePoints(const std::vector<PointDisplacement>& displacements) {
  for (const auto& d : displacements) {
    if (d.point >= positions_.size()) {
      throw std::invalid_argument("displaced point " + std::to_string(d.point) +
                                  " is out of range (" + std::to_string(positions_.size()) +
                                  " points)");
    }
    if (!d.displacement_m.allFinite() || !d.velocity_change_mps.allFinite()) {
      throw std::invalid_argument("displacement or velocity change of point " +
                                  std::to_string(d.point) + " is not finite");
    }
  }
  withMode([&](auto mode) { applyDisplacements<decltype(mode)::value>(displacements); });
}

template <DeformationMode Mode, bool Damped>
void ShapeMatchingBody::simulate(double dt_s, const Eigen::Vector3d& acceleration_mps2) {
  constexpr int K = kFeatureCount<Mode>;

  // Goals come from the registration of the current positions (kept from the last step or
  // registration), before any point moves.
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const ClusterDeformation& deformation = deformations_[k];
    const Eigen::Matrix3d rotation = deformation.rotation.toRotationMatrix();
    const Eigen::Matrix<double, 3, K> fit = deformation.transform.template leftCols<K>();
    Eigen::Matrix<double, 3, K> goal;
    if constexpr (Mode == DeformationMode::kRigid) {
      goal = rotation;
    } else if constexpr (Mode == DeformationMode::kLinear) {
      goal = linearGoalTransform(fit, deformation.rotation, config_.beta, config_.preserve_volume);
    } else {
      goal = config_.beta * fit;
      goal.template leftCols<3>() += (1.0 - config_.beta) * rotation;
    }
    goal_transforms_[k].template leftCols<K>() = goal;
    goal_translations_[k] =
        deformation.center_of_mass - goal * clusters_[k].mean_features.template head<K>();
  }

  // Damping keeps the rigid motion of the whole object, not of each cluster: clusters
  // turning against each other (bending) are non-rigid motion and must decay too.
  Eigen::Vector3d object_center = Eigen::Vector3d::Zero();
  Eigen::Vector3d object_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d object_spin = Eigen::Vector3d::Zero();
  if constexpr (Damped) {
    double mass = 0.0;
    Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
    const Eigen::Vector3d origin = deformations_[0].center_of_mass;
    for (std::size_t k = 0; k < clusters_.size(); ++k) {
      mass += clusters_[k].total_weight_kg;
      object_center += clusters_[k].total_weight_kg * (deformations_[k].center_of_mass - origin);
      momentum += cluster_sums_[k].momentum;
    }
    object_center = origin + object_center / mass;
    object_velocity = momentum / mass;
    Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < clusters_.size(); ++k) {
      const ClusterSums& sums = cluster_sums_[k];
      const double cluster_mass = clusters_[k].total_weight_kg;
      const Eigen::Vector3d shift = sums.offset / cluster_mass;
      const Eigen::Vector3d velocity = sums.momentum / cluster_mass;
      const Eigen::Matrix3d second = sums.second_moment - cluster_mass * shift * shift.transpose();
      // Parallel-axis sums of the clusters about the object's centre.
      const Eigen::Vector3d arm = deformations_[k].center_of_mass - object_center;
      angular_momentum +=
          sums.angular_momentum - cluster_mass * shift.cross(velocity) + arm.cross(sums.momentum);
      inertia += second.trace() * Eigen::Matrix3d::Identity() - second +
                 cluster_mass * (arm.squaredNorm() * Eigen::Matrix3d::Identity() -
                                 arm * arm.transpose());
    }
    object_spin = pseudoInverseSymmetric<3>(inertia).inverse * angular_momentum;
  }

  StepMotion motion;
  motion.dt_s = dt_s;
  motion.pull = config_.stiffness / dt_s;
  motion.damping = config_.damping;
  for (int r = 0; r < 3; ++r) {
    motion.kick[r] = dt_s * acceleration_mps2[r];
    motion.object_center[r] = object_center[r];
    motion.object_velocity[r] = object_velocity[r];
    motion.object_spin[r] = object_spin[r];
  }

  // Move the points; the same pass sums the moved points for the next fit.
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const Cluster& cluster = clusters_[k];
    const GoalKernel<K> kernel(goal_transforms_[k], goal_translations_[k]);
    const Eigen::Vector3d reference = deformations_[k].center_of_mass;
    PartialMoments<K> next;
    std::size_t j = 0;
#if defined(__GNUC__) && defined(__x86_64__)
    if (wide_vectors_) {
      j = moveExclusiveAvx512<K, Damped>(kernel, cluster, motion, positions_.data(),
                                         velocities_.data(), reference, next);
    }
#endif
    // The wide vectors took whole blocks of eight, so slot j + n goes to part n.
    for (; j < cluster.exclusive_count; j += kParts) {
      const int lanes =
          static_cast<int>(std::min<std::size_t>(kParts, cluster.exclusive_count - j));
      SlotLanes<K> slots;
      for (int n = 0; n < lanes; ++n) {
        const std::uint32_t i = cluster.points[j + n];
        double features[K];
        featureArray<K>(cluster.rest_offsets[j + n], features);
        double goal[3];
        kernel.goalFromFeatures(features, goal);
        double* x = positions_[i].data();
        double* u = velocities_[i].data();
        motion.move<Damped>(goal, x, u);
        slots.set(n, features, x, u, reference);
      }
      next.template addLanes<false, true, Damped>(lanes, slots);
    }
    j = cluster.exclusive_count;
#if defined(__GNUC__) && defined(__x86_64__)
    if (wide_vectors_) j = addSharedGoalsAvx512<K>(kernel, cluster, goal_sums_.data());
#endif
    for (; j < cluster.points.size(); ++j) {
      const std::uint32_t i = cluster.points[j];
      double goal[3];
      kernel.goal(cluster.rest_offsets[j], goal);
      goal_sums_[i] += Eigen::Vector3d(goal[0], goal[1], goal[2]);
    }
    ClusterSums& sums = cluster_sums_[k];
    sums = ClusterSums{};
    sums.reference = reference;
    addScaled(next.total(), point_mass_kg_, sums);
  }

  // A shared point takes the mean of its clusters' goals; the rigid velocity it is damped
  // towards is the whole object's, the same in every cluster.
  for (const std::uint32_t i : shared_points_) {
    const double share = 1.0 / membership_counts_[i];
    double goal[3];
    for (int r = 0; r < 3; ++r) goal[r] = share * goal_sums_[i][r];
    motion.move<Damped>(goal, positions_[i].data(), velocities_[i].data());
    goal_sums_[i].setZero();
  }

  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const Cluster& cluster = clusters_[k];
    ClusterDeformation& deformation = deformations_[k];
    if (cluster.exclusive_count < cluster.points.size()) {
      addScaled(accumulate<K, true, Damped>(cluster, cluster.exclusive_count, cluster.points.size(),
                                            cluster.shared_weights_kg.data(), positions_,
                                            velocities_, cluster_sums_[k].reference,
                                            wide_vectors_),
                1.0, cluster_sums_[k]);
    }
    setGoalTransform<K>(cluster, fitCluster<Mode>(cluster, cluster_sums_[k], deformation),
                        deformation);
  }
  measureFitResiduals<Mode>();
}

template <DeformationMode Mode>
void ShapeMatchingBody::sumCurrentState() {
  constexpr int K = kFeatureCount<Mode>;
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    cluster_sums_[k] = clusterSums<K, true, true>(clusters_[k], point_mass_kg_, positions_,
                                                  velocities_, deformations_[k].center_of_mass,
                                                  wide_vectors_);
  }
}

template <DeformationMode Mode>
void ShapeMatchingBody::registerPositions(const std::vector<Eigen::Vector3d>* observed) {
  constexpr int K = kFeatureCount<Mode>;
  const auto seen = [observed](std::uint32_t i) {
    return observed == nullptr || (*observed)[i].allFinite();
  };
  for (auto& v : velocities_) v.setZero();
  sumCurrentState<Mode>();
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const Cluster& cluster = clusters_[k];
    ClusterDeformation& deformation = deformations_[k];
    if (std::all_of(cluster.points.begin(), cluster.points.end(), seen)) {
      setGoalTransform<K>(cluster, fitCluster<Mode>(cluster, cluster_sums_[k], deformation),
                          deformation);
    } else {
      fitObservedSubset<Mode>(cluster, point_mass_kg_, positions_, seen, deformation);
    }
  }

  if (observed != nullptr) {
    double goal[3];
    for (std::size_t k = 0; k < clusters_.size(); ++k) {
      const Cluster& cluster = clusters_[k];
      const GoalKernel<K> kernel(deformations_[k]);
      for (std::size_t j = 0; j < cluster.points.size(); ++j) {
        const std::uint32_t i = cluster.points[j];
        if (seen(i)) continue;
        kernel.goal(cluster.rest_offsets[j], goal);
        goal_sums_[i] += Eigen::Vector3d(goal[0], goal[1], goal[2]);
      }
    }
    for (std::size_t i = 0; i < positions_.size(); ++i) {
      if (seen(static_cast<std::uint32_t>(i))) continue;
      positions_[i] = goal_sums_[i] / membership_counts_[i];
      goal_sums_[i].setZero();
    }
    // The filled-in points moved: the sums must describe the positions now held.
    sumCurrentState<Mode>();
  }
  measureFitResiduals<Mode>();
}

template <DeformationMode Mode>
void ShapeMatchingBody::measureFitResiduals() {
  constexpr int K = kFeatureCount<Mode>;
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    const Cluster& cluster = clusters_[k];
    const GoalKernel<K> kernel(deformations_[k]);
    double deviation_squared = 0.0;
    std::size_t j = 0;
#if defined(__GNUC__) && defined(__x86_64__)
    if (wide_vectors_) {
      std::tie(deviation_squared, j) =
          largestSquaredGoalDistanceAvx512<K>(kernel, cluster, positions_.data());
    }
#endif
    for (; j < cluster.points.size(); ++j) {
      deviation_squared = std::max(
          deviation_squared,
          squaredGoalDistance<K>(kernel, cluster.rest_offsets[j], positions_[cluster.points[j]]));
    }
    deformations_[k].goal_deviation_bound_m = std::sqrt(deviation_squared);
  }
}

template <DeformationMode Mode>
void ShapeMatchingBody::applyDisplacements(const std::vector<PointDisplacement>& displacements) {
  constexpr int K = kFeatureCount<Mode>;
  // With p = x - reference, a point moved by dx with its velocity changed by dv adds to the
  // sums w dx, w dx q~^T, w dv, w ((p + dx) x dv + dx x v) and
  // w ((p + dx)(p + dx)^T - p p^T) = w (h dx^T + dx h^T) with h = p + dx / 2.
  // The points a contact dents come one after the other with the same dx: over such a run
  // (in one cluster) the terms in dx need only the sums of w, w p, w v and w q~, and their
  // products with dx are formed once per run.
  constexpr std::size_t kNoCluster = std::numeric_limits<std::size_t>::max();
  struct Run {
    std::size_t cluster = kNoCluster;
    double dx[3] = {};
    double weight = 0.0;
    double weighted_offset[3] = {};
    double weighted_velocity[3] = {};
    double weighted_features[K] = {};
    double momentum[3] = {};
    double angular_momentum[3] = {};  ///< The terms in dv: w (p + dx) x dv.
  } run;
  const auto close_run = [&] {
    if (run.cluster == kNoCluster) return;
    DisplacedMoments& added = displaced_moments_scratch_[run.cluster];
    const double* dx = run.dx;
    const double* wv = run.weighted_velocity;
    for (int r = 0; r < 3; ++r) {
      added.offset[r] += run.weight * dx[r];
      added.momentum[r] += run.momentum[r];
      for (int c = 0; c < K; ++c) added.offset_features[r][c] += dx[r] * run.weighted_features[c];
      const double half = run.weighted_offset[r] + 0.5 * run.weight * dx[r];
      for (int c = 0; c < 3; ++c) added.half_second_moment[r][c] += half * dx[c];
    }
    added.angular_momentum[0] += run.angular_momentum[0] + dx[1] * wv[2] - dx[2] * wv[1];
    added.angular_momentum[1] += run.angular_momentum[1] + dx[2] * wv[0] - dx[0] * wv[2];
    added.angular_momentum[2] += run.angular_momentum[2] + dx[0] * wv[1] - dx[1] * wv[0];
    added.largest_squared_m2 =
        std::max(added.largest_squared_m2, dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
    added.touched = true;
    run = Run{};
  };
  for (const auto& d : displacements) {
    const double dx[3] = {d.displacement_m.x(), d.displacement_m.y(), d.displacement_m.z()};
    const double dv[3] = {d.velocity_change_mps.x(), d.velocity_change_mps.y(),
                          d.velocity_change_mps.z()};
    Eigen::Vector3d& position = positions_[d.point];
    Eigen::Vector3d& velocity = velocities_[d.point];
    for (std::uint32_t m = point_slot_offsets_[d.point]; m < point_slot_offsets_[d.point + 1]; ++m) {
      const auto [k, slot] = point_slots_[m];
      if (k != run.cluster || dx[0] != run.dx[0] || dx[1] != run.dx[1] || dx[2] != run.dx[2]) {
        close_run();
        run.cluster = k;
        for (int r = 0; r < 3; ++r) run.dx[r] = dx[r];
      }
      const Eigen::Vector3d& reference = cluster_sums_[k].reference;
      const double w = slotWeightKg(clusters_[k], slot, point_mass_kg_);
      double f[K];
      featureArray<K>(clusters_[k].rest_offsets[slot], f);
      double moved[3];
      run.weight += w;
      for (int r = 0; r < 3; ++r) {
        const double p = position[r] - reference[r];
        moved[r] = p + dx[r];
        run.weighted_offset[r] += w * p;
        run.weighted_velocity[r] += w * velocity[r];
        run.momentum[r] += w * dv[r];
      }
      for (int c = 0; c < K; ++c) run.weighted_features[c] += w * f[c];
      run.angular_momentum[0] += w * (moved[1] * dv[2] - moved[2] * dv[1]);
      run.angular_momentum[1] += w * (moved[2] * dv[0] - moved[0] * dv[2]);
      run.angular_momentum[2] += w * (moved[0] * dv[1] - moved[1] * dv[0]);
    }
    position += d.displacement_m;
    velocity += d.velocity_change_mps;
  }
  close_run();
  for (std::size_t k = 0; k < clusters_.size(); ++k) {
    DisplacedMoments& added = displaced_moments_scratch_[k];
    if (!added.touched) continue;
    ClusterSums& sums = cluster_sums_[k];
    for (int r = 0; r < 3; ++r) {
      sums.offset[r] += added.offset[r];
      sums.momentum[r] += added.momentum[r];
      sums.angular_momentum[r] += added.angular_momentum[r];
      for (int c = 0; c < K; ++c) sums.offset_features(r, c) += added.offset_features[r][c];
      for (int c = 0; c < 3; ++c) {
        sums.second_moment(r, c) += added.half_second_moment[r][c] + added.half_second_moment[c][r];
      }
    }
    ClusterDeformation& deformation = deformations_[k];
    const Eigen::Matrix<double, 3, K> old_transform = deformation.transform.template leftCols<K>();
    const Eigen::Vector3d old_translation = deformation.translation;
    setGoalTransform<K>(clusters_[k], fitCluster<Mode>(clusters_[k], sums, deformation),
                        deformation);
    // Every fitted point moves by at most |dT| |q~| + |dt| with the refit, and a displaced
    // point by its displacement too: the residual stays bounded without visiting the cluster.
    const double refit_motion =
        (deformation.transform.template leftCols<K>() - old_transform).norm() *
            clusters_[k].max_feature_norm +
        (deformation.translation - old_translation).norm();
    deformation.goal_deviation_bound_m += std::sqrt(added.largest_squared_m2) + refit_motion;
    added = DisplacedMoments{};
  }
}

}  // namespace deformable_collision
