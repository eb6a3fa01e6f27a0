#pragma once

// Internal to the core: the AVX2 kernels of leaf pairs, four points or spheres per
// instruction (which leaf spheres are in reach, the closest pair of two leaves' points), for
// the pair query (collision_query_kernels.h) and the self-collision query. Internal linkage,
// so that each inlines them as if in its own file.

#include <cstddef>
#include <cstdint>
#include <limits>

#include "deformable_collision/core/common/detail/wide_kernels.h"

#if defined(__GNUC__) && defined(__x86_64__)
namespace deformable_collision {
namespace {

/// The lanes of the up to four values from `offset` on of `count`, as a mask of whole lanes.
__attribute__((target("avx2"))) inline __m256i lanesFromAvx2(std::uint32_t offset,
                                                             std::uint32_t count) {
  const __m256i lane = _mm256_add_epi64(_mm256_set1_epi64x(offset), _mm256_set_epi64x(3, 2, 1, 0));
  return _mm256_cmpgt_epi64(_mm256_set1_epi64x(count), lane);
}

/// Squared distances from the point (x, y, z), in every lane, to four points given by their
/// coordinates, summed as the scalar code sums them, so both give the same bits.
__attribute__((target("avx2"))) inline __m256d squaredDistancesAvx2(__m256d x, __m256d y, __m256d z,
                                                                    __m256d xs, __m256d ys,
                                                                    __m256d zs) {
  const __m256d dx = _mm256_sub_pd(x, xs);
  const __m256d dy = _mm256_sub_pd(y, ys);
  const __m256d dz = _mm256_sub_pd(z, zs);
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                       _mm256_mul_pd(dz, dz));
}

/// The least of the four values.
__attribute__((target("avx2"))) inline double leastOfAvx2(__m256d values) {
  const __m128d halves =
      _mm_min_pd(_mm256_castpd256_pd128(values), _mm256_extractf128_pd(values, 1));
  return _mm_cvtsd_f64(_mm_min_sd(halves, _mm_unpackhi_pd(halves, halves)));
}

/// Up to eight points as two halves of four; lanes past `count` hold an infinite x, so that
/// their distances are infinite, never least.
__attribute__((target("avx2"))) inline void loadEightAvx2(const double* xs, const double* ys,
                                                          const double* zs, std::uint32_t count,
                                                          __m256d (&x)[2], __m256d (&y)[2],
                                                          __m256d (&z)[2]) {
  const __m256d infinity = _mm256_set1_pd(std::numeric_limits<double>::infinity());
#pragma GCC unroll 2
  for (int h = 0; h < 2; ++h) {
    const __m256i lanes = lanesFromAvx2(4 * h, count);
    x[h] = _mm256_blendv_pd(infinity, _mm256_maskload_pd(xs + 4 * h, lanes),
                            _mm256_castsi256_pd(lanes));
    y[h] = _mm256_maskload_pd(ys + 4 * h, lanes);
    z[h] = _mm256_maskload_pd(zs + 4 * h, lanes);
  }
}

/// Squared distances from (x, y, z) to eight points, four per half (squaredDistancesAvx2).
__attribute__((target("avx2"))) inline void squaredDistancesToEightAvx2(
    double x, double y, double z, const __m256d (&xs)[2], const __m256d (&ys)[2],
    const __m256d (&zs)[2], __m256d& low, __m256d& high) {
  const __m256d px = _mm256_set1_pd(x);
  const __m256d py = _mm256_set1_pd(y);
  const __m256d pz = _mm256_set1_pd(z);
  low = squaredDistancesAvx2(px, py, pz, xs[0], ys[0], zs[0]);
  high = squaredDistancesAvx2(px, py, pz, xs[1], ys[1], zs[1]);
}

/// The lanes of the eight distances (low, then high) equal to `value`, one bit each.
__attribute__((target("avx2"))) inline std::uint32_t lanesAtAvx2(__m256d low, __m256d high,
                                                                 double value) {
  const __m256d target = _mm256_set1_pd(value);
  return static_cast<std::uint32_t>(_mm256_movemask_pd(_mm256_cmp_pd(low, target, _CMP_EQ_OQ)) |
                                    _mm256_movemask_pd(_mm256_cmp_pd(high, target, _CMP_EQ_OQ))
                                        << 4);
}

/// The first pair, in row-major order, at the least of the squared distances that
/// `rows(s, low, high)` gives from a's point s to up to eight points (four per half), if that
/// least is below `below_squared`. Every pair, the least kept per lane without a branch; only
/// a least below `below_squared` is then looked for, in a second pass that stops at its
/// first pair: `rows` computes the same sums again (the core is built with
/// -ffp-contract=off), so some point of a meets it before the last.
template <typename Rows>
__attribute__((target("avx2"))) inline bool firstClosestPairAvx2(
    const Rows& rows, std::uint32_t count_a, double below_squared, double& nearest_squared,
    std::uint32_t& offset_a, std::uint32_t& offset_b) {
  __m256d least_lanes = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  for (std::uint32_t s = 0; s < count_a; ++s) {
    __m256d low, high;
    rows(s, low, high);
    least_lanes = _mm256_min_pd(least_lanes, _mm256_min_pd(low, high));
  }
  const double least = leastOfAvx2(least_lanes);
  if (!(least < below_squared)) return false;
  for (std::uint32_t s = 0;; ++s) {
    __m256d low, high;
    rows(s, low, high);
    const std::uint32_t at_least = lanesAtAvx2(low, high, least);
    if (at_least != 0) {
      nearest_squared = least;
      offset_a = s;
      offset_b = static_cast<std::uint32_t>(__builtin_ctz(at_least));
      return true;
    }
  }
}

/// Squared distances from a's points, by row, to up to eight points of b.
struct RowsToEightAvx2 {
  const double* ax;
  const double* ay;
  const double* az;
  __m256d x[2], y[2], z[2];
  __attribute__((target("avx2"))) void operator()(std::uint32_t s, __m256d& low,
                                                  __m256d& high) const {
    squaredDistancesToEightAvx2(ax[s], ay[s], az[s], x, y, z, low, high);
  }
};

/// The closest pair of a's points and up to eight points of b if it is below
/// `below_squared`, the first in row-major order, four of b's points per instruction
/// (firstClosestPairAvx2). Testing only the points of a near b's centre, with a branch per
/// point on whether it came closer, tests fewer pairs but takes longer: most leaf pairs in
/// reach have a point or two near, and whether one is, and whether it came closer, are coin
/// tosses (S1 with thousands of contacts, S2's finest level). `point_tests` counts every
/// pair.
__attribute__((target("avx2"))) inline bool closestPairOfEightAvx2(
    const double* ax, const double* ay, const double* az, std::uint32_t count_a, const double* bx,
    const double* by, const double* bz, std::uint32_t count_b, double below_squared,
    double& nearest_squared, std::uint32_t& offset_a, std::uint32_t& offset_b,
    std::size_t& point_tests) {
  RowsToEightAvx2 rows{ax, ay, az, {}, {}, {}};
  loadEightAvx2(bx, by, bz, count_b, rows.x, rows.y, rows.z);
  point_tests += count_a * count_b;
  return firstClosestPairAvx2(rows, count_a, below_squared, nearest_squared, offset_a, offset_b);
}

/// RowsToEightAvx2 with the distances of pairs whose squared distance at rest (by the rest
/// points' rows) is not above `apart_squared` replaced by infinity: pairs too near at rest
/// never count.
struct RowsApartAtRestAvx2 {
  RowsToEightAvx2 now;
  RowsToEightAvx2 rest;
  __m256d apart_squared;
  __attribute__((target("avx2"))) void operator()(std::uint32_t s, __m256d& low,
                                                  __m256d& high) const {
    const __m256d infinity = _mm256_set1_pd(std::numeric_limits<double>::infinity());
    now(s, low, high);
    __m256d rest_low, rest_high;
    rest(s, rest_low, rest_high);
    low = _mm256_blendv_pd(infinity, low, _mm256_cmp_pd(rest_low, apart_squared, _CMP_GT_OQ));
    high = _mm256_blendv_pd(infinity, high, _mm256_cmp_pd(rest_high, apart_squared, _CMP_GT_OQ));
  }
};

/// closestPairOfEightAvx2 over the pairs whose points lie more than sqrt(apart_squared)
/// apart at rest, the rest points given by coordinate arrays in the same order: the same
/// pair, to the bit, as a point-by-point test that skips the others.
__attribute__((target("avx2"))) inline bool closestPairApartAtRestOfEightAvx2(
    const double* const (&a)[3], const double* const (&rest_a)[3], std::uint32_t count_a,
    const double* const (&b)[3], const double* const (&rest_b)[3], std::uint32_t count_b,
    double apart_squared, double below_squared, double& nearest_squared, std::uint32_t& offset_a,
    std::uint32_t& offset_b, std::size_t& point_tests) {
  RowsApartAtRestAvx2 rows{{a[0], a[1], a[2], {}, {}, {}},
                           {rest_a[0], rest_a[1], rest_a[2], {}, {}, {}},
                           _mm256_set1_pd(apart_squared)};
  loadEightAvx2(b[0], b[1], b[2], count_b, rows.now.x, rows.now.y, rows.now.z);
  loadEightAvx2(rest_b[0], rest_b[1], rest_b[2], count_b, rows.rest.x, rows.rest.y, rows.rest.z);
  point_tests += count_a * count_b;
  return firstClosestPairAvx2(rows, count_a, below_squared, nearest_squared, offset_a, offset_b);
}

/// Bit j set if sphere j of the `count` (<= 8) given by coordinate arrays comes within
/// `reach_m` plus its radius of (x, y, z), four spheres per instruction.
__attribute__((target("avx2"))) inline std::uint32_t reachMaskAvx2(
    double x, double y, double z, double reach_m, const double* xs, const double* ys,
    const double* zs, const double* radii, std::uint32_t count) {
  const __m256d px = _mm256_set1_pd(x);
  const __m256d py = _mm256_set1_pd(y);
  const __m256d pz = _mm256_set1_pd(z);
  std::uint32_t mask = 0;
#pragma GCC unroll 2
  for (std::uint32_t j = 0; j < count; j += 4) {
    const __m256i lanes = lanesFromAvx2(j, count);
    const __m256d squared =
        squaredDistancesAvx2(px, py, pz, _mm256_maskload_pd(xs + j, lanes),
                             _mm256_maskload_pd(ys + j, lanes), _mm256_maskload_pd(zs + j, lanes));
    const __m256d reach =
        _mm256_add_pd(_mm256_maskload_pd(radii + j, lanes), _mm256_set1_pd(reach_m));
    const __m256d within =
        _mm256_and_pd(_mm256_cmp_pd(squared, _mm256_mul_pd(reach, reach), _CMP_LT_OQ),
                      _mm256_castsi256_pd(lanes));
    mask |= static_cast<std::uint32_t>(_mm256_movemask_pd(within)) << j;
  }
  return mask;
}

}  // namespace
}  // namespace deformable_collision
#endif
