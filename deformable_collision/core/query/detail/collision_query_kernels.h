#pragma once

// Internal to the core, included by collision_query.cpp only: the point kernels of the
// query, portable, AVX2 and AVX-512, on points given by coordinate arrays. They keep internal
// linkage, so the compiler inlines them into the query as if they stood in its file.

#include <cstdint>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "deformable_collision/core/common/detail/wide_kernels.h"
#include "deformable_collision/core/common/wide_vectors.h"
#include "deformable_collision/core/query/detail/leaf_pair_kernels.h"

namespace deformable_collision {
namespace {

/// Squared distance from (x, y, z) to the nearest of `count` points given by their
/// coordinate arrays.
double nearestSquaredDistance(const double* xs, const double* ys, const double* zs,
                              std::uint32_t count, double x, double y, double z) {
  double nearest = std::numeric_limits<double>::infinity();
  std::uint32_t t = 0;
#if defined(__SSE2__)
  // Two points per instruction, the innermost loop without wide vectors. The sums are
  // formed in the scalar loop's order, so both give the same bits.
  const __m128d px = _mm_set1_pd(x);
  const __m128d py = _mm_set1_pd(y);
  const __m128d pz = _mm_set1_pd(z);
  __m128d pair_nearest = _mm_set1_pd(nearest);
  for (; t + 2 <= count; t += 2) {
    const __m128d dx = _mm_sub_pd(px, _mm_loadu_pd(xs + t));
    const __m128d dy = _mm_sub_pd(py, _mm_loadu_pd(ys + t));
    const __m128d dz = _mm_sub_pd(pz, _mm_loadu_pd(zs + t));
    const __m128d squared =
        _mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)), _mm_mul_pd(dz, dz));
    pair_nearest = _mm_min_pd(pair_nearest, squared);
  }
  nearest = std::min(_mm_cvtsd_f64(pair_nearest),
                     _mm_cvtsd_f64(_mm_unpackhi_pd(pair_nearest, pair_nearest)));
#endif
  for (; t < count; ++t) {
    const double dx = x - xs[t], dy = y - ys[t], dz = z - zs[t];
    nearest = std::min(nearest, dx * dx + dy * dy + dz * dz);
  }
  return nearest;
}

#if defined(__GNUC__) && defined(__x86_64__)
DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

/// The least of the eight values, in every lane.
__attribute__((target("avx512f"))) inline __m512d leastInEveryLaneAvx512(__m512d values) {
  values = _mm512_min_pd(values, _mm512_shuffle_f64x2(values, values, 0x4E));
  values = _mm512_min_pd(values, _mm512_shuffle_f64x2(values, values, 0xB1));
  return _mm512_min_pd(values, _mm512_shuffle_pd(values, values, 0x55));
}

/// Squared distance of the nearest pair of two point sets if it is below `below_squared`,
/// all pairs at once, eight of b's points per instruction.
__attribute__((target("avx512f"))) bool nearestPairSquaredDistanceAvx512(
    const double* ax, const double* ay, const double* az, std::uint32_t count_a, const double* bx,
    const double* by, const double* bz, std::uint32_t count_b, double below_squared,
    double& nearest_squared) {
  __m512d nearest = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  for (std::uint32_t t = 0; t < count_b; t += 8) {
    const __mmask8 lanes = lanesFrom(t, count_b);
    const __m512d x = _mm512_maskz_loadu_pd(lanes, bx + t);
    const __m512d y = _mm512_maskz_loadu_pd(lanes, by + t);
    const __m512d z = _mm512_maskz_loadu_pd(lanes, bz + t);
    for (std::uint32_t s = 0; s < count_a; ++s) {
      nearest = _mm512_mask_min_pd(nearest, lanes, nearest,
                                   squaredDistancesAvx512(ax[s], ay[s], az[s], x, y, z));
    }
  }
  // Most leaf pairs in reach have no pair close enough: they end on one comparison.
  if (_mm512_cmp_pd_mask(nearest, _mm512_set1_pd(below_squared), _CMP_LT_OQ) == 0) return false;
  nearest_squared = _mm512_cvtsd_f64(leastInEveryLaneAvx512(nearest));
  return true;
}

/// nearestPairSquaredDistanceAvx512 and firstPairAtAvx512 for up to eight points of b, from
/// one pass over a's points in rows of up to eight: the rows' distances are independent and
/// their least is taken as a tree, so no row waits on the one before; only a row block
/// with a pair close enough is searched for its first pair at the least distance.
__attribute__((target("avx512f"))) inline bool closestPairOfEightAvx512(
    const double* ax, const double* ay, const double* az, std::uint32_t count_a, const double* bx,
    const double* by, const double* bz, std::uint32_t count_b, double below_squared,
    double& nearest_squared, std::uint32_t& offset_a, std::uint32_t& offset_b) {
  const __mmask8 lanes = lanesFrom(0, count_b);
  const __m512d x = _mm512_maskz_loadu_pd(lanes, bx);
  const __m512d y = _mm512_maskz_loadu_pd(lanes, by);
  const __m512d z = _mm512_maskz_loadu_pd(lanes, bz);
  const __m512d infinity = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  bool found = false;
  for (std::uint32_t first_row = 0; first_row < count_a; first_row += 8) {
    const std::uint32_t rows = std::min<std::uint32_t>(8, count_a - first_row);
    __m512d squared[8];
    for (std::uint32_t r = 0; r < 8; ++r) {
      // Rows past a's points repeat its last one, which cannot come first or closer; a
      // select, not a branch per row count (leaves of 7 and 8 points alternate).
      const std::uint32_t s = first_row + std::min(r, rows - 1);
      squared[r] =
          _mm512_mask_mov_pd(infinity, lanes, squaredDistancesAvx512(ax[s], ay[s], az[s], x, y, z));
    }
    const __m512d least_of_rows = _mm512_min_pd(
        _mm512_min_pd(_mm512_min_pd(squared[0], squared[1]), _mm512_min_pd(squared[2], squared[3])),
        _mm512_min_pd(_mm512_min_pd(squared[4], squared[5]),
                      _mm512_min_pd(squared[6], squared[7])));
    // Most leaf pairs in reach have no pair close enough: they end on one comparison, before
    // the rows' least is reduced across lanes.
    if (_mm512_cmp_pd_mask(least_of_rows, _mm512_set1_pd(below_squared), _CMP_LT_OQ) == 0) {
      continue;
    }
    const __m512d target = leastInEveryLaneAvx512(least_of_rows);
    const double least = _mm512_cvtsd_f64(target);
    // Row-major order of the pairs at the least distance: the first set bit is the first pair
    // (a repeated row's bits come after the same bits of the row it repeats).
    std::uint64_t at_least = 0;
    for (std::uint32_t r = 0; r < 8; ++r) {
      at_least |=
          static_cast<std::uint64_t>(_mm512_mask_cmp_pd_mask(lanes, squared[r], target, _CMP_EQ_OQ))
          << (8 * r);
    }
    const auto first = static_cast<std::uint32_t>(__builtin_ctzll(at_least));
    below_squared = least;
    nearest_squared = least;
    offset_a = first_row + (first >> 3);
    offset_b = first & 7;
    found = true;
  }
  return found;
}

/// The first pair, a's points in order and then b's, at `squared_distance` (one that
/// nearestPairSquaredDistanceAvx512 returned), as offsets into a's and b's arrays.
__attribute__((target("avx512f"))) void firstPairAtAvx512(
    const double* ax, const double* ay, const double* az, std::uint32_t count_a, const double* bx,
    const double* by, const double* bz, std::uint32_t count_b, double squared_distance,
    std::uint32_t& offset_a, std::uint32_t& offset_b) {
  const __m512d target = _mm512_set1_pd(squared_distance);
  for (std::uint32_t s = 0; s < count_a; ++s) {
    for (std::uint32_t t = 0; t < count_b; t += 8) {
      const __mmask8 lanes = lanesFrom(t, count_b);
      const __m512d squared = squaredDistancesAvx512(
          ax[s], ay[s], az[s], _mm512_maskz_loadu_pd(lanes, bx + t),
          _mm512_maskz_loadu_pd(lanes, by + t), _mm512_maskz_loadu_pd(lanes, bz + t));
      const std::uint32_t equal = _mm512_mask_cmp_pd_mask(lanes, squared, target, _CMP_EQ_OQ);
      if (equal != 0) {
        offset_a = s;
        offset_b = t + static_cast<std::uint32_t>(__builtin_ctz(equal));
        return;
      }
    }
  }
}

/// reachMask, eight spheres per instruction.
__attribute__((target("avx512f"))) std::uint32_t reachMaskAvx512(double x, double y, double z,
                                                                 double reach_m, const double* xs,
                                                                 const double* ys, const double* zs,
                                                                 const double* radii,
                                                                 std::uint32_t count) {
  const __mmask8 lanes = lanesFrom(0, count);
  const __m512d squared =
      squaredDistancesAvx512(x, y, z, _mm512_maskz_loadu_pd(lanes, xs),
                             _mm512_maskz_loadu_pd(lanes, ys), _mm512_maskz_loadu_pd(lanes, zs));
  const __m512d reach = _mm512_add_pd(_mm512_maskz_loadu_pd(lanes, radii), _mm512_set1_pd(reach_m));
  return _mm512_mask_cmp_pd_mask(lanes, squared, _mm512_mul_pd(reach, reach), _CMP_LT_OQ);
}

DEFORMABLE_COLLISION_END_WIDE_KERNELS
#endif

/// Bit j set if sphere j of the `count` (<= 8) given by coordinate arrays comes within
/// `reach_m` plus its radius of (x, y, z).
template <VectorWidth Width>
[[gnu::always_inline]] inline std::uint32_t reachMask(double x, double y, double z, double reach_m,
                                                      const double* xs, const double* ys,
                                                      const double* zs, const double* radii,
                                                      std::uint32_t count) {
#if defined(__GNUC__) && defined(__x86_64__)
  if constexpr (Width == VectorWidth::kAvx512) {
    return reachMaskAvx512(x, y, z, reach_m, xs, ys, zs, radii, count);
  }
  if constexpr (Width == VectorWidth::kAvx2) {
    return reachMaskAvx2(x, y, z, reach_m, xs, ys, zs, radii, count);
  }
#endif
  std::uint32_t mask = 0;
  for (std::uint32_t j = 0; j < count; ++j) {
    const double dx = x - xs[j], dy = y - ys[j], dz = z - zs[j];
    const double reach = radii[j] + reach_m;
    mask |= static_cast<std::uint32_t>(dx * dx + dy * dy + dz * dz < reach * reach) << j;
  }
  return mask;
}

}  // namespace
}  // namespace deformable_collision
