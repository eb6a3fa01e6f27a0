#include "deformable_collision/core/shape_matching/detail/wide.h"

#include "deformable_collision/core/common/detail/wide_kernels.h"

#if defined(__GNUC__) && defined(__x86_64__)

namespace deformable_collision::detail {
namespace {

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "points are packed triples");

DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

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

  __attribute__((target("avx512f")))
  WideGoals(const GoalKernel<K>& kernel, const Cluster& cluster, std::size_t slot) {
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
  template <bool Weighted, MomentTerms Terms>
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
    if constexpr (Terms != MomentTerms::kAtRest) {
      for (int r = 0; r < 3; ++r) {
        momentum[r] = _mm512_add_pd(momentum[r], Weighted ? _mm512_mul_pd(w, v[r]) : v[r]);
      }
    }
    if constexpr (Terms == MomentTerms::kMomentumAndSpin) {
      for (int r = 0; r < 3; ++r) {
        const __m512d spin = crossComponent(r, p, v);
        angular_momentum[r] =
            _mm512_add_pd(angular_momentum[r], Weighted ? _mm512_mul_pd(w, spin) : spin);
      }
    }
    if constexpr (Terms != MomentTerms::kMomentum) {
      for (int e = 0; e < 6; ++e) {
        second_moment[e] =
            _mm512_add_pd(second_moment[e], _mm512_mul_pd(wp[kUpperRow[e]], p[kUpperColumn[e]]));
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

}  // namespace

template <int K, MomentTerms Terms>
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
    __m512d v[3] = {};
    for (int r = 0; r < 3; ++r) {
      const __m512d x = _mm512_i32gather_pd(offsets, positions->data() + r, 8);
      p[r] = _mm512_sub_pd(x, _mm512_set1_pd(reference[r]));
      if constexpr (Terms != MomentTerms::kAtRest) {
        v[r] = _mm512_i32gather_pd(offsets, velocities->data() + r, 8);
      }
    }
    if (weights != nullptr) {
      moments.template add<true, Terms>(_mm512_loadu_pd(weights + (slot - begin)), p, v, f);
    } else {
      moments.template add<false, Terms>(_mm512_setzero_pd(), p, v, f);
    }
  }
  moments.storeTo(sums);
  return slot;
}

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
        target[r] =
            _mm512_add_pd(_mm512_set1_pd(motion.object_velocity[r]), crossComponent(r, spin, d));
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
    moments.template add<false, kStepTerms<Damped>>(_mm512_setzero_pd(), p, v, wide.features);
  }
  moments.storeTo(sums);
  return slot;
}

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

DEFORMABLE_COLLISION_END_WIDE_KERNELS

// The kernels for every feature count, set of terms and flag the body uses.
#define DEFORMABLE_COLLISION_WIDE_ACCUMULATE(K, TERMS)                                 \
  template std::size_t accumulateAvx512<K, MomentTerms::TERMS>(                        \
      const Cluster&, std::size_t, std::size_t, const double*, const Eigen::Vector3d*, \
      const Eigen::Vector3d*, const Eigen::Vector3d, PartialMoments<K>&);
#define DEFORMABLE_COLLISION_WIDE_MOVE(K, DAMPED)                                                \
  template std::size_t moveExclusiveAvx512<K, DAMPED>(                                           \
      const GoalKernel<K>, const Cluster&, const StepMotion, Eigen::Vector3d*, Eigen::Vector3d*, \
      const Eigen::Vector3d, PartialMoments<K>&);
#define DEFORMABLE_COLLISION_WIDE_SHAPE_MATCHING(K)         \
  DEFORMABLE_COLLISION_WIDE_ACCUMULATE(K, kMomentum)        \
  DEFORMABLE_COLLISION_WIDE_ACCUMULATE(K, kMomentumAndSpin) \
  DEFORMABLE_COLLISION_WIDE_ACCUMULATE(K, kAtRest)          \
  DEFORMABLE_COLLISION_WIDE_MOVE(K, false)                  \
  DEFORMABLE_COLLISION_WIDE_MOVE(K, true)
DEFORMABLE_COLLISION_WIDE_SHAPE_MATCHING(3)
DEFORMABLE_COLLISION_WIDE_SHAPE_MATCHING(9)
#undef DEFORMABLE_COLLISION_WIDE_SHAPE_MATCHING
#undef DEFORMABLE_COLLISION_WIDE_MOVE
#undef DEFORMABLE_COLLISION_WIDE_ACCUMULATE
template std::size_t addSharedGoalsAvx512<3>(const GoalKernel<3>, const Cluster&, Eigen::Vector3d*);
template std::size_t addSharedGoalsAvx512<9>(const GoalKernel<9>, const Cluster&, Eigen::Vector3d*);
template std::pair<double, std::size_t> largestSquaredGoalDistanceAvx512<3>(const GoalKernel<3>,
                                                                            const Cluster&,
                                                                            const Eigen::Vector3d*);
template std::pair<double, std::size_t> largestSquaredGoalDistanceAvx512<9>(const GoalKernel<9>,
                                                                            const Cluster&,
                                                                            const Eigen::Vector3d*);

}  // namespace deformable_collision::detail

#endif
