// The AVX2 twins of shape matching's per-point passes: a block of eight slots as two halves
// of four, parts 0 to 3 and 4 to 7, each value computed with the operations of the portable
// code in its order. No FMA: a fused product would round once where the portable code
// rounds twice.
#include "deformable_collision/core/shape_matching/detail/wide.h"

#include <algorithm>

#include "deformable_collision/core/common/detail/wide_kernels.h"

#if defined(__GNUC__) && defined(__x86_64__)

namespace deformable_collision::detail {
namespace {

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "points are packed triples");

DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

constexpr int kHalves = 2;
constexpr int kHalfLanes = 4;

/// a x b, component `row`, as the portable code computes it: a[i] b[j] - a[j] b[i].
__attribute__((target("avx2"))) inline __m256d crossComponent(int row, const __m256d (&a)[3],
                                                              const __m256d (&b)[3]) {
  const int i = (row + 1) % 3;
  const int j = (row + 2) % 3;
  return _mm256_sub_pd(_mm256_mul_pd(a[i], b[j]), _mm256_mul_pd(a[j], b[i]));
}

/// Four packed triples from `triples` on, split into their x, y and z: copies, no arithmetic.
__attribute__((target("avx2"))) inline void splitTriples(const double* triples, __m256d (&xyz)[3]) {
  // In 128-bit halves: a = (x0 y0 | z0 x1), b = (y1 z1 | x2 y2), c = (z2 x3 | y3 z3).
  const __m256d a = _mm256_loadu_pd(triples);
  const __m256d b = _mm256_loadu_pd(triples + 4);
  const __m256d c = _mm256_loadu_pd(triples + 8);
  const __m256d x0y0x2y2 = _mm256_blend_pd(a, b, 0b1100);
  const __m256d z0x1z2x3 = _mm256_permute2f128_pd(a, c, 0x21);
  const __m256d y1z1y3z3 = _mm256_blend_pd(b, c, 0b1100);
  xyz[0] = _mm256_blend_pd(x0y0x2y2, z0x1z2x3, 0b1010);
  xyz[1] = _mm256_shuffle_pd(x0y0x2y2, y1z1y3z3, 0b0101);
  xyz[2] = _mm256_shuffle_pd(z0x1z2x3, y1z1y3z3, 0b1010);
}

/// The features of the cluster's four slots from `slot` on, each as featureArray gives it.
template <int K>
__attribute__((target("avx2"))) inline void wideFeatures(const Cluster& cluster, std::size_t slot,
                                                         __m256d (&f)[K]) {
  __m256d xyz[3];
  splitTriples(cluster.rest_offsets[slot].data(), xyz);
  for (int r = 0; r < 3; ++r) f[r] = xyz[r];
  if constexpr (K == 9) {
    f[3] = _mm256_mul_pd(f[0], f[0]);
    f[4] = _mm256_mul_pd(f[1], f[1]);
    f[5] = _mm256_mul_pd(f[2], f[2]);
    f[6] = _mm256_mul_pd(f[0], f[1]);
    f[7] = _mm256_mul_pd(f[1], f[2]);
    f[8] = _mm256_mul_pd(f[2], f[0]);
  }
}

/// Four consecutive slots of a cluster, from `slot` on: their features and their goals, each
/// computed as GoalKernel::goal does.
template <int K>
struct WideGoals {
  __m256d features[K];
  __m256d goal[3];

  __attribute__((target("avx2")))
  WideGoals(const GoalKernel<K>& kernel, const Cluster& cluster, std::size_t slot) {
    wideFeatures<K>(cluster, slot, features);
    for (int r = 0; r < 3; ++r) {
      __m256d g = _mm256_set1_pd(kernel.translation[r]);
      for (int c = 0; c < K; ++c) {
        g = _mm256_add_pd(g, _mm256_mul_pd(_mm256_set1_pd(kernel.transform[r][c]), features[c]));
      }
      goal[r] = g;
    }
  }
};

/// The coordinates of the points of the cluster's four slots from `slot` on: copies, no
/// arithmetic. Loaded point by point and transposed; AVX2's gathers cost more here.
__attribute__((target("avx2"))) inline void loadPoints(const Cluster& cluster, std::size_t slot,
                                                       const double* coordinates,
                                                       __m256d (&xyz)[3]) {
  const double* p[kHalfLanes];
  for (int n = 0; n < kHalfLanes; ++n)
    p[n] = coordinates + 3 * std::size_t{cluster.points[slot + n]};
  const __m256d xy02 =
      _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p[0])), _mm_loadu_pd(p[2]), 1);
  const __m256d xy13 =
      _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p[1])), _mm_loadu_pd(p[3]), 1);
  xyz[0] = _mm256_unpacklo_pd(xy02, xy13);
  xyz[1] = _mm256_unpackhi_pd(xy02, xy13);
  xyz[2] = _mm256_setr_pd(p[0][2], p[1][2], p[2][2], p[3][2]);
}

/// Writes four points' coordinates back to the cluster's points of slots [slot, slot + 4).
__attribute__((target("avx2"))) inline void scatterPoints(const Cluster& cluster, std::size_t slot,
                                                          const __m256d (&xyz)[3],
                                                          double* coordinates) {
  alignas(32) double lanes[3][kHalfLanes];
  for (int r = 0; r < 3; ++r) _mm256_store_pd(lanes[r], xyz[r]);
  for (int n = 0; n < kHalfLanes; ++n) {
    double* point = coordinates + 3 * std::size_t{cluster.points[slot + n]};
    for (int r = 0; r < 3; ++r) point[r] = lanes[r][n];
  }
}

/// PartialMoments with its eight parts in two halves of four lanes.
template <int K>
struct WideMoments {
  __m256d offset[3][kHalves];
  __m256d offset_features[3][K][kHalves];
  __m256d momentum[3][kHalves];
  __m256d angular_momentum[3][kHalves];
  __m256d second_moment[6][kHalves];

  __attribute__((target("avx2"))) WideMoments() {
    for (int h = 0; h < kHalves; ++h) {
      for (int r = 0; r < 3; ++r) {
        offset[r][h] = momentum[r][h] = angular_momentum[r][h] = _mm256_setzero_pd();
        for (int c = 0; c < K; ++c) offset_features[r][c][h] = _mm256_setzero_pd();
      }
      for (int e = 0; e < 6; ++e) second_moment[e][h] = _mm256_setzero_pd();
    }
  }

  /// PartialMoments::addLanes for four slots, into parts 4 h to 4 h + 3.
  template <bool Weighted, MomentTerms Terms>
  __attribute__((target("avx2"))) void add(int h, __m256d w, const __m256d (&p)[3],
                                           const __m256d (&v)[3], const __m256d (&f)[K]) {
    __m256d wp[3];
    for (int r = 0; r < 3; ++r) {
      wp[r] = Weighted ? _mm256_mul_pd(w, p[r]) : p[r];
      offset[r][h] = _mm256_add_pd(offset[r][h], wp[r]);
      for (int c = 0; c < K; ++c) {
        offset_features[r][c][h] =
            _mm256_add_pd(offset_features[r][c][h], _mm256_mul_pd(wp[r], f[c]));
      }
    }
    if constexpr (Terms != MomentTerms::kAtRest) {
      for (int r = 0; r < 3; ++r) {
        momentum[r][h] = _mm256_add_pd(momentum[r][h], Weighted ? _mm256_mul_pd(w, v[r]) : v[r]);
      }
    }
    if constexpr (Terms == MomentTerms::kMomentumAndSpin) {
      for (int r = 0; r < 3; ++r) {
        const __m256d spin = crossComponent(r, p, v);
        angular_momentum[r][h] =
            _mm256_add_pd(angular_momentum[r][h], Weighted ? _mm256_mul_pd(w, spin) : spin);
      }
    }
    if constexpr (Terms != MomentTerms::kMomentum) {
      for (int e = 0; e < 6; ++e) {
        second_moment[e][h] =
            _mm256_add_pd(second_moment[e][h], _mm256_mul_pd(wp[kUpperRow[e]], p[kUpperColumn[e]]));
      }
    }
  }

  /// Writes the parts to `sums`, which hold nothing yet.
  __attribute__((target("avx2"))) void storeTo(PartialMoments<K>& sums) const {
    for (int h = 0; h < kHalves; ++h) {
      const int part = kHalfLanes * h;
      for (int r = 0; r < 3; ++r) {
        _mm256_storeu_pd(sums.offset[r] + part, offset[r][h]);
        _mm256_storeu_pd(sums.momentum[r] + part, momentum[r][h]);
        _mm256_storeu_pd(sums.angular_momentum[r] + part, angular_momentum[r][h]);
        for (int c = 0; c < K; ++c) {
          _mm256_storeu_pd(sums.offset_features[r][c] + part, offset_features[r][c][h]);
        }
      }
      for (int e = 0; e < 6; ++e)
        _mm256_storeu_pd(sums.second_moment[e] + part, second_moment[e][h]);
    }
  }
};

}  // namespace

template <int K, MomentTerms Terms>
__attribute__((target("avx2"))) std::size_t accumulateAvx2(
    const Cluster& cluster, std::size_t begin, std::size_t end, const double* weights,
    const Eigen::Vector3d* positions, const Eigen::Vector3d* velocities,
    const Eigen::Vector3d reference, PartialMoments<K>& sums) {
  WideMoments<K> moments;
  std::size_t block = begin;
  for (; block + kParts <= end; block += kParts) {
    for (int h = 0; h < kHalves; ++h) {
      const std::size_t slot = block + kHalfLanes * h;
      __m256d f[K];
      wideFeatures<K>(cluster, slot, f);
      __m256d p[3];
      __m256d v[3] = {};
      loadPoints(cluster, slot, positions->data(), p);
      if constexpr (Terms != MomentTerms::kAtRest) loadPoints(cluster, slot, velocities->data(), v);
      for (int r = 0; r < 3; ++r) p[r] = _mm256_sub_pd(p[r], _mm256_set1_pd(reference[r]));
      if (weights != nullptr) {
        moments.template add<true, Terms>(h, _mm256_loadu_pd(weights + (slot - begin)), p, v, f);
      } else {
        moments.template add<false, Terms>(h, _mm256_setzero_pd(), p, v, f);
      }
    }
  }
  moments.storeTo(sums);
  return block;
}

template <int K, bool Damped>
__attribute__((target("avx2"))) std::size_t moveExclusiveAvx2(
    const GoalKernel<K> kernel, const Cluster& cluster, const StepMotion motion,
    Eigen::Vector3d* positions, Eigen::Vector3d* velocities, const Eigen::Vector3d reference,
    PartialMoments<K>& sums) {
  double* xs = positions->data();
  double* vs = velocities->data();
  WideMoments<K> moments;
  std::size_t block = 0;
  for (; block + kParts <= cluster.exclusive_count; block += kParts) {
    for (int h = 0; h < kHalves; ++h) {
      const std::size_t slot = block + kHalfLanes * h;
      const WideGoals<K> wide(kernel, cluster, slot);
      __m256d x[3];
      __m256d v[3];
      loadPoints(cluster, slot, xs, x);
      loadPoints(cluster, slot, vs, v);
      if (motion.deferred.moves_positions) {
        for (int r = 0; r < 3; ++r) {
          x[r] = _mm256_add_pd(x[r], _mm256_set1_pd(motion.deferred.offset[r]));
        }
      }
      if (motion.deferred.moves_velocities) {
        for (int r = 0; r < 3; ++r) {
          v[r] = _mm256_add_pd(v[r], _mm256_set1_pd(motion.deferred.velocity_change[r]));
        }
      }
      __m256d target[3];
      if constexpr (Damped) {
        __m256d spin[3];
        __m256d d[3];
        for (int r = 0; r < 3; ++r) {
          spin[r] = _mm256_set1_pd(motion.object_spin[r]);
          d[r] = _mm256_sub_pd(x[r], _mm256_set1_pd(motion.object_center[r]));
        }
        for (int r = 0; r < 3; ++r) {
          target[r] =
              _mm256_add_pd(_mm256_set1_pd(motion.object_velocity[r]), crossComponent(r, spin, d));
        }
      }
      __m256d p[3];
      for (int r = 0; r < 3; ++r) {
        if constexpr (Damped) {
          v[r] = _mm256_add_pd(
              v[r], _mm256_mul_pd(_mm256_set1_pd(motion.damping), _mm256_sub_pd(target[r], v[r])));
        }
        const __m256d pull =
            _mm256_mul_pd(_mm256_set1_pd(motion.pull), _mm256_sub_pd(wide.goal[r], x[r]));
        v[r] = _mm256_add_pd(v[r], _mm256_add_pd(pull, _mm256_set1_pd(motion.kick[r])));
        x[r] = _mm256_add_pd(x[r], _mm256_mul_pd(_mm256_set1_pd(motion.dt_s), v[r]));
        p[r] = _mm256_sub_pd(x[r], _mm256_set1_pd(reference[r]));
      }
      // A cluster holds a point once: the four slots write four different points.
      scatterPoints(cluster, slot, x, xs);
      scatterPoints(cluster, slot, v, vs);
      moments.template add<false, kStepTerms<Damped>>(h, _mm256_setzero_pd(), p, v, wide.features);
    }
  }
  moments.storeTo(sums);
  return block;
}

template <int K>
__attribute__((target("avx2"))) std::size_t addSharedGoalsAvx2(const GoalKernel<K> kernel,
                                                               const Cluster& cluster,
                                                               Eigen::Vector3d* goal_sums) {
  double* sums = goal_sums->data();
  std::size_t slot = cluster.exclusive_count;
  for (; slot + kHalfLanes <= cluster.points.size(); slot += kHalfLanes) {
    const WideGoals<K> wide(kernel, cluster, slot);
    __m256d sum[3];
    loadPoints(cluster, slot, sums, sum);
    for (int r = 0; r < 3; ++r) sum[r] = _mm256_add_pd(sum[r], wide.goal[r]);
    scatterPoints(cluster, slot, sum, sums);
  }
  return slot;
}

template <int K>
__attribute__((target("avx2"))) std::pair<double, std::size_t> largestSquaredGoalDistanceAvx2(
    const GoalKernel<K> kernel, const Cluster& cluster, const Eigen::Vector3d* positions) {
  __m256d largest = _mm256_setzero_pd();
  std::size_t slot = 0;
  for (; slot + kHalfLanes <= cluster.points.size(); slot += kHalfLanes) {
    const WideGoals<K> wide(kernel, cluster, slot);
    __m256d x[3];
    loadPoints(cluster, slot, positions->data(), x);
    __m256d squared = _mm256_setzero_pd();
    for (int r = 0; r < 3; ++r) {
      const __m256d e = _mm256_sub_pd(wide.goal[r], x[r]);
      squared = r == 0 ? _mm256_mul_pd(e, e) : _mm256_add_pd(squared, _mm256_mul_pd(e, e));
    }
    // As std::max(largest, squared) in the portable code: a NaN distance is passed over.
    largest = _mm256_max_pd(squared, largest);
  }
  alignas(32) double lanes[kHalfLanes];
  _mm256_store_pd(lanes, largest);
  return {std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3])), slot};
}

DEFORMABLE_COLLISION_END_WIDE_KERNELS

// The kernels for every feature count, set of terms and flag the body uses.
#define DEFORMABLE_COLLISION_AVX2_ACCUMULATE(K, TERMS)                                 \
  template std::size_t accumulateAvx2<K, MomentTerms::TERMS>(                          \
      const Cluster&, std::size_t, std::size_t, const double*, const Eigen::Vector3d*, \
      const Eigen::Vector3d*, const Eigen::Vector3d, PartialMoments<K>&);
#define DEFORMABLE_COLLISION_AVX2_MOVE(K, DAMPED)                                                \
  template std::size_t moveExclusiveAvx2<K, DAMPED>(                                             \
      const GoalKernel<K>, const Cluster&, const StepMotion, Eigen::Vector3d*, Eigen::Vector3d*, \
      const Eigen::Vector3d, PartialMoments<K>&);
#define DEFORMABLE_COLLISION_AVX2_SHAPE_MATCHING(K)         \
  DEFORMABLE_COLLISION_AVX2_ACCUMULATE(K, kMomentum)        \
  DEFORMABLE_COLLISION_AVX2_ACCUMULATE(K, kMomentumAndSpin) \
  DEFORMABLE_COLLISION_AVX2_ACCUMULATE(K, kAtRest)          \
  DEFORMABLE_COLLISION_AVX2_MOVE(K, false)                  \
  DEFORMABLE_COLLISION_AVX2_MOVE(K, true)
DEFORMABLE_COLLISION_AVX2_SHAPE_MATCHING(3)
DEFORMABLE_COLLISION_AVX2_SHAPE_MATCHING(9)
#undef DEFORMABLE_COLLISION_AVX2_SHAPE_MATCHING
#undef DEFORMABLE_COLLISION_AVX2_MOVE
#undef DEFORMABLE_COLLISION_AVX2_ACCUMULATE
template std::size_t addSharedGoalsAvx2<3>(const GoalKernel<3>, const Cluster&, Eigen::Vector3d*);
template std::size_t addSharedGoalsAvx2<9>(const GoalKernel<9>, const Cluster&, Eigen::Vector3d*);
template std::pair<double, std::size_t> largestSquaredGoalDistanceAvx2<3>(const GoalKernel<3>,
                                                                          const Cluster&,
                                                                          const Eigen::Vector3d*);
template std::pair<double, std::size_t> largestSquaredGoalDistanceAvx2<9>(const GoalKernel<9>,
                                                                          const Cluster&,
                                                                          const Eigen::Vector3d*);

}  // namespace deformable_collision::detail

#endif
