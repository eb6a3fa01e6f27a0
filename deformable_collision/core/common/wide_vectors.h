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

/// The widest vectors this CPU gives the collision query's kernels: eight lanes
/// (AVX-512F), four (AVX2), or none (portable code). Every width finds the same bits.
enum class VectorWidth { kPortable, kAvx2, kAvx512 };

inline VectorWidth widestVectors() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const VectorWidth widest = wideVectorsAvailable()           ? VectorWidth::kAvx512
                                    : __builtin_cpu_supports("avx2") ? VectorWidth::kAvx2
                                                                     : VectorWidth::kPortable;
  return widest;
#else
  return VectorWidth::kPortable;
#endif
}

}  // namespace deformable_collision
