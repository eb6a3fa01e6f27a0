#include "deformable_collision/core/collision_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "deformable_collision/core/wide_kernels.h"

namespace deformable_collision {
namespace {

/// Unit vector from b to a, or +z when the two coincide (any direction is then as good).
Eigen::Vector3d directionFrom(const Eigen::Vector3d& b, const Eigen::Vector3d& a) {
  const Eigen::Vector3d d = a - b;
  const double length = d.norm();
  return length > 0.0 ? Eigen::Vector3d(d / length) : Eigen::Vector3d::UnitZ();
}

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
    const __m128d squared = _mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)), _mm_mul_pd(dz, dz));
    pair_nearest = _mm_min_pd(pair_nearest, squared);
  }
  nearest = std::min(_mm_cvtsd_f64(pair_nearest), _mm_cvtsd_f64(_mm_unpackhi_pd(pair_nearest, pair_nearest)));
#endif
  for (; t < count; ++t) {
    const double dx = x - xs[t], dy = y - ys[t], dz = z - zs[t];
    nearest = std::min(nearest, dx * dx + dy * dy + dz * dz);
  }
  return nearest;
}

#if defined(__GNUC__) && defined(__x86_64__)
DEFORMABLE_COLLISION_BEGIN_WIDE_KERNELS

/// Squared distances from (x, y, z) to eight points given by their coordinates, summed as
/// the scalar code sums them, so both give the same bits.
__attribute__((target("avx512f"))) inline __m512d squaredDistancesAvx512(double x, double y,
                                                                         double z, __m512d xs,
                                                                         __m512d ys, __m512d zs) {
  const __m512d dx = _mm512_sub_pd(_mm512_set1_pd(x), xs);
  const __m512d dy = _mm512_sub_pd(_mm512_set1_pd(y), ys);
  const __m512d dz = _mm512_sub_pd(_mm512_set1_pd(z), zs);
  return _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
}

/// The lanes of the up to eight values from `offset` on of `count`.
inline __mmask8 lanesFrom(std::uint32_t offset, std::uint32_t count) {
  return count - offset >= 8 ? 0xFF : static_cast<__mmask8>((1u << (count - offset)) - 1);
}

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

/// nearestPairSquaredDistanceAvx512 and firstPairAtAvx512 in one pass, for up to eight
/// points of b: each lane keeps the first of a's points at its least distance, so the
/// closest pair of a contact costs no second pass over the rows.
__attribute__((target("avx512f"))) bool closestPairOfEightAvx512(
    const double* ax, const double* ay, const double* az, std::uint32_t count_a, const double* bx,
    const double* by, const double* bz, std::uint32_t count_b, double below_squared,
    double& nearest_squared, std::uint32_t& offset_a, std::uint32_t& offset_b) {
  const __mmask8 lanes = lanesFrom(0, count_b);
  const __m512d x = _mm512_maskz_loadu_pd(lanes, bx);
  const __m512d y = _mm512_maskz_loadu_pd(lanes, by);
  const __m512d z = _mm512_maskz_loadu_pd(lanes, bz);
  __m512d nearest = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  __m512i row = _mm512_setzero_si512();
  for (std::uint32_t s = 0; s < count_a; ++s) {
    const __m512d squared = squaredDistancesAvx512(ax[s], ay[s], az[s], x, y, z);
    const __mmask8 closer = _mm512_mask_cmp_pd_mask(lanes, squared, nearest, _CMP_LT_OQ);
    nearest = _mm512_mask_mov_pd(nearest, closer, squared);
    row = _mm512_mask_mov_epi64(row, closer, _mm512_set1_epi64(s));
  }
  if (_mm512_cmp_pd_mask(nearest, _mm512_set1_pd(below_squared), _CMP_LT_OQ) == 0) return false;
  const __m512d least = leastInEveryLaneAvx512(nearest);
  nearest_squared = _mm512_cvtsd_f64(least);
  // Of the lanes at the least distance, the one with the first row, then the first lane.
  const __mmask8 at_least = _mm512_mask_cmp_pd_mask(lanes, nearest, least, _CMP_EQ_OQ);
  const __m512i order = _mm512_add_epi64(_mm512_slli_epi64(row, 3),
                                         _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0));
  const auto first = static_cast<std::uint64_t>(_mm512_mask_reduce_min_epi64(at_least, order));
  offset_a = static_cast<std::uint32_t>(first >> 3);
  offset_b = static_cast<std::uint32_t>(first & 7);
  return true;
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
__attribute__((target("avx512f"))) std::uint32_t reachMaskAvx512(
    double x, double y, double z, double reach_m, const double* xs, const double* ys,
    const double* zs, const double* radii, std::uint32_t count) {
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
template <bool Wide>
[[gnu::always_inline]] inline std::uint32_t reachMask(double x, double y, double z, double reach_m,
                                                      const double* xs, const double* ys,
                                                      const double* zs, const double* radii,
                                                      std::uint32_t count) {
#if defined(__GNUC__) && defined(__x86_64__)
  if constexpr (Wide) return reachMaskAvx512(x, y, z, reach_m, xs, ys, zs, radii, count);
#endif
  std::uint32_t mask = 0;
  for (std::uint32_t j = 0; j < count; ++j) {
    const double dx = x - xs[j], dy = y - ys[j], dz = z - zs[j];
    const double reach = radii[j] + reach_m;
    mask |= static_cast<std::uint32_t>(dx * dx + dy * dy + dz * dz < reach * reach) << j;
  }
  return mask;
}

/// Adds the contact of the leaves at `leaf_a` and `leaf_b` in the trees' leaf orders if a
/// point pair is closer than the contact distance, at their closest pair: all pairs at once
/// with wide vectors; otherwise the points of a near b's sphere, each against b's. Both
/// leaves must be current.
template <bool Wide>
[[gnu::always_inline]] inline void closestLeafPair(const SphereTree& a, std::uint32_t leaf_a,
                                                   const SphereTree& b, std::uint32_t leaf_b,
                                                   double contact_distance_m, ContactSink& contacts,
                                                   QueryCounters& counters) {
  const std::uint32_t first_a = a.leafSlotStarts()[leaf_a];
  const std::uint32_t first_b = b.leafSlotStarts()[leaf_b];
  const std::uint32_t count_a = a.leafSlotStarts()[leaf_a + 1] - first_a;
  const std::uint32_t count_b = b.leafSlotStarts()[leaf_b + 1] - first_b;
  const auto& pa = a.leafPositions();
  const auto& pb = b.leafPositions();
  const double* bx = &pb(0, first_b);
  const double* by = &pb(1, first_b);
  const double* bz = &pb(2, first_b);
  const double* ax = &pa(0, first_a);
  const double* ay = &pa(1, first_a);
  const double* az = &pa(2, first_a);
  double best = contact_distance_m * contact_distance_m;
  // Offsets of the closest pair in the two leaves: the first point of a at the least
  // distance, and the first point of b at that distance from it.
  std::uint32_t best_a = count_a;
  std::uint32_t best_b = 0;
#if defined(__GNUC__) && defined(__x86_64__)
  if constexpr (Wide) {
    counters.point_tests += count_a * count_b;
    if (count_b <= 8) {
      if (!closestPairOfEightAvx512(ax, ay, az, count_a, bx, by, bz, count_b, best, best, best_a,
                                    best_b)) {
        return;
      }
    } else {
      if (!nearestPairSquaredDistanceAvx512(ax, ay, az, count_a, bx, by, bz, count_b, best, best)) {
        return;
      }
      firstPairAtAvx512(ax, ay, az, count_a, bx, by, bz, count_b, best, best_a, best_b);
    }
  } else
#endif
  {
    const LeafSpheres& spheres_b = b.leafSpheres();
    const Eigen::Vector3d center_b(spheres_b.x[leaf_b], spheres_b.y[leaf_b], spheres_b.z[leaf_b]);
    const double reach = spheres_b.radius[leaf_b] + contact_distance_m;
    counters.point_tests += count_a;
    for (std::uint32_t s = 0; s < count_a; ++s) {
      const Eigen::Vector3d point(ax[s], ay[s], az[s]);
      if ((point - center_b).squaredNorm() >= reach * reach) continue;
      counters.point_tests += count_b;
      const double nearest = nearestSquaredDistance(bx, by, bz, count_b, ax[s], ay[s], az[s]);
      if (nearest < best) {
        best = nearest;
        best_a = s;
      }
    }
    if (best_a == count_a) return;
    double nearest = std::numeric_limits<double>::infinity();
    for (std::uint32_t t = 0; t < count_b; ++t) {
      const double dx = ax[best_a] - bx[t], dy = ay[best_a] - by[t], dz = az[best_a] - bz[t];
      const double distance_squared = dx * dx + dy * dy + dz * dz;
      if (distance_squared < nearest) {
        nearest = distance_squared;
        best_b = t;
      }
    }
  }
  SphereContact& contact = contacts.add();
  contact.node_a = a.leafNode(leaf_a);
  contact.node_b = b.leafNode(leaf_b);
  contact.level = std::max(a.node(contact.node_a).level, b.node(contact.node_b).level);
  contact.point_a = a.pointIndices()[first_a + best_a];
  contact.point_b = b.pointIndices()[first_b + best_b];
  const Eigen::Vector3d x(ax[best_a], ay[best_a], az[best_a]);
  const Eigen::Vector3d y(bx[best_b], by[best_b], bz[best_b]);
  contact.position = 0.5 * (x + y);
  contact.normal = directionFrom(y, x);
  contact.depth_m = contact_distance_m - std::sqrt(best);
}

/// Leaves under a node at which the descent to the leaves stops: their spheres are then
/// tested all against all, eight at a time, instead of pair by pair down the last levels.
constexpr std::uint32_t kBucketLeaves = SphereTree::kBucketLeaves;
static_assert(kBucketLeaves * kBucketLeaves <= 64, "a bucket pair's leaf pairs are one mask");

/// The leaf contacts of two nodes of at most kBucketLeaves leaves each, every leaf sphere
/// of one against every leaf sphere of the other. Both nodes' leaves must be current.
template <bool Wide>
[[gnu::always_inline]] inline void collideBuckets(const SphereTree& a, const NodeState& bucket_a,
                                                  const SphereTree& b, const NodeState& bucket_b,
                                                  double contact_distance_m,
                                                  ContactSink& contacts,
                                                  QueryCounters& counters) {
  counters.node_pairs_tested += bucket_a.leaf_count * bucket_b.leaf_count;
  const LeafSpheres& spheres_a = a.leafSpheres();
  const LeafSpheres& spheres_b = b.leafSpheres();
  const std::uint32_t first_a = bucket_a.first_leaf;
  const std::uint32_t first_b = bucket_b.first_leaf;
  // The pairs in reach, bit 8 k + j for leaf k of a and leaf j of b: one loop over them
  // all rather than one per leaf of a, whose ends a branch predictor cannot foresee.
  std::uint64_t within_reach = 0;
  for (std::uint32_t k = 0; k < bucket_a.leaf_count; ++k) {
    within_reach |= static_cast<std::uint64_t>(reachMask<Wide>(
                        spheres_a.x[first_a + k], spheres_a.y[first_a + k], spheres_a.z[first_a + k],
                        spheres_a.radius[first_a + k] + contact_distance_m, &spheres_b.x[first_b],
                        &spheres_b.y[first_b], &spheres_b.z[first_b], &spheres_b.radius[first_b],
                        bucket_b.leaf_count))
                    << (8 * k);
  }
  while (within_reach != 0) {
    const auto bit = static_cast<std::uint32_t>(__builtin_ctzll(within_reach));
    within_reach &= within_reach - 1;
    closestLeafPair<Wide>(a, first_a + (bit >> 3), b, first_b + (bit & 7), contact_distance_m,
                          contacts, counters);
  }
}

/// collideBuckets compiled for the wide vectors, its kernels inlined into it; and without.
#if defined(__GNUC__) && defined(__x86_64__)
__attribute__((target("avx512f"))) void collideBucketsWide(
    const SphereTree& a, const NodeState& bucket_a, const SphereTree& b, const NodeState& bucket_b,
    double contact_distance_m, ContactSink& contacts, QueryCounters& counters) {
  collideBuckets<true>(a, bucket_a, b, bucket_b, contact_distance_m, contacts, counters);
}
#endif

void collideBucketsPortable(const SphereTree& a, const NodeState& bucket_a, const SphereTree& b,
                            const NodeState& bucket_b, double contact_distance_m,
                            ContactSink& contacts, QueryCounters& counters) {
  collideBuckets<false>(a, bucket_a, b, bucket_b, contact_distance_m, contacts, counters);
}

/// The leaf contacts of two sets of at most kBucketLeaves buckets each, every bucket of one
/// against every bucket of the other at once: all the buckets of a small object (one of at
/// most kBucketLeaves buckets) rather than pair by pair down the levels above them. A small
/// object in reach of another has most of its buckets in reach too (a pile), and costs at
/// most kBucketLeaves buckets however its contacts lie.
template <bool Wide>
[[gnu::always_inline]] inline void collideBucketSets(SphereTree& a, const std::uint32_t* buckets_a,
                                                     std::uint32_t count_a, SphereTree& b,
                                                     const std::uint32_t* buckets_b,
                                                     std::uint32_t count_b,
                                                     double contact_distance_m,
                                                     ContactSink& contacts,
                                                     QueryCounters& counters) {
  double x[kBucketLeaves], y[kBucketLeaves], z[kBucketLeaves], radius[kBucketLeaves];
  for (std::uint32_t j = 0; j < count_b; ++j) {
    const Sphere& sphere = b.current(buckets_b[j], kBucketLeaves).sphere;
    x[j] = sphere.center.x();
    y[j] = sphere.center.y();
    z[j] = sphere.center.z();
    radius[j] = sphere.radius;
  }
  counters.node_pairs_tested += count_a * count_b;
  for (std::uint32_t k = 0; k < count_a; ++k) {
    const NodeState& bucket_a = a.current(buckets_a[k], kBucketLeaves);
    const Sphere& sphere = bucket_a.sphere;
    std::uint32_t within_reach =
        reachMask<Wide>(sphere.center.x(), sphere.center.y(), sphere.center.z(),
                        sphere.radius + contact_distance_m, x, y, z, radius, count_b);
    while (within_reach != 0) {
      const auto j = static_cast<std::uint32_t>(__builtin_ctz(within_reach));
      within_reach &= within_reach - 1;
      collideBuckets<Wide>(a, bucket_a, b, b.current(buckets_b[j], kBucketLeaves),
                           contact_distance_m, contacts, counters);
    }
  }
}

#if defined(__GNUC__) && defined(__x86_64__)
__attribute__((target("avx512f"))) void collideBucketSetsWide(
    SphereTree& a, const std::uint32_t* buckets_a, std::uint32_t count_a, SphereTree& b,
    const std::uint32_t* buckets_b, std::uint32_t count_b, double contact_distance_m,
    ContactSink& contacts, QueryCounters& counters) {
  collideBucketSets<true>(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                          contacts, counters);
}
#endif

void collideBucketSetsPortable(SphereTree& a, const std::uint32_t* buckets_a,
                               std::uint32_t count_a, SphereTree& b,
                               const std::uint32_t* buckets_b, std::uint32_t count_b,
                               double contact_distance_m, ContactSink& contacts,
                               QueryCounters& counters) {
  collideBucketSets<false>(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                           contacts, counters);
}

/// Whether two spheres come closer than the contact distance.
bool withinReach(const Sphere& a, const Sphere& b, double contact_distance_m) {
  const double reach = a.radius + b.radius + contact_distance_m;
  return (a.center - b.center).squaredNorm() < reach * reach;
}

/// How far two spheres, each grown by half the contact distance, overlap.
double overlap(const Sphere& a, const Sphere& b, double contact_distance_m) {
  return a.radius + b.radius + contact_distance_m - (a.center - b.center).norm();
}

}  // namespace

HierarchyQuery::HierarchyQuery(bool use_wide_vectors)
    : wide_vectors_(use_wide_vectors && wideVectorsAvailable()) {}

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             std::vector<SphereContact>& contacts, QueryCounters& counters) {
  struct Appender final : ContactSink {
    explicit Appender(std::vector<SphereContact>& contacts) : contacts(contacts) {}
    SphereContact& add() override { return contacts.emplace_back(); }
    std::vector<SphereContact>& contacts;
  } appender(contacts);
  collide(a, b, level, contact_distance_m, appender, counters);
}

void HierarchyQuery::collide(SphereTree& a, SphereTree& b, int level, double contact_distance_m,
                             ContactSink& contacts, QueryCounters& counters) {
  const bool to_leaves = level >= std::max(a.maxLevel(), b.maxLevel());
  // Towards the leaves, a node of kBucketLeaves leaves or fewer is measured with its leaves:
  // its leaves are tested whenever it comes within reach of another.
  const std::uint32_t leaf_limit = to_leaves ? kBucketLeaves : 0;
  // Branch-free where the outcome is a coin toss: which pairs end, which are in reach.
  const auto terminal = [level, to_leaves](const NodeState& node) {
    return to_leaves ? node.leaf_count <= kBucketLeaves : endsDescentToLevel(node, level);
  };
  // Pairs are tested before they are stacked, so the stack holds only pairs within reach.
  ++counters.node_pairs_tested;
  if (!withinReach(a.current(0, leaf_limit).sphere, b.current(0, leaf_limit).sphere,
                   contact_distance_m)) {
    return;
  }
  const auto bucketSets = [&](const std::uint32_t* buckets_a, std::uint32_t count_a,
                              const std::uint32_t* buckets_b, std::uint32_t count_b) {
#if defined(__GNUC__) && defined(__x86_64__)
    if (wide_vectors_) {
      collideBucketSetsWide(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                            contacts, counters);
      return;
    }
#endif
    collideBucketSetsPortable(a, buckets_a, count_a, b, buckets_b, count_b, contact_distance_m,
                              contacts, counters);
  };
  // A small object is never descended: its buckets meet the other's as a set, the other
  // object's buckets one at a time if it is not small too.
  const bool small_a = to_leaves && a.buckets().size() <= kBucketLeaves;
  const bool small_b = to_leaves && b.buckets().size() <= kBucketLeaves;
  const auto bucket_count_a = static_cast<std::uint32_t>(a.buckets().size());
  const auto bucket_count_b = static_cast<std::uint32_t>(b.buckets().size());
  if (small_a && small_b) {
    bucketSets(a.buckets().data(), bucket_count_a, b.buckets().data(), bucket_count_b);
    return;
  }
  // Above the leaves a pair carries the least overlap of its own and its ancestors'
  // spheres: all of them bound its points, so their overlap is at most that. A contact's
  // depth is then one that the response can clear without the pair's ancestors leaving
  // reach first, which would end the contact above where it rests.
  if (stack_.empty()) stack_.resize(1);
  stack_[0] = {0, 0, to_leaves ? 0.0 : overlap(a.sphere(0), b.sphere(0), contact_distance_m)};
  std::size_t stacked = 1;
  while (stacked > 0) {
    const auto [ia, ib, least_overlap] = stack_[--stacked];
    const NodeState& na = a.current(ia, leaf_limit);
    const NodeState& nb = b.current(ib, leaf_limit);
    const bool stop_a = small_a || terminal(na);
    const bool stop_b = small_b || terminal(nb);
    if (stop_a && stop_b) {
      if (small_a || small_b) {
        const std::uint32_t bucket_a = ia;
        const std::uint32_t bucket_b = ib;
        bucketSets(small_a ? a.buckets().data() : &bucket_a, small_a ? bucket_count_a : 1,
                   small_b ? b.buckets().data() : &bucket_b, small_b ? bucket_count_b : 1);
        continue;
      }
      if (to_leaves) {
#if defined(__GNUC__) && defined(__x86_64__)
        if (wide_vectors_) {
          collideBucketsWide(a, na, b, nb, contact_distance_m, contacts, counters);
          continue;
        }
#endif
        collideBucketsPortable(a, na, b, nb, contact_distance_m, contacts, counters);
        continue;
      }
      SphereContact& contact = contacts.add();
      contact.node_a = ia;
      contact.node_b = ib;
      contact.level = std::max(na.level, nb.level);
      const Sphere& sa = na.sphere;
      const Sphere& sb = nb.sphere;
      contact.normal = directionFrom(sb.center, sa.center);
      contact.depth_m = least_overlap;
      // Midway between the surfaces (grown by half the contact distance each) along the normal.
      const Eigen::Vector3d surface_a = sa.center - (sa.radius + 0.5 * contact_distance_m) * contact.normal;
      const Eigen::Vector3d surface_b = sb.center + (sb.radius + 0.5 * contact_distance_m) * contact.normal;
      contact.position = 0.5 * (surface_a + surface_b);
      continue;
    }
    // Descend the node that is not done, the larger one if both may go on. Children are
    // stacked last first, so that contacts come in depth-first order; each is written on
    // top and kept if it is within reach. The stack grows only in the first queries.
    const bool split_a = !stop_a && (stop_b || na.sphere.radius >= nb.sphere.radius);
    const NodeState& split = split_a ? na : nb;
    if (stack_.size() < stacked + split.child_count) {
      stack_.resize(std::max(2 * stack_.size(), stacked + split.child_count));
    }
    counters.node_pairs_tested += split.child_count;
    if (split_a) {
      for (std::uint32_t c = na.first_child + na.child_count; c-- > na.first_child;) {
        const Sphere& child = a.current(c, leaf_limit).sphere;
        stack_[stacked] = {c, ib, to_leaves ? 0.0
                                            : std::min(least_overlap,
                                                       overlap(child, nb.sphere, contact_distance_m))};
        stacked += withinReach(child, nb.sphere, contact_distance_m);
      }
    } else {
      for (std::uint32_t c = nb.first_child + nb.child_count; c-- > nb.first_child;) {
        const Sphere& child = b.current(c, leaf_limit).sphere;
        stack_[stacked] = {ia, c, to_leaves ? 0.0
                                            : std::min(least_overlap,
                                                       overlap(na.sphere, child, contact_distance_m))};
        stacked += withinReach(na.sphere, child, contact_distance_m);
      }
    }
  }
}

}  // namespace deformable_collision
