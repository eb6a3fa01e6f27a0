#include "deformable_collision/ros/cloud_handoff.h"

#include <algorithm>
#include <utility>

namespace deformable_collision {

CloudHandoff::CloudHandoff(std::vector<bool> starts_cycle)
    : waiting_(starts_cycle.size()),
      is_waiting_(starts_cycle.size(), false),
      taken_early_(starts_cycle.size(), false),
      replaced_since_cycle_(starts_cycle.size(), false),
      cycles_faster_(starts_cycle.size(), 0),
      starts_cycle_(std::move(starts_cycle)),
      objects_starting_cycles_(
          static_cast<std::size_t>(std::count(starts_cycle_.begin(), starts_cycle_.end(), true))) {
  // Each object is listed at most once in each: the lists never grow past this.
  waiting_objects_.reserve(starts_cycle_.size());
  early_objects_.reserve(starts_cycle_.size());
}

void CloudHandoff::put(std::size_t object, ReadCloud& cloud) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::swap(waiting_.at(object), cloud);
  if (is_waiting_[object]) {
    ReadCloud& newer = waiting_[object];
    if (newer.prepared.empty() && !cloud.prepared.empty())
      newer.prepared = std::move(cloud.prepared);
    if (!newer.fitted && cloud.fitted && newer.registration) keepOlderFit(newer, cloud);
    ++coalesced_;
    replaced_since_cycle_[object] = true;
    return;
  }
  is_waiting_[object] = true;
  waiting_objects_.push_back(object);
  if (starts_cycle_[object] && !taken_early_[object]) ++fresh_starting_cycles_;
}

void CloudHandoff::keepOlderFit(ReadCloud& newer, ReadCloud& older) {
  std::swap(newer.points, older.points);
  std::swap(newer.fit, older.fit);
  newer.fitted = true;
  newer.fit_error = older.fit_error;
}

bool CloudHandoff::ready(bool all) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return all ? objects_starting_cycles_ > 0 && fresh_starting_cycles_ == objects_starting_cycles_
             : fresh_starting_cycles_ > 0;
}

void CloudHandoff::takeEarly(std::vector<ReadCloud>& taken, std::vector<std::size_t>& objects) {
  objects.clear();
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t still_waiting = 0;
  for (const std::size_t object : waiting_objects_) {
    if (taken_early_[object] || cycles_faster_[object] >= kCyclesFasterToWait) {
      waiting_objects_[still_waiting++] = object;
      continue;
    }
    std::swap(waiting_[object], taken.at(object));
    is_waiting_[object] = false;
    taken_early_[object] = true;
    early_objects_.push_back(object);
    objects.push_back(object);
  }
  waiting_objects_.resize(still_waiting);
}

void CloudHandoff::takeForCycle(std::vector<ReadCloud>& taken, std::vector<std::size_t>& objects) {
  objects.clear();
  std::lock_guard<std::mutex> lock(mutex_);
  for (const std::size_t object : waiting_objects_) {
    std::swap(waiting_[object], taken.at(object));
    is_waiting_[object] = false;
    // Two clouds or more for this cycle: one taken early, or one replaced while it waited.
    const bool faster = taken_early_[object] || replaced_since_cycle_[object];
    cycles_faster_[object] = faster ? std::min(cycles_faster_[object] + 1, kCyclesFasterToWait) : 0;
    replaced_since_cycle_[object] = false;
    taken_early_[object] = false;
    objects.push_back(object);
  }
  waiting_objects_.clear();
  for (const std::size_t object : early_objects_) {
    // Still marked: taken early and not again, one cloud for this cycle.
    if (taken_early_[object]) cycles_faster_[object] = 0;
    taken_early_[object] = false;
  }
  early_objects_.clear();
  fresh_starting_cycles_ = 0;
}

std::uint64_t CloudHandoff::coalesced() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return coalesced_;
}

}  // namespace deformable_collision
