#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {

/// Nearest-point queries over a set of points rebuilt often (a registration's model points,
/// every round of every cloud): a kd-tree laid out in one index array, split at the median
/// of each range's widest coordinate. After the first build of a size, rebuilding for at
/// most that many points allocates nothing.
class NearestPointIndex {
 public:
  struct Nearest {
    std::uint32_t index = 0;  ///< Into the points given to build().
    double squared_distance_m2 = 0.0;
  };

  /// Indexes `points`, which must stay alive and unchanged until the next build(). The
  /// points must be finite.
  void build(const std::vector<Eigen::Vector3d>& points);

  /// The nearest indexed point to `query` (of equally near ones, any); false if no point
  /// is indexed.
  bool nearest(const Eigen::Vector3d& query, Nearest& found) const;
  /// The nearest indexed point to `query` at a squared distance below `below_squared_m2`;
  /// false if there is none. The bound prunes the search from the start: a query far from
  /// every point costs a few nodes.
  bool nearestWithin(const Eigen::Vector3d& query, double below_squared_m2, Nearest& found) const;

  std::size_t size() const { return order_.size(); }

 private:
  /// Ranges of at most this many points are scanned rather than split.
  static constexpr std::uint32_t kLeafSize = 8;

  void split(std::uint32_t begin, std::uint32_t end);
  void search(std::uint32_t begin, std::uint32_t end, const Eigen::Vector3d& query,
              Nearest& best) const;

  const std::vector<Eigen::Vector3d>* points_ = nullptr;
  std::vector<std::uint32_t> order_;  ///< Point indices; each range's median splits it.
  /// The points in that order: a search reads them in sequence.
  std::vector<Eigen::Vector3d> ordered_;
  /// Of a range split at `mid`: the coordinate it was split on, stored at `mid`.
  std::vector<std::uint8_t> split_axis_;
};

}  // namespace deformable_collision
