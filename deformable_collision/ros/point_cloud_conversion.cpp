#include "deformable_collision/ros/point_cloud_conversion.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>

namespace deformable_collision {
namespace {

struct CoordinateField {
  std::uint32_t offset = 0;
  std::uint8_t datatype = 0;
};

std::uint32_t byteSize(std::uint8_t datatype) {
  return datatype == sensor_msgs::PointField::FLOAT64 ? 8 : 4;
}

double readCoordinate(const std::uint8_t* bytes, std::uint8_t datatype, bool swap) {
  std::uint8_t buffer[8];
  const std::uint32_t size = byteSize(datatype);
  std::memcpy(buffer, bytes, size);
  if (swap) std::reverse(buffer, buffer + size);
  if (datatype == sensor_msgs::PointField::FLOAT64) {
    double value;
    std::memcpy(&value, buffer, sizeof value);
    return value;
  }
  float value;
  std::memcpy(&value, buffer, sizeof value);
  return value;
}

bool hostIsBigEndian() {
  const std::uint16_t probe = 1;
  std::uint8_t first;
  std::memcpy(&first, &probe, 1);
  return first == 0;
}

/// Where x, y and z are in a point; an empty string, or what is wrong with the fields.
std::string findCoordinateFields(const sensor_msgs::PointCloud2& cloud,
                                 CoordinateField (&fields)[3]) {
  std::ostringstream error;
  const char* names[3] = {"x", "y", "z"};
  for (int axis = 0; axis < 3; ++axis) {
    const auto found =
        std::find_if(cloud.fields.begin(), cloud.fields.end(),
                     [&](const sensor_msgs::PointField& f) { return f.name == names[axis]; });
    if (found == cloud.fields.end()) {
      error << "field '" << names[axis] << "' is missing";
      return error.str();
    }
    if (found->datatype != sensor_msgs::PointField::FLOAT32 &&
        found->datatype != sensor_msgs::PointField::FLOAT64) {
      error << "field '" << names[axis] << "' has datatype " << int(found->datatype)
            << ", expected FLOAT32 (7) or FLOAT64 (8)";
      return error.str();
    }
    if (static_cast<std::uint64_t>(found->offset) + byteSize(found->datatype) > cloud.point_step) {
      error << "field '" << names[axis] << "' at offset " << found->offset
            << " does not fit in point_step " << cloud.point_step;
      return error.str();
    }
    fields[axis] = {found->offset, found->datatype};
  }
  return "";
}

/// An empty string if the header's size fits max_points and its rows fit the data, checked
/// before a byte is read, so that a huge or lying header costs nothing.
std::string checkCloudSize(const sensor_msgs::PointCloud2& cloud, std::size_t max_points) {
  std::ostringstream error;
  const std::uint64_t count = static_cast<std::uint64_t>(cloud.width) * cloud.height;
  if (count > max_points) {
    error << "cloud of " << count << " points exceeds max_points_per_object " << max_points;
    return error.str();
  }
  const std::uint64_t row_bytes = static_cast<std::uint64_t>(cloud.width) * cloud.point_step;
  if (count > 0 && cloud.row_step < row_bytes) {
    error << "row_step " << cloud.row_step << " is shorter than width " << cloud.width
          << " x point_step " << cloud.point_step;
    return error.str();
  }
  const std::uint64_t needed =
      count == 0 ? 0 : static_cast<std::uint64_t>(cloud.height - 1) * cloud.row_step + row_bytes;
  if (cloud.data.size() < needed) {
    error << "data has " << cloud.data.size() << " bytes, the header declares " << needed;
    return error.str();
  }
  return "";
}

/// Reads every point of a cloud checked by checkCloudSize with `read_point` (bytes of one
/// point to its x, y, z), counting the non-finite ones.
template <typename ReadPoint>
void readCheckedPoints(const sensor_msgs::PointCloud2& cloud, ReadPoint read_point,
                       NonFinitePoints policy, std::vector<Eigen::Vector3d>& points,
                       CloudReadResult& result) {
  points.reserve(static_cast<std::size_t>(cloud.width) * cloud.height);
  for (std::uint32_t row = 0; row < cloud.height; ++row) {
    const std::uint8_t* row_start =
        cloud.data.data() + static_cast<std::size_t>(row) * cloud.row_step;
    for (std::uint32_t column = 0; column < cloud.width; ++column) {
      const std::size_t offset = static_cast<std::size_t>(column) * cloud.point_step;
      Eigen::Vector3d p = read_point(row_start + offset);
      if (!p.allFinite()) {
        ++result.non_finite;
        if (policy == NonFinitePoints::kDrop) continue;
        p.setConstant(std::numeric_limits<double>::quiet_NaN());
      }
      points.push_back(p);
    }
  }
}

/// Reads a cloud checked by checkCloudSize. What cameras and PCL send, FLOAT32 x, y, z in the
/// host's byte order, is read without deciding datatype and byte order per coordinate: that
/// decision was most of the time spent on a cloud.
void readCheckedPoints(const sensor_msgs::PointCloud2& cloud, const CoordinateField (&fields)[3],
                       NonFinitePoints policy, std::vector<Eigen::Vector3d>& points,
                       CloudReadResult& result) {
  const bool swap = static_cast<bool>(cloud.is_bigendian) != hostIsBigEndian();
  const bool host_floats = !swap && std::all_of(fields, fields + 3, [](const CoordinateField& f) {
    return f.datatype == sensor_msgs::PointField::FLOAT32;
  });
  if (host_floats) {
    const std::uint32_t x = fields[0].offset, y = fields[1].offset, z = fields[2].offset;
    readCheckedPoints(
        cloud,
        [x, y, z](const std::uint8_t* point) {
          float xyz[3];
          std::memcpy(&xyz[0], point + x, sizeof(float));
          std::memcpy(&xyz[1], point + y, sizeof(float));
          std::memcpy(&xyz[2], point + z, sizeof(float));
          return Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
        },
        policy, points, result);
    return;
  }
  readCheckedPoints(
      cloud,
      [&fields, swap](const std::uint8_t* point) {
        Eigen::Vector3d p;
        for (int axis = 0; axis < 3; ++axis) {
          p[axis] = readCoordinate(point + fields[axis].offset, fields[axis].datatype, swap);
        }
        return p;
      },
      policy, points, result);
}

}  // namespace

CloudReadResult readCloudPoints(const sensor_msgs::PointCloud2& cloud, NonFinitePoints policy,
                                std::size_t max_points, std::vector<Eigen::Vector3d>& points) {
  CloudReadResult result;
  CoordinateField fields[3];
  result.error = findCoordinateFields(cloud, fields);
  if (result.error.empty()) result.error = checkCloudSize(cloud, max_points);
  if (!result.ok()) return result;
  for (const CoordinateField& field : fields) {
    if (field.datatype == sensor_msgs::PointField::FLOAT64) result.datatype = field.datatype;
  }
  points.clear();
  // Rows of no points may still be many, over no data at all.
  if (static_cast<std::uint64_t>(cloud.width) * cloud.height == 0) return result;
  readCheckedPoints(cloud, fields, policy, points, result);
  return result;
}

void writeCloudPoints(const std::vector<Eigen::Vector3d>& points, sensor_msgs::PointCloud2& cloud,
                      std::uint8_t datatype) {
  if (datatype != sensor_msgs::PointField::FLOAT64) datatype = sensor_msgs::PointField::FLOAT32;
  const std::uint32_t size = byteSize(datatype);
  if (cloud.fields.size() != 3 || cloud.fields[0].datatype != datatype) {
    cloud.fields.resize(3);
    const char* names[3] = {"x", "y", "z"};
    for (std::uint32_t axis = 0; axis < 3; ++axis) {
      cloud.fields[axis].name = names[axis];
      cloud.fields[axis].offset = axis * size;
      cloud.fields[axis].datatype = datatype;
      cloud.fields[axis].count = 1;
    }
  }
  cloud.height = 1;
  cloud.width = static_cast<std::uint32_t>(points.size());
  cloud.point_step = 3 * size;
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.is_bigendian = hostIsBigEndian();
  cloud.is_dense = true;
  cloud.data.resize(cloud.row_step);
  std::uint8_t* out = cloud.data.data();
  for (const auto& p : points) {
    if (datatype == sensor_msgs::PointField::FLOAT64) {
      std::memcpy(out, p.data(), cloud.point_step);
    } else {
      const float xyz[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()),
                            static_cast<float>(p.z())};
      std::memcpy(out, xyz, cloud.point_step);
    }
    out += cloud.point_step;
  }
}

}  // namespace deformable_collision
