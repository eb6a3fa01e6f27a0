// Internal to the core: work items grouped by the object they change, run on a pool. Not
// installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "deformable_collision/core/common/worker_pool.h"

namespace deformable_collision {
namespace detail {

/// Items that each change one object and read nothing another item changes, except earlier
/// items of the same object: the items of an object run on one thread in the order added,
/// different objects' on the pool's threads at once. So every item sees what it would see
/// with all of them run in the order added on one thread. Nothing is allocated once the
/// lists have grown to a scene's needs.
class ObjectGroups {
 public:
  /// Forgets the items of the last run.
  void clear() { items_.clear(); }
  /// One more item, numbered above every item added since clear(), changing `object`.
  void add(std::uint32_t object, std::uint32_t item) { items_.emplace_back(object, item); }
  std::size_t size() const { return items_.size(); }

  /// Calls body(item, lane) for every item added since clear(), on `pool`'s threads, `lane`
  /// in [0, pool.threads()) and never used by two calls at once: the caller's scratch for
  /// the call. The first exception a call throws is thrown once every call has returned.
  template <typename Body>
  void run(WorkerPool& pool, const Body& body) {
    group();
    // An object's items stay on one lane, in order.
    pool.forEachOnLane(starts_.size() - 1, [&](std::size_t g, std::size_t lane) {
      for (std::size_t i = starts_[g]; i < starts_[g + 1]; ++i) body(items_[i].second, lane);
    });
  }

 private:
  /// Sorts the items by object, then number, and marks where each object's begin.
  void group();

  std::vector<std::pair<std::uint32_t, std::uint32_t>> items_;  ///< (object, item).
  std::vector<std::size_t> starts_;  ///< Each object's first item, then items_.size().
};

}  // namespace detail
}  // namespace deformable_collision
