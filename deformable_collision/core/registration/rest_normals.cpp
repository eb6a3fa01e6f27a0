#include "deformable_collision/core/registration/detail/rest_normals.h"

#include <Eigen/Eigenvalues>
#include <nanoflann.hpp>

namespace deformable_collision {
namespace detail {
namespace {

/// The rest shape's points, as nanoflann reads them.
struct MatchingPoints {
  std::vector<Eigen::Vector3d> positions;
  std::size_t kdtree_get_point_count() const { return positions.size(); }
  double kdtree_get_pt(std::size_t index, std::size_t dim) const { return positions[index][dim]; }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*box*/) const {
    return false;
  }
};

using MatchingTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, MatchingPoints>,
                                        MatchingPoints, 3, std::uint32_t>;

/// Neighbours whose spread gives a matching point's surface normal.
constexpr std::size_t kNormalNeighbours = 12;
/// A neighbourhood is flat where it spreads this much less across than along: a face, not
/// an edge, whose points are matched along the normal only. Loose enough for a scan or a
/// first cloud with the camera's noise (1 mm across at 2 mm spacing spreads about 0.15 as
/// much across as along).
constexpr double kFlatness = 0.25;

}  // namespace

RestNormals restNormals(const std::vector<Eigen::Vector3d>& rest,
                        const std::vector<std::uint32_t>& chosen) {
  MatchingPoints all{rest};
  MatchingTree tree(3, all, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : rest) centre += p;
  centre /= static_cast<double>(rest.size());
  RestNormals normals{std::vector<Eigen::Vector3d>(chosen.size(), Eigen::Vector3d::Zero()),
                      std::vector<char>(chosen.size(), 0)};
  std::uint32_t neighbours[kNormalNeighbours];
  double squared[kNormalNeighbours];
  for (std::size_t m = 0; m < chosen.size(); ++m) {
    const Eigen::Vector3d& at = rest[chosen[m]];
    const std::size_t found = tree.knnSearch(at.data(), kNormalNeighbours, neighbours, squared);
    if (found < 3) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < found; ++k) mean += rest[neighbours[k]];
    mean /= static_cast<double>(found);
    Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < found; ++k) {
      const Eigen::Vector3d d = rest[neighbours[k]] - mean;
      spread += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(spread);
    const Eigen::Vector3d normal = solver.eigenvectors().col(0);
    normals.outward[m] = normal.dot(at - centre) < 0.0 ? Eigen::Vector3d(-normal) : normal;
    normals.flat[m] = solver.eigenvalues()(0) < kFlatness * solver.eigenvalues()(1);
  }
  return normals;
}

}  // namespace detail
}  // namespace deformable_collision
