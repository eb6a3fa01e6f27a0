// libFuzzer target: readCloudPoints on any PointCloud2 a publisher can send. The header
// fields are drawn mostly small (so the data can match them) and sometimes from the whole
// range; the rest of the input is the data.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "deformable_collision/ros/point_cloud_conversion.h"

namespace {

using deformable_collision::CloudReadResult;
using deformable_collision::NonFinitePoints;

std::uint32_t dimension(FuzzedDataProvider& input, std::uint32_t small) {
  return input.ConsumeBool() ? input.ConsumeIntegralInRange<std::uint32_t>(0, small)
                             : input.ConsumeIntegral<std::uint32_t>();
}

void check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz_point_cloud_conversion: %s\n", what);
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* bytes, std::size_t size) {
  FuzzedDataProvider input(bytes, size);
  sensor_msgs::PointCloud2 cloud;
  cloud.height = dimension(input, 4);
  cloud.width = dimension(input, 64);
  cloud.point_step = dimension(input, 48);
  cloud.row_step = dimension(input, 48 * 64);
  cloud.is_bigendian = input.ConsumeBool();
  const char* known_names[] = {"x", "y", "z", "rgb", "intensity", ""};
  const int field_count = input.ConsumeIntegralInRange(0, 6);
  for (int i = 0; i < field_count; ++i) {
    sensor_msgs::PointField field;
    field.name = input.ConsumeBool() ? known_names[input.ConsumeIntegralInRange(0, 5)]
                                     : input.ConsumeRandomLengthString(4);
    field.offset = dimension(input, 40);
    field.datatype = input.ConsumeIntegral<std::uint8_t>();
    field.count = input.ConsumeIntegralInRange<std::uint32_t>(0, 2);
    cloud.fields.push_back(field);
  }
  const NonFinitePoints policy =
      input.ConsumeBool() ? NonFinitePoints::kDrop : NonFinitePoints::kKeepAsNaN;
  const std::size_t max_points = input.ConsumeIntegralInRange<std::size_t>(1, 1u << 20);
  cloud.data = input.ConsumeRemainingBytes<std::uint8_t>();

  const Eigen::Vector3d sentinel(1.0, 2.0, 3.0);
  std::vector<Eigen::Vector3d> points{sentinel};
  const CloudReadResult result =
      deformable_collision::readCloudPoints(cloud, policy, max_points, points);
  const std::uint64_t count = static_cast<std::uint64_t>(cloud.width) * cloud.height;
  if (!result.ok()) {
    check(points.size() == 1 && points[0] == sentinel, "a refused cloud changed the points");
    return 0;
  }
  check(count <= max_points, "a cloud over max_points was read");
  check(result.non_finite <= count, "more non-finite points than points");
  if (policy == NonFinitePoints::kDrop) {
    check(points.size() == count - result.non_finite, "dropped points miscounted");
    for (const auto& p : points) check(p.allFinite(), "a non-finite point was kept");
  } else {
    check(points.size() == count, "track mode lost a point's slot");
    std::size_t unobserved = 0;
    for (const auto& p : points) {
      check(p.allFinite() || p.array().isNaN().all(), "a point is partly NaN");
      unobserved += p.allFinite() ? 0 : 1;
    }
    check(unobserved == result.non_finite, "unobserved points miscounted");
  }
  return 0;
}
