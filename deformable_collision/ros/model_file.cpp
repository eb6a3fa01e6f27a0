#include "deformable_collision/ros/model_file.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl_conversions/pcl_conversions.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <sys/stat.h>

#include "deformable_collision/ros/point_cloud_conversion.h"

namespace deformable_collision {
namespace {

std::invalid_argument modelFileError(const std::string& path, const std::string& what) {
  return std::invalid_argument("model file '" + path + "': " + what);
}

std::string lowerCaseExtension(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string extension = path.substr(dot);
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

}  // namespace

std::vector<Eigen::Vector3d> readModelFile(const std::string& path) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) throw modelFileError(path, "no such file");
  if (!S_ISREG(status.st_mode)) throw modelFileError(path, "not a regular file");
  const std::string extension = lowerCaseExtension(path);
  pcl::PCLPointCloud2 cloud;
  int code;
  if (extension == ".ply") {
    code = pcl::io::loadPLYFile(path, cloud);
  } else if (extension == ".pcd") {
    code = pcl::io::loadPCDFile(path, cloud);
  } else {
    throw modelFileError(path, "the extension must be .ply or .pcd");
  }
  if (code < 0) throw modelFileError(path, "PCL could not read it as " + extension.substr(1));
  // The same bytes as a ROS message, so that one reader checks and converts every layout.
  sensor_msgs::PointCloud2 message;
  pcl_conversions::moveFromPCL(cloud, message);
  std::vector<Eigen::Vector3d> points;
  const CloudReadResult read = readCloudPoints(message, NonFinitePoints::kDrop,
                                               std::numeric_limits<std::size_t>::max(), points);
  if (!read.ok()) throw modelFileError(path, read.error);
  if (points.empty()) throw modelFileError(path, "has no point with finite x, y and z");
  return points;
}

void writeModelFile(const std::string& path, const std::vector<Eigen::Vector3d>& points) {
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) throw modelFileError(path, "a point to write is not finite");
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw modelFileError(path, "cannot be opened for writing");
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  for (const Eigen::Vector3d& p : points) {
    for (int axis = 0; axis < 3; ++axis) {
      const float value = static_cast<float>(p[axis]);
      std::uint32_t bits;
      std::memcpy(&bits, &value, sizeof bits);
      const char bytes[4] = {static_cast<char>(bits & 0xFF), static_cast<char>((bits >> 8) & 0xFF),
                             static_cast<char>((bits >> 16) & 0xFF), static_cast<char>(bits >> 24)};
      out.write(bytes, sizeof bytes);
    }
  }
  out.close();
  if (!out) throw modelFileError(path, "writing failed");
}

}  // namespace deformable_collision
