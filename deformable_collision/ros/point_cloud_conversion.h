#pragma once

#include <Eigen/Core>
#include <sensor_msgs/PointCloud2.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace deformable_collision {

/// What to do with a point whose x, y or z is NaN or infinite.
enum class NonFinitePoints {
  kDrop,       ///< Leave it out (a new rest shape).
  kKeepAsNaN,  ///< Keep its slot as NaN, so point correspondences hold (track mode).
};

struct CloudReadResult {
  std::string error;           ///< Empty when the cloud was read; otherwise what is wrong.
  std::size_t non_finite = 0;  ///< Points with a non-finite coordinate.
  /// FLOAT64 when any of x, y, z is, else FLOAT32: the precision an output of these points
  /// keeps (writeCloudPoints).
  std::uint8_t datatype = sensor_msgs::PointField::FLOAT32;
  bool ok() const { return error.empty(); }
};

/// Reads x, y, z (FLOAT32 or FLOAT64, either byte order, any point_step and row_step,
/// organized or not) of every point. The cloud is validated completely before `points`
/// is written, so on error `points` is unchanged and the message says what is wrong.
/// A cloud of more than `max_points` points is refused.
CloudReadResult readCloudPoints(const sensor_msgs::PointCloud2& cloud, NonFinitePoints policy,
                                std::size_t max_points, std::vector<Eigen::Vector3d>& points);

/// Writes `points` as an unorganized x y z cloud of `datatype`, FLOAT32 or FLOAT64 (which
/// keeps a double's every bit: FLOAT32 rounds to 8 mm at 1e5 m from the origin). The
/// message's buffers are reused when the point count is unchanged, so a steady publisher
/// allocates nothing.
void writeCloudPoints(const std::vector<Eigen::Vector3d>& points, sensor_msgs::PointCloud2& cloud,
                      std::uint8_t datatype = sensor_msgs::PointField::FLOAT32);

}  // namespace deformable_collision
