#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "deformable_collision/core/registration/cloud_registration.h"

namespace deformable_collision::bench {

/// PCL's rigid ICP (pcl::IterativeClosestPoint) as a peer of CloudRegistration in
/// bench_registration: the model is cut into rigid parts (the whole object, or each
/// shape-matching cluster), and each part's rest points are aligned to every cloud alone,
/// warm started from the part's last transform. The cloud is thinned as CloudRegistration
/// thins it, and the rounds and the largest match distance are its own, so that errors
/// and times compare on the same work. Each thinned cloud point is matched to its nearest
/// rest point of the part (PCL's kd-tree over the rest points, built once): the direction
/// in which a partial view has a match for every point of the object, as in ours.
class PclIcpRegistration {
 public:
  /// `parts`: indices into `rest_points_m`, every point in at least one part. A point in
  /// several parts is placed at the mean of their transforms.
  PclIcpRegistration(const std::vector<Eigen::Vector3d>& rest_points_m,
                     const std::vector<std::vector<std::uint32_t>>& parts,
                     const RegistrationConfig& config);
  ~PclIcpRegistration();

  /// Aligns every part to `cloud_m` (world frame, NaNs allowed) and places the model's
  /// points by the parts' transforms. A part with fewer than three matches keeps its last
  /// transform. Returns the number of parts so held.
  std::size_t registerCloud(const std::vector<Eigen::Vector3d>& cloud_m);

  /// The model's points in the world frame, in model order.
  const std::vector<Eigen::Vector3d>& positions() const { return positions_; }

 private:
  struct Part;
  struct Samples;
  void thinCloud(const std::vector<Eigen::Vector3d>& cloud_m);
  void placePoints();

  RegistrationConfig config_;
  std::vector<Eigen::Vector3d> rest_points_m_;
  std::vector<Part> parts_;
  std::vector<std::uint32_t> parts_of_point_;
  std::vector<Eigen::Vector3d> positions_;
  std::unique_ptr<Samples> samples_;
};

}  // namespace deformable_collision::bench
