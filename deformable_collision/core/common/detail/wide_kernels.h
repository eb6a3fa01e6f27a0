#pragma once

// Internal to the core: what a source file with AVX-512 kernels includes. Which kernels run
// is decided at run time (wide_vectors.h); this header only makes them compile.

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <cstdint>

// GCC 12's AVX-512 intrinsics pass a deliberately undefined operand that its own
// uninitialised-use warnings then report (GCC bug 105593): the kernels sit between these two.
#if defined(__clang__)
#define DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS \
  _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wuninitialized\"")
#else
#define DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS                                        \
  _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wuninitialized\"") \
      _Pragma("GCC diagnostic ignored \"-Wmaybe-uninitialized\"")
#endif
#define DEFORMABLE_COLLISION_END_WIDE_KERNELS _Pragma("GCC diagnostic pop")

namespace deformable_collision {
namespace {
DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

/// Squared distances from (x, y, z) to eight points given by their coordinates, summed as
/// the scalar code sums them, so both give the same bits.
__attribute__((target("avx512f"))) inline __m512d squaredDistancesAvx512(double x, double y,
                                                                         double z, __m512d xs,
                                                                         __m512d ys, __m512d zs) {
  const __m512d dx = _mm512_sub_pd(_mm512_set1_pd(x), xs);
  const __m512d dy = _mm512_sub_pd(_mm512_set1_pd(y), ys);
  const __m512d dz = _mm512_sub_pd(_mm512_set1_pd(z), zs);
  return _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                       _mm512_mul_pd(dz, dz));
}

/// The lanes of the up to eight values from `offset` on of `count`.
inline __mmask8 lanesFrom(std::uint32_t offset, std::uint32_t count) {
  return count - offset >= 8 ? 0xFF : static_cast<__mmask8>((1u << (count - offset)) - 1);
}

DEFORMABLE_COLLISION_END_WIDE_KERNELS
}  // namespace
}  // namespace deformable_collision

#endif
