// PairQueryLanes: every pair is queried once, never while another query holds one of its
// objects; each pair's contacts come back in the order its query appended them, whichever
// lane ran it; counters add up over the lanes; a throwing query is reported and releases
// its objects.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "deformable_collision/core/scene/detail/pair_query_lanes.h"

namespace deformable_collision {
namespace detail {
namespace {

using ObjectPairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

/// A pile-like set of pairs: object 0 (a floor) with many, the others with neighbours.
ObjectPairs pileLikePairs(std::uint32_t objects, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ObjectPairs pairs;
  for (std::uint32_t a = 0; a < objects; ++a) {
    for (std::uint32_t b = a + 1; b < objects; ++b) {
      if (a == 0 ? rng() % 3 == 0 : (b - a < 6 && rng() % 2 == 0)) pairs.emplace_back(a, b);
    }
  }
  return pairs;
}

/// Contacts whose fields say which pair made them and in which order.
SceneContact contactOf(std::uint32_t a, std::uint32_t b, std::uint32_t k) {
  SceneContact contact;
  contact.object_a = a;
  contact.object_b = b;
  contact.contact.node_a = k;
  return contact;
}

TEST(PairQueryLanes, QueriesEveryPairOnceAndNeverTwoSharingAnObject) {
  for (const int threads : {1, 2, 4}) {
    WorkerPool pool(threads);
    PairQueryLanes lanes;
    for (int round = 0; round < 20; ++round) {
      const std::uint32_t objects = 40 + round;
      const ObjectPairs pairs = pileLikePairs(objects, 11 + static_cast<std::uint64_t>(round));
      lanes.clear(objects);
      for (const auto& [a, b] : pairs) lanes.add(a, b);
      std::vector<std::atomic<int>> in_use(objects);
      std::atomic<int> overlaps{0};
      std::atomic<std::size_t> calls{0};
      lanes.run(pool, [&](std::uint32_t a, std::uint32_t b, HierarchyQuery&,
                          QueryCounters& counters, std::vector<SceneContact>& contacts) {
        if (in_use[a].fetch_add(1) != 0) ++overlaps;
        if (in_use[b].fetch_add(1) != 0) ++overlaps;
        std::this_thread::yield();
        // As many contacts as the pair's objects say, so that lanes' lists differ in length.
        for (std::uint32_t k = 0; k < (a + b) % 4; ++k) contacts.push_back(contactOf(a, b, k));
        ++counters.node_pairs_tested;
        calls.fetch_add(1);
        in_use[a].fetch_sub(1);
        in_use[b].fetch_sub(1);
      });
      ASSERT_EQ(overlaps.load(), 0) << threads << " threads, round " << round;
      ASSERT_EQ(calls.load(), pairs.size());
      QueryCounters counters;
      lanes.addCounters(counters);
      EXPECT_EQ(counters.node_pairs_tested, pairs.size());
      for (std::size_t i = 0; i < pairs.size(); ++i) {
        const auto [a, b] = pairs[i];
        const SceneContact* begin = lanes.contactsBegin(i);
        ASSERT_EQ(lanes.contactsEnd(i) - begin, static_cast<std::ptrdiff_t>((a + b) % 4));
        for (std::uint32_t k = 0; k < (a + b) % 4; ++k) {
          EXPECT_EQ(begin[k].object_a, a);
          EXPECT_EQ(begin[k].object_b, b);
          EXPECT_EQ(begin[k].contact.node_a, k);
        }
      }
    }
  }
}

TEST(PairQueryLanes, AThrowingQueryIsReportedAndReleasesItsObjects) {
  WorkerPool pool(2);
  PairQueryLanes lanes;
  const ObjectPairs pairs = pileLikePairs(30, 5);
  lanes.clear(30);
  for (const auto& [a, b] : pairs) lanes.add(a, b);
  std::atomic<std::size_t> calls{0};
  const auto query = [&](std::uint32_t a, std::uint32_t, HierarchyQuery&, QueryCounters&,
                         std::vector<SceneContact>&) {
    calls.fetch_add(1);
    if (a == 0) throw std::runtime_error("the floor's query failed");
  };
  EXPECT_THROW(lanes.run(pool, query), std::runtime_error);
  EXPECT_GE(calls.load(), 1u);
  // The next run finds every object free: it would wait for ever on one still held.
  calls = 0;
  lanes.run(pool, [&](std::uint32_t, std::uint32_t, HierarchyQuery&, QueryCounters&,
                      std::vector<SceneContact>&) { calls.fetch_add(1); });
  EXPECT_EQ(calls.load(), pairs.size());
}

}  // namespace
}  // namespace detail
}  // namespace deformable_collision
