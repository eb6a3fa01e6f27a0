#include "deformable_collision/core/query/broad_phase.h"

#include <algorithm>

namespace deformable_collision {

void BroadPhase::renumber(std::size_t count) {
  entries_.clear();
  for (std::uint32_t i = 0; i < count; ++i) entries_.push_back({{}, i, false});
}

void BroadPhase::sortEntries() {
  const auto before = [](const Entry& a, const Entry& b) {
    return a.box.min().x() < b.box.min().x() ||
           (a.box.min().x() == b.box.min().x() && a.object < b.object);
  };
  for (std::size_t i = 1; i < entries_.size(); ++i) {
    const Entry entry = entries_[i];
    std::size_t j = i;
    for (; j > 0 && before(entry, entries_[j - 1]); --j) {
      entries_[j] = entries_[j - 1];
    }
    entries_[j] = entry;
  }
}

// Objects overlapping the current one along x are those after it whose interval starts
// before its own ends; of those, the ones whose boxes overlap along y and z are kept.
void BroadPhase::collectOverlappingPairs() {
  candidate_pairs_.clear();
  for (std::size_t s = 0; s < entries_.size(); ++s) {
    const Entry& first = entries_[s];
    for (std::size_t t = s + 1; t < entries_.size(); ++t) {
      const Entry& second = entries_[t];
      if (second.box.min().x() > first.box.max().x()) break;
      // Overlapping along x by the sweep; y and z decide, without a branch.
      const bool overlap = (second.box.min().y() <= first.box.max().y()) &
                           (first.box.min().y() <= second.box.max().y()) &
                           (second.box.min().z() <= first.box.max().z()) &
                           (first.box.min().z() <= second.box.max().z()) &
                           !(first.is_static & second.is_static);
      if (!overlap) continue;
      candidate_pairs_.emplace_back(std::min(first.object, second.object),
                                    std::max(first.object, second.object));
    }
  }
}

// Deterministic contact order, whatever the sweep order: by first object (a counting sort),
// then by second (an object has a handful of partners).
void BroadPhase::sortCandidatePairs(std::size_t count) {
  pair_offsets_.assign(count + 1, 0);
  for (const auto& pair : candidate_pairs_) ++pair_offsets_[pair.first + 1];
  for (std::size_t i = 0; i < count; ++i) pair_offsets_[i + 1] += pair_offsets_[i];
  sorted_pairs_.resize(candidate_pairs_.size());
  for (const auto& pair : candidate_pairs_) sorted_pairs_[pair_offsets_[pair.first]++] = pair;
  // Each offset now ends its object's run, where the next object's begins.
  std::uint32_t run_begin = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t run_end = pair_offsets_[i];
    for (std::uint32_t k = run_begin + 1; k < run_end; ++k) {
      const auto pair = sorted_pairs_[k];
      std::uint32_t j = k;
      for (; j > run_begin && pair.second < sorted_pairs_[j - 1].second; --j) {
        sorted_pairs_[j] = sorted_pairs_[j - 1];
      }
      sorted_pairs_[j] = pair;
    }
    run_begin = run_end;
  }
  candidate_pairs_.swap(sorted_pairs_);
}

}  // namespace deformable_collision
