#pragma once

// Internal to the core: what a source file with AVX-512 kernels includes. Which kernels run
// is decided at run time (wide_vectors.h); this header only makes them compile.

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

// GCC 12's AVX-512 intrinsics pass a deliberately undefined operand that its own
// uninitialised-use warnings then report (GCC bug 105593): the kernels sit between these two.
#if defined(__clang__)
#define DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS \
  _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wuninitialized\"")
#else
#define DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS                    \
  _Pragma("GCC diagnostic push")                                   \
      _Pragma("GCC diagnostic ignored \"-Wuninitialized\"")        \
          _Pragma("GCC diagnostic ignored \"-Wmaybe-uninitialized\"")
#endif
#define DEFORMABLE_COLLISION_END_WIDE_KERNELS _Pragma("GCC diagnostic pop")

#endif
