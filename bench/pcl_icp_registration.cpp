#include "pcl_icp_registration.h"

#include <pcl/console/print.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>

namespace deformable_collision::bench {

namespace {

using Point = pcl::PointXYZ;
using Cloud = pcl::PointCloud<Point>;
using Icp = pcl::IterativeClosestPoint<Point, Point>;

Point toPcl(const Eigen::Vector3d& p) {
  return Point(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
}

Eigen::Matrix4f rigidInverse(const Eigen::Matrix4f& transform) {
  return Eigen::Affine3f(transform).inverse(Eigen::Isometry).matrix();
}

}  // namespace

struct PclIcpRegistration::Part {
  std::vector<std::uint32_t> points;
  std::unique_ptr<Icp> icp;
  Eigen::Matrix4f world_from_rest = Eigen::Matrix4f::Identity();
};

struct PclIcpRegistration::Samples {
  Cloud::Ptr thinned{new Cloud};
  Cloud aligned;  ///< align()'s output, unused: the transform is what is kept.
};

PclIcpRegistration::PclIcpRegistration(const std::vector<Eigen::Vector3d>& rest_points_m,
                                       const std::vector<std::vector<std::uint32_t>>& parts,
                                       const RegistrationConfig& config)
    : config_(config),
      rest_points_m_(rest_points_m),
      parts_of_point_(rest_points_m.size(), 0),
      positions_(rest_points_m),
      samples_(std::make_unique<Samples>()) {
  validateRegistrationConfig(config);
  // A part the camera does not see has no matches, which PCL reports on stderr every cloud;
  // registerCloud counts such parts instead.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  parts_.reserve(parts.size());
  for (const auto& indices : parts) {
    Cloud::Ptr target(new Cloud);
    for (const std::uint32_t i : indices) {
      target->push_back(toPcl(rest_points_m.at(i)));
      ++parts_of_point_[i];
    }
    // The rest points never move (the cloud is brought to them), so the kd-tree over them
    // is built here once, not by every align().
    pcl::search::KdTree<Point>::Ptr tree(new pcl::search::KdTree<Point>);
    tree->setInputCloud(target);
    Part part{indices, std::make_unique<Icp>(), Eigen::Matrix4f::Identity()};
    part.icp->setInputTarget(target);
    part.icp->setSearchMethodTarget(tree, true);
    part.icp->setMaximumIterations(config.iterations);
    part.icp->setMaxCorrespondenceDistance(config.max_correspondence_m);
    parts_.push_back(std::move(part));
  }
  if (std::count(parts_of_point_.begin(), parts_of_point_.end(), 0u) > 0) {
    throw std::invalid_argument("PclIcpRegistration: a model point belongs to no part");
  }
}

PclIcpRegistration::~PclIcpRegistration() = default;

std::size_t PclIcpRegistration::registerCloud(const std::vector<Eigen::Vector3d>& cloud_m) {
  thinCloud(cloud_m);
  // align() returns early on fewer points, leaving hasConverged() from the previous cloud.
  constexpr std::size_t kMinMatches = 3;
  if (samples_->thinned->size() < kMinMatches) return parts_.size();
  std::size_t held = 0;
  for (Part& part : parts_) {
    // ICP moves the cloud onto the part's rest points: start from the last cloud's answer.
    part.icp->setInputSource(samples_->thinned);
    part.icp->align(samples_->aligned, rigidInverse(part.world_from_rest));
    if (part.icp->hasConverged()) {
      part.world_from_rest = rigidInverse(part.icp->getFinalTransformation());
    } else {
      ++held;
    }
  }
  placePoints();
  return held;
}

void PclIcpRegistration::thinCloud(const std::vector<Eigen::Vector3d>& cloud_m) {
  std::size_t finite_count = 0;
  for (const auto& p : cloud_m) finite_count += p.allFinite() ? 1 : 0;
  // As CloudRegistration: every stride-th finite point, evenly over the image.
  const std::size_t max_points = config_.max_cloud_points;
  const std::size_t stride = std::max<std::size_t>(1, (finite_count + max_points - 1) / max_points);
  Cloud& thinned = *samples_->thinned;
  thinned.clear();
  std::size_t seen = 0;
  for (const auto& p : cloud_m) {
    if (p.allFinite() && seen++ % stride == 0) thinned.push_back(toPcl(p));
  }
}

void PclIcpRegistration::placePoints() {
  std::fill(positions_.begin(), positions_.end(), Eigen::Vector3d::Zero());
  for (const Part& part : parts_) {
    const Eigen::Affine3d world_from_rest(part.world_from_rest.cast<double>());
    for (const std::uint32_t i : part.points) positions_[i] += world_from_rest * rest_points_m_[i];
  }
  for (std::size_t i = 0; i < positions_.size(); ++i) positions_[i] /= parts_of_point_[i];
}

}  // namespace deformable_collision::bench
