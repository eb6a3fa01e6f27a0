// The ways S1 answers one query on two deforming point sets: our sphere trees with each
// update (bench_collision.cpp), and the peers a user would pick instead (FCL, Bullet, PCL,
// s1_peers.cpp). Every method answers the same question on the same points each step:
// which point pairs (one point of each object) are closer than the contact distance.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace deformable_collision::bench {

/// (index of a point of object a, index of a point of object b).
using PointPair = std::pair<std::uint32_t, std::uint32_t>;

inline bool closerThan(const Eigen::Vector3d& x, const Eigen::Vector3d& y, double distance) {
  return (x - y).squaredNorm() < distance * distance;
}

inline std::vector<PointPair> sortedUnique(std::vector<PointPair> pairs) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

class S1Method {
 public:
  virtual ~S1Method() = default;
  virtual const char* name() const = 0;
  /// The timed work of one step: brings the structure up to the current points and runs
  /// the query. Returns the bounding volumes it updated (each method says what it counts).
  virtual std::size_t step() = 0;
  /// The point pairs the last step found, sorted and unique: the untimed cross-check that
  /// every method found the same pairs.
  virtual std::vector<PointPair> pointPairs() const = 0;
};

/// The peers, over the bodies' current points (`a` and `b` keep their size and address):
///   fcl_aabb, fcl_obbrss - FCL BVHModel point clouds refitted each step; count every BV
///                          node of both models
///   bullet_dbvt          - a btDbvt per object, a leaf per point; counts leaves reinserted
///   pcl_kdtree           - a KdTreeFLANN over b rebuilt each step, a radius search per
///                          point of a; counts the points indexed
/// (s1_peers.cpp says how each is used).
std::vector<std::unique_ptr<S1Method>> makePeers(const std::vector<Eigen::Vector3d>& a,
                                                 const std::vector<Eigen::Vector3d>& b,
                                                 double contact_distance_m);

}  // namespace deformable_collision::bench
