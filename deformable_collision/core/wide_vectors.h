#pragma once

namespace deformable_collision {

/// Whether this CPU has the wide vectors (AVX-512F) with which the core's kernels handle
/// eight points or leaves per instruction. Each such kernel computes every point's value
/// with the same operations, in the same order, as its portable twin, so both give the same
/// bits: results never depend on the machine's CPU.
inline bool wideVectorsAvailable() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool available = __builtin_cpu_supports("avx512f");
  return available;
#else
  return false;
#endif
}

}  // namespace deformable_collision
