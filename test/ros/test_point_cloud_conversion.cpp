#include "deformable_collision/ros/point_cloud_conversion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

namespace deformable_collision {
namespace {

using sensor_msgs::PointCloud2;
using sensor_msgs::PointField;

struct Layout {
  std::uint8_t datatype = PointField::FLOAT32;
  std::uint32_t point_step = 12;  // bytes per point; coordinates first, then padding
  std::uint32_t row_padding = 0;  // extra bytes at the end of each row
  bool big_endian = false;
};

void putCoordinate(std::uint8_t* out, std::uint8_t datatype, double value, bool big_endian) {
  std::uint8_t bytes[8];
  std::size_t size;
  if (datatype == PointField::FLOAT64) {
    size = 8;
    std::memcpy(bytes, &value, size);
  } else {
    size = 4;
    const float f = static_cast<float>(value);
    std::memcpy(bytes, &f, size);
  }
  if (big_endian) std::reverse(bytes, bytes + size);
  std::memcpy(out, bytes, size);
}

/// A cloud of `points` laid out as `layout` says, `height` rows.
PointCloud2 makeCloud(const std::vector<Eigen::Vector3d>& points, const Layout& layout,
                      std::uint32_t height = 1) {
  PointCloud2 cloud;
  const std::uint32_t size = layout.datatype == PointField::FLOAT64 ? 8 : 4;
  const char* names[3] = {"x", "y", "z"};
  for (std::uint32_t axis = 0; axis < 3; ++axis) {
    PointField field;
    field.name = names[axis];
    field.offset = axis * size;
    field.datatype = layout.datatype;
    field.count = 1;
    cloud.fields.push_back(field);
  }
  cloud.height = height;
  cloud.width = static_cast<std::uint32_t>(points.size() / height);
  cloud.point_step = layout.point_step;
  cloud.row_step = cloud.width * cloud.point_step + layout.row_padding;
  cloud.is_bigendian = layout.big_endian;
  cloud.data.assign(static_cast<std::size_t>(cloud.row_step) * height, 0xAB);
  for (std::uint32_t row = 0; row < height; ++row) {
    for (std::uint32_t column = 0; column < cloud.width; ++column) {
      const auto& p = points[row * cloud.width + column];
      std::uint8_t* out = cloud.data.data() + row * cloud.row_step + column * cloud.point_step;
      for (int axis = 0; axis < 3; ++axis) {
        putCoordinate(out + axis * size, layout.datatype, p[axis], layout.big_endian);
      }
    }
  }
  return cloud;
}

const std::vector<Eigen::Vector3d> kPoints = {
    {0.5, -1.25, 2.0}, {3.0, 4.5, -6.75}, {1e3, -0.001953125, 0.125}, {-7.5, 8.0, 9.25}};

struct GoodCase {
  const char* name;
  Layout layout;
  std::uint32_t height;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const GoodCase& c, std::ostream* os) { *os << c.name; }

class ReadGoodCloudTest : public ::testing::TestWithParam<GoodCase> {};

TEST_P(ReadGoodCloudTest, ReadsEveryPointExactly) {
  const auto& c = GetParam();
  const PointCloud2 cloud = makeCloud(kPoints, c.layout, c.height);
  std::vector<Eigen::Vector3d> points;
  const auto result = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_TRUE(result.ok()) << result.error;
  EXPECT_EQ(result.non_finite, 0u);
  ASSERT_EQ(points.size(), kPoints.size());
  for (std::size_t i = 0; i < kPoints.size(); ++i) {
    // Every value above is exact in float.
    EXPECT_EQ(points[i], kPoints[i]) << "point " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Layouts, ReadGoodCloudTest,
    ::testing::Values(GoodCase{"float32_packed", {PointField::FLOAT32, 12, 0, false}, 1},
                      GoodCase{"float32_padded_point", {PointField::FLOAT32, 16, 0, false}, 1},
                      GoodCase{"float64_packed", {PointField::FLOAT64, 24, 0, false}, 1},
                      GoodCase{"float64_padded_point", {PointField::FLOAT64, 32, 0, false}, 1},
                      GoodCase{"organized_padded_rows", {PointField::FLOAT32, 16, 8, false}, 2},
                      GoodCase{"big_endian_float32", {PointField::FLOAT32, 12, 0, true}, 1},
                      GoodCase{"big_endian_float64", {PointField::FLOAT64, 24, 0, true}, 2}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(ReadCloud, NonFinitePointsAreDroppedOrKeptAsNaN) {
  auto points_in = kPoints;
  points_in[1].y() = std::numeric_limits<double>::quiet_NaN();
  points_in[3].z() = std::numeric_limits<double>::infinity();
  const PointCloud2 cloud = makeCloud(points_in, Layout{});

  std::vector<Eigen::Vector3d> dropped;
  const auto drop = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, dropped);
  ASSERT_TRUE(drop.ok());
  EXPECT_EQ(drop.non_finite, 2u);
  ASSERT_EQ(dropped.size(), 2u);
  EXPECT_EQ(dropped[0], kPoints[0]);
  EXPECT_EQ(dropped[1], kPoints[2]);

  std::vector<Eigen::Vector3d> kept;
  const auto keep = readCloudPoints(cloud, NonFinitePoints::kKeepAsNaN, 1000, kept);
  ASSERT_TRUE(keep.ok());
  EXPECT_EQ(keep.non_finite, 2u);
  ASSERT_EQ(kept.size(), 4u);
  EXPECT_TRUE(kept[1].array().isNaN().all());
  EXPECT_TRUE(kept[3].array().isNaN().all());
  EXPECT_EQ(kept[2], kPoints[2]);
}

TEST(ReadCloud, FieldsAreFoundByNameWhereverTheyAreInAPoint) {
  // x last, y first, another field between: read through the same offsets in either byte order.
  const std::uint32_t offsets[3] = {12, 0, 4};
  for (const bool big_endian : {false, true}) {
    PointCloud2 cloud;
    const char* names[3] = {"x", "y", "z"};
    for (std::uint32_t axis = 0; axis < 3; ++axis) {
      PointField field;
      field.name = names[axis];
      field.offset = offsets[axis];
      field.datatype = PointField::FLOAT32;
      field.count = 1;
      cloud.fields.push_back(field);
    }
    cloud.height = 1;
    cloud.width = static_cast<std::uint32_t>(kPoints.size());
    cloud.point_step = 20;
    cloud.row_step = cloud.width * cloud.point_step;
    cloud.is_bigendian = big_endian;
    cloud.data.assign(cloud.row_step, 0xAB);
    for (std::size_t i = 0; i < kPoints.size(); ++i) {
      for (int axis = 0; axis < 3; ++axis) {
        putCoordinate(cloud.data.data() + i * cloud.point_step + offsets[axis], PointField::FLOAT32,
                      kPoints[i][axis], big_endian);
      }
    }
    std::vector<Eigen::Vector3d> points;
    const auto result = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
    ASSERT_TRUE(result.ok()) << result.error;
    ASSERT_EQ(points.size(), kPoints.size());
    for (std::size_t i = 0; i < kPoints.size(); ++i) {
      EXPECT_EQ(points[i], kPoints[i]) << "point " << i << (big_endian ? ", big endian" : "");
    }
  }
}

TEST(ReadCloud, EmptyCloudIsReadAsNoPoints) {
  const PointCloud2 cloud = makeCloud({}, Layout{});
  std::vector<Eigen::Vector3d> points = kPoints;
  const auto result = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_TRUE(result.ok()) << result.error;
  EXPECT_TRUE(points.empty());
}

TEST(ReadCloud, RowsOfNoPointsOverNoDataAreReadAsNoPoints) {
  // Found by fuzz_point_cloud_conversion: row pointers over empty data were formed (UB).
  PointCloud2 cloud = makeCloud({}, Layout{});
  cloud.height = 1000;
  cloud.width = 0;
  cloud.row_step = 788;
  std::vector<Eigen::Vector3d> points = kPoints;
  const auto result = readCloudPoints(cloud, NonFinitePoints::kKeepAsNaN, 1000, points);
  ASSERT_TRUE(result.ok()) << result.error;
  EXPECT_TRUE(points.empty());
}

struct BadCase {
  const char* name;
  std::function<void(PointCloud2&)> spoil;
  const char* message_part;
};

// Named in gtest output instead of as a byte dump.
void PrintTo(const BadCase& c, std::ostream* os) { *os << c.name; }

class ReadBadCloudTest : public ::testing::TestWithParam<BadCase> {};

TEST_P(ReadBadCloudTest, RejectsWithAMessageAndLeavesThePointsAlone) {
  const auto& c = GetParam();
  PointCloud2 cloud = makeCloud(kPoints, Layout{});
  c.spoil(cloud);
  const std::vector<Eigen::Vector3d> before = {{1, 2, 3}};
  std::vector<Eigen::Vector3d> points = before;
  const auto result = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error.find(c.message_part), std::string::npos) << result.error;
  EXPECT_EQ(points, before);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ReadBadCloudTest,
    ::testing::Values(
        BadCase{"missing_z", [](PointCloud2& c) { c.fields.pop_back(); }, "field 'z' is missing"},
        BadCase{"integer_field", [](PointCloud2& c) { c.fields[1].datatype = PointField::INT32; },
                "field 'y' has datatype 5"},
        BadCase{"point_step_too_small", [](PointCloud2& c) { c.point_step = 8; },
                "does not fit in point_step 8"},
        BadCase{"data_shorter_than_declared", [](PointCloud2& c) { c.data.resize(20); },
                "data has 20 bytes"},
        BadCase{"row_step_too_small", [](PointCloud2& c) { c.row_step = 4; }, "row_step 4"},
        BadCase{"too_many_points", [](PointCloud2& c) { c.width = 1001; },
                "exceeds max_points_per_object 1000"},
        BadCase{"huge_declared_size",
                [](PointCloud2& c) {
                  c.width = 0xFFFFFFFFu;
                  c.height = 0xFFFFFFFFu;
                },
                "exceeds max_points_per_object"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(WriteCloud, RoundTripsAndReusesItsBuffer) {
  PointCloud2 cloud;
  writeCloudPoints(kPoints, cloud);
  std::vector<Eigen::Vector3d> points;
  ASSERT_TRUE(readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points).ok());
  EXPECT_EQ(points, kPoints);
  const auto* buffer = cloud.data.data();
  writeCloudPoints(kPoints, cloud);
  EXPECT_EQ(cloud.data.data(), buffer);
}

TEST(WriteCloud, Float64KeepsEveryBitFarFromTheOriginWhereFloat32Rounds) {
  std::vector<Eigen::Vector3d> far;
  for (const auto& p : kPoints)
    far.push_back(p + Eigen::Vector3d(1e5 + 0.0037, -2e5 + 0.0041, 3e4 + 0.0013));
  PointCloud2 cloud;
  writeCloudPoints(far, cloud, PointField::FLOAT64);
  ASSERT_EQ(cloud.fields.size(), 3u);
  EXPECT_EQ(cloud.fields[2].datatype, PointField::FLOAT64);
  EXPECT_EQ(cloud.fields[2].offset, 16u);
  EXPECT_EQ(cloud.point_step, 24u);
  std::vector<Eigen::Vector3d> points;
  const CloudReadResult read = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_TRUE(read.ok()) << read.error;
  EXPECT_EQ(read.datatype, PointField::FLOAT64);
  EXPECT_EQ(points, far);

  writeCloudPoints(far, cloud);  // back to FLOAT32: the fields follow
  EXPECT_EQ(cloud.fields[2].datatype, PointField::FLOAT32);
  EXPECT_EQ(cloud.point_step, 12u);
  const CloudReadResult rounded = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_TRUE(rounded.ok()) << rounded.error;
  EXPECT_EQ(rounded.datatype, PointField::FLOAT32);
  double largest_error_m = 0.0;
  for (std::size_t i = 0; i < far.size(); ++i) {
    largest_error_m = std::max(largest_error_m, (points[i] - far[i]).norm());
  }
  EXPECT_GT(largest_error_m, 1e-3) << "float32 values near 2e5 m are 16 mm apart";
}

TEST(ReadCloud, ACloudWithOneFloat64CoordinateIsFloat64) {
  PointCloud2 cloud;
  writeCloudPoints(kPoints, cloud);
  cloud.fields[1].datatype = PointField::FLOAT64;
  cloud.point_step = 16;
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.data.resize(cloud.row_step);
  std::vector<Eigen::Vector3d> points;
  const CloudReadResult read = readCloudPoints(cloud, NonFinitePoints::kDrop, 1000, points);
  ASSERT_TRUE(read.ok()) << read.error;
  EXPECT_EQ(read.datatype, PointField::FLOAT64);
}

}  // namespace
}  // namespace deformable_collision
