#include "deformable_collision/core/query/broad_phase.h"

#include <gtest/gtest.h>

#include <vector>

namespace deformable_collision {
namespace {

using Pairs = std::vector<BroadPhase::Pair>;

BroadPhase::Box box(double x0, double x1, bool is_static = false, double y0 = 0.0,
                    double y1 = 1.0) {
  return {Eigen::AlignedBox3d(Eigen::Vector3d(x0, y0, 0.0), Eigen::Vector3d(x1, y1, 1.0)),
          is_static};
}

struct SweepCase {
  const char* name;
  std::vector<BroadPhase::Box> boxes;
  Pairs expected;
};

class BroadPhaseTest : public ::testing::TestWithParam<SweepCase> {};

TEST_P(BroadPhaseTest, PairsTheOverlappingBoxesInObjectOrder) {
  const SweepCase& c = GetParam();
  BroadPhase broad_phase;
  const Pairs& pairs =
      broad_phase.sweep(c.boxes.size(), [&](std::uint32_t object) { return c.boxes[object]; });
  EXPECT_EQ(pairs, c.expected);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BroadPhaseTest,
    ::testing::Values(
        SweepCase{"none", {}, {}}, SweepCase{"apart", {box(0, 1), box(2, 3)}, {}},
        SweepCase{"touching_faces", {box(0, 1), box(1, 2)}, {{0, 1}}},
        SweepCase{"apart_across_x", {box(0, 1), box(0, 1, false, 2, 3)}, {}},
        SweepCase{"two_static", {box(0, 1, true), box(0.5, 1.5, true)}, {}},
        SweepCase{"static_and_moving", {box(0, 1, true), box(0.5, 1.5)}, {{0, 1}}},
        // Given out of x order: the pairs still come sorted by first, then second object.
        SweepCase{"chain_out_of_order",
                  {box(4, 6), box(0, 2), box(1, 5), box(5.5, 7)},
                  {{0, 2}, {0, 3}, {1, 2}}}),
    [](const ::testing::TestParamInfo<SweepCase>& info) { return info.param.name; });

TEST(BroadPhase, KeepsItsOrderAcrossSweepsAndTakesNewObjects) {
  std::vector<BroadPhase::Box> boxes = {box(0, 1), box(3, 4), box(6, 7)};
  BroadPhase broad_phase;
  const auto box_of = [&](std::uint32_t object) { return boxes[object]; };
  EXPECT_TRUE(broad_phase.sweep(boxes.size(), box_of).empty());
  // Object 2 moves onto object 0, object 1 stays: the insertion sort restores the order.
  boxes[2] = box(0.5, 1.5);
  EXPECT_EQ(broad_phase.sweep(boxes.size(), box_of), (Pairs{{0, 2}}));
  boxes.push_back(box(3.5, 4.5));
  EXPECT_EQ(broad_phase.sweep(boxes.size(), box_of), (Pairs{{0, 2}, {1, 3}}));
}

}  // namespace
}  // namespace deformable_collision
