#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace deformable_collision {

/// Sweep and prune over the objects' boxes: the object pairs whose boxes overlap, the
/// candidates of the hierarchy query. The boxes are kept in the order of the last sweep:
/// objects move little between cycles, and an insertion sort restores the order in about
/// linear time. Steady-state sweeps allocate nothing.
class BroadPhase {
 public:
  /// An object's box; two static objects are never paired (neither can move the other).
  struct Box {
    Eigen::AlignedBox3d box;
    bool is_static = false;
  };
  using Pair = std::pair<std::uint32_t, std::uint32_t>;

  /// The pairs (a, b), a < b, of objects 0 .. count-1 whose boxes overlap, sorted by a, then
  /// b: the same order whatever the sweep's. `box_of(object)` gives each object's Box.
  template <typename BoxOf>
  const std::vector<Pair>& sweep(std::size_t count, BoxOf&& box_of) {
    if (entries_.size() != count) renumber(count);
    for (Entry& entry : entries_) {
      const Box box = box_of(entry.object);
      entry.box = box.box;
      entry.is_static = box.is_static;
    }
    sortEntries();
    collectOverlappingPairs();
    sortCandidatePairs(count);
    return candidate_pairs_;
  }

  /// Makes room for `count` objects' boxes ahead of their sweep.
  void reserve(std::size_t count) { entries_.reserve(count); }

 private:
  struct Entry {
    Eigen::AlignedBox3d box;
    std::uint32_t object = 0;
    bool is_static = false;
  };

  void renumber(std::size_t count);
  /// Insertion sort by the boxes' lower x (the order of the last sweep is nearly right).
  void sortEntries();
  void collectOverlappingPairs();
  void sortCandidatePairs(std::size_t count);

  std::vector<Entry> entries_;
  std::vector<Pair> candidate_pairs_;
  std::vector<Pair> sorted_pairs_;
  std::vector<std::uint32_t> pair_offsets_;
};

}  // namespace deformable_collision
