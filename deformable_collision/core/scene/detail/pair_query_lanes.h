// Internal to the core: a detection's object pairs queried on a pool's threads. Not
// installed.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "deformable_collision/core/common/worker_pool.h"
#include "deformable_collision/core/query/collision_query.h"
#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {
namespace detail {

/// Runs the queries of a detection's object pairs on a pool's threads. A pair's query reads
/// and writes its two objects (their trees' lazy spheres and their slabs) and nothing else, so
/// a thread takes a pair only while it holds both objects; each thread appends the contacts of
/// the pairs it took to its own list. What is computed lazily is the same whichever query
/// computes it first, so each pair's contacts are those one thread finds, in its order.
/// Nothing is allocated once the lists have grown to a scene's needs.
class PairQueryLanes {
 public:
  /// Forgets the pairs of the last run; the objects' indices are below `objects`.
  void clear(std::size_t objects);
  /// One more pair to query; a and b differ.
  void add(std::uint32_t object_a, std::uint32_t object_b) {
    pairs_.push_back(Pair{object_a, object_b});
  }

  /// Calls query(object_a, object_b, hierarchy_query, counters, contacts) for every pair
  /// added since clear(), on the pool's threads, each thread with its own query, counters and
  /// contact list. A query that throws releases its objects and ends its thread's part;
  /// the first such exception is thrown once every thread has stopped.
  template <typename Query>
  void run(WorkerPool& pool, const Query& query) {
    startLanes(static_cast<std::size_t>(pool.threads()));
    pool.forEach(lanes_.size(), [&](std::size_t lane_index) {
      Lane& lane = lanes_[lane_index];
      while (const std::optional<std::size_t> taken = take(lane)) {
        Pair& pair = pairs_[*taken];
        const Held held(*this, pair);
        pair.lane = lane_index;
        pair.begin = lane.contacts.size();
        query(pair.object_a, pair.object_b, lane.query, lane.counters, lane.contacts);
        pair.end = lane.contacts.size();
      }
    });
  }

  /// The contacts of pair `index` (in the order add() was called), in the order its query
  /// appended them.
  const SceneContact* contactsBegin(std::size_t index) const;
  const SceneContact* contactsEnd(std::size_t index) const;
  /// Adds the counters of the last run, over its threads, to `counters`.
  void addCounters(QueryCounters& counters) const;

 private:
  /// A pair to query, and once run() returned, where its contacts are.
  struct Pair {
    std::uint32_t object_a = 0;
    std::uint32_t object_b = 0;
    std::size_t lane = 0;
    std::size_t begin = 0;
    std::size_t end = 0;
  };

  struct Lane {
    HierarchyQuery query;
    QueryCounters counters;
    std::vector<SceneContact> contacts;
    std::size_t first_open = 0;  ///< Every pair before it is taken.
    std::size_t next = 0;        ///< After the lane's last pair.
  };

  /// Releases a taken pair's two objects when its query returns or throws.
  class Held {
   public:
    Held(PairQueryLanes& lanes, const Pair& pair) : lanes_(lanes), pair_(pair) {}
    ~Held();
    Held(const Held&) = delete;
    Held& operator=(const Held&) = delete;

   private:
    PairQueryLanes& lanes_;
    const Pair& pair_;
  };

  void startLanes(std::size_t threads);
  /// A pair not yet taken whose two objects this lane now holds; std::nullopt once every pair
  /// is taken. Waits while the pairs left share an object with a query in progress.
  std::optional<std::size_t> take(Lane& lane);
  /// The first pair in [begin, end) that tryTake() takes, for `lane`.
  std::optional<std::size_t> takeAmong(Lane& lane, std::size_t begin, std::size_t end);
  /// Takes pair `index` if no lane took it and both its objects are free.
  bool tryTake(std::size_t index);
  bool hold(std::uint32_t object);
  void release(std::uint32_t object);

  std::vector<Pair> pairs_;
  std::vector<Lane> lanes_;
  std::unique_ptr<std::atomic<bool>[]> object_held_;
  std::size_t objects_capacity_ = 0;
  std::unique_ptr<std::atomic<bool>[]> pair_taken_;
  std::size_t pairs_capacity_ = 0;
  std::atomic<std::size_t> pairs_taken_{0};
  /// The most contacts a run found: every lane has room for them, so that however the pairs
  /// fall to the lanes, a steady scene allocates nothing.
  std::size_t most_contacts_ = 0;
};

}  // namespace detail
}  // namespace deformable_collision
