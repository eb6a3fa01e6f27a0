#include "deformable_collision/core/scene/detail/pair_query_lanes.h"

#include <algorithm>
#include <thread>

namespace deformable_collision {
namespace detail {

void PairQueryLanes::clear(std::size_t objects) {
  pairs_.clear();
  if (objects > objects_capacity_) {
    object_held_ = std::make_unique<std::atomic<bool>[]>(objects);
    objects_capacity_ = objects;
  }
}

const SceneContact* PairQueryLanes::contactsBegin(std::size_t index) const {
  const Pair& p = pairs_[index];
  return lanes_[p.lane].contacts.data() + p.begin;
}

const SceneContact* PairQueryLanes::contactsEnd(std::size_t index) const {
  const Pair& p = pairs_[index];
  return lanes_[p.lane].contacts.data() + p.end;
}

void PairQueryLanes::addCounters(QueryCounters& counters) const {
  for (const Lane& lane : lanes_) {
    counters.node_pairs_tested += lane.counters.node_pairs_tested;
    counters.leaf_pairs_tested += lane.counters.leaf_pairs_tested;
    counters.point_tests += lane.counters.point_tests;
  }
}

PairQueryLanes::Held::~Held() {
  lanes_.release(pair_.object_a);
  lanes_.release(pair_.object_b);
}

void PairQueryLanes::startLanes(std::size_t threads) {
  std::size_t contacts = 0;
  for (const Lane& lane : lanes_) contacts += lane.contacts.size();
  most_contacts_ = std::max(most_contacts_, contacts);
  if (lanes_.size() != threads) lanes_ = std::vector<Lane>(threads);
  for (Lane& lane : lanes_) {
    lane.counters = QueryCounters{};
    lane.contacts.clear();
    lane.contacts.reserve(most_contacts_);
    lane.first_open = 0;
    lane.next = 0;
  }
  if (pairs_.size() > pairs_capacity_) {
    pair_taken_ = std::make_unique<std::atomic<bool>[]>(pairs_.size());
    pairs_capacity_ = pairs_.size();
  }
  for (std::size_t i = 0; i < pairs_.size(); ++i) pair_taken_[i].store(false);
  pairs_taken_.store(0);
}

std::optional<std::size_t> PairQueryLanes::take(Lane& lane) {
  const std::size_t count = pairs_.size();
  while (pairs_taken_.load(std::memory_order_acquire) < count) {
    // On from the lane's last pair, then the ones before it: a lane kept off the pairs of a
    // busy object (a pile's floor, whose pairs come first) does not scan them every time.
    if (const auto taken = takeAmong(lane, lane.next, count)) return taken;
    while (lane.first_open < lane.next &&
           pair_taken_[lane.first_open].load(std::memory_order_relaxed)) {
      ++lane.first_open;
    }
    if (const auto taken = takeAmong(lane, lane.first_open, lane.next)) return taken;
    // The pairs left share an object with a query in progress.
    std::this_thread::yield();
  }
  return std::nullopt;
}

std::optional<std::size_t> PairQueryLanes::takeAmong(Lane& lane, std::size_t begin,
                                                     std::size_t end) {
  for (std::size_t i = begin; i < end; ++i) {
    if (!tryTake(i)) continue;
    lane.next = i + 1;
    return i;
  }
  return std::nullopt;
}

bool PairQueryLanes::tryTake(std::size_t index) {
  if (pair_taken_[index].load(std::memory_order_relaxed)) return false;
  const Pair& p = pairs_[index];
  if (!hold(p.object_a)) return false;
  if (!hold(p.object_b)) {
    release(p.object_a);
    return false;
  }
  // Another lane may have taken and finished the pair between the test above and now.
  if (pair_taken_[index].exchange(true, std::memory_order_acq_rel)) {
    release(p.object_a);
    release(p.object_b);
    return false;
  }
  pairs_taken_.fetch_add(1, std::memory_order_acq_rel);
  return true;
}

bool PairQueryLanes::hold(std::uint32_t object) {
  // Read first: a lane scanning past a busy object's pairs (a pile's floor) would otherwise
  // write its flag's cache line away from the core that holds it each time.
  if (object_held_[object].load(std::memory_order_relaxed)) return false;
  return !object_held_[object].exchange(true, std::memory_order_acquire);
}

void PairQueryLanes::release(std::uint32_t object) {
  object_held_[object].store(false, std::memory_order_release);
}

}  // namespace detail
}  // namespace deformable_collision
