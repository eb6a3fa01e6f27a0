#include "deformable_collision/core/lod/level_costs.h"

#include <gtest/gtest.h>

#include <limits>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::optional<double> kNever = std::nullopt;

using Basis = LevelCosts::Basis;

/// Costs measured once per level (kNever: not measured), then a budget's pick.
struct PickCase {
  std::string name;
  std::vector<std::optional<double>> cost_ms;
  double budget_ms;
  int max_level;
  int level;
  Basis basis;
};

void PrintTo(const PickCase& c, std::ostream* out) { *out << c.name; }

class LevelCostsPickTest : public ::testing::TestWithParam<PickCase> {};

TEST_P(LevelCostsPickTest, TakesTheFinestLevelWithinTheBudgetElseTheCheapestElseTheCoarsest) {
  const PickCase& c = GetParam();
  LevelCosts costs(static_cast<int>(c.cost_ms.size()) - 1);
  for (int level = 0; level <= costs.maxLevel(); ++level) {
    if (c.cost_ms[level]) costs.record(level, *c.cost_ms[level]);
  }
  const LevelCosts::LevelForBudget pick = costs.levelWithin(c.budget_ms, c.max_level);
  EXPECT_EQ(pick.level, c.level);
  EXPECT_EQ(pick.basis, c.basis);
  EXPECT_EQ(pick.estimate_ms, costs.estimateMs(c.level));
  EXPECT_EQ(pick.estimate_ms.has_value(), c.basis != Basis::kNoneMeasured);
}

INSTANTIATE_TEST_SUITE_P(
    LevelCosts, LevelCostsPickTest,
    ::testing::Values(
        PickCase{"Monotone", {0.2, 0.5, 0.9, 1.4}, 1.0, 3, 2, Basis::kWithinBudget},
        PickCase{"ExactlyTheBudgetFits", {0.2, 1.0, 1.4}, 1.0, 2, 1, Basis::kWithinBudget},
        // Costs are not monotone: a coarse level dearer than a finer one does not stop it.
        PickCase{"FinerLevelCheaper", {0.2, 3.0, 0.8, 2.0}, 1.0, 3, 2, Basis::kWithinBudget},
        // A level never measured is no candidate, however large the budget.
        PickCase{"NeverMeasuredLevelsAreNotGuessed",
                 {0.2, kNever, kNever},
                 100.0,
                 2,
                 0,
                 Basis::kWithinBudget},
        PickCase{"NoneFitsTheCheapest", {3.0, 2.0, 2.5, kNever}, 1.0, 3, 1, Basis::kCheapest},
        PickCase{"NoneFitsEqualCostsTheCoarsest", {3.0, 2.0, 2.0}, 1.0, 2, 1, Basis::kCheapest},
        PickCase{"NoneMeasuredLevel0", {kNever, kNever, kNever}, 1.0, 2, 0, Basis::kNoneMeasured},
        // The scene's levels now end above the costs' (max_level): deeper ones are not taken.
        PickCase{"OnlyUpToMaxLevel", {0.2, 0.5, 0.9}, 1.0, 1, 1, Basis::kWithinBudget},
        PickCase{"CheapestOnlyUpToMaxLevel", {3.0, 2.0, 0.5}, 0.1, 1, 1, Basis::kCheapest},
        // Levels the costs do not have yet (objects came since the last cycle) have no estimate.
        PickCase{"LevelsBeyondTheCostsHaveNone", {0.2, 0.5}, 1.0, 5, 1, Basis::kWithinBudget}),
    [](const auto& info) { return info.param.name; });

TEST(LevelCosts, AnEstimateFollowsRisesFasterThanFalls) {
  LevelCosts costs(2);
  EXPECT_FALSE(costs.estimateMs(1));
  costs.record(1, 1.0);
  EXPECT_EQ(costs.estimateMs(1), 1.0);  // the first cost is the estimate
  costs.record(1, 3.0);
  EXPECT_DOUBLE_EQ(*costs.estimateMs(1), 1.0 + LevelCosts::kRiseWeight * 2.0);
  const double before = *costs.estimateMs(1);
  costs.record(1, 1.0);
  EXPECT_DOUBLE_EQ(*costs.estimateMs(1), before - LevelCosts::kFallWeight * (before - 1.0));
  EXPECT_FALSE(costs.estimateMs(0));
  EXPECT_FALSE(costs.estimateMs(2));
}

TEST(LevelCosts, KeptLevelsKeepTheirEstimatesWhenTheLevelsChange) {
  LevelCosts costs(3);
  costs.record(1, 0.5);
  costs.record(3, 2.0);
  costs.setMaxLevel(1);
  EXPECT_EQ(costs.maxLevel(), 1);
  EXPECT_EQ(costs.estimateMs(1), 0.5);
  EXPECT_FALSE(costs.estimateMs(3));
  costs.setMaxLevel(4);
  EXPECT_EQ(costs.estimateMs(1), 0.5);
  EXPECT_FALSE(costs.estimateMs(3));  // dropped with its level, not back with it
}

TEST(LevelCosts, RefusesABadLevelCostOrBudgetAndChangesNothing) {
  LevelCosts costs(2);
  costs.record(0, 1.0);
  for (const int bad : {-1, 3}) EXPECT_THROW(costs.record(bad, 1.0), std::out_of_range) << bad;
  for (const double bad : {-0.1, kNaN, kInf}) {
    EXPECT_THROW(costs.record(0, bad), std::invalid_argument) << bad;
  }
  EXPECT_EQ(costs.estimateMs(0), 1.0);
  for (const double bad : {0.0, -1.0, kNaN, kInf}) {
    EXPECT_THROW(costs.levelWithin(bad, 2), std::invalid_argument) << bad;
  }
  EXPECT_THROW(costs.levelWithin(1.0, -1), std::invalid_argument);
  EXPECT_THROW(costs.setMaxLevel(-1), std::invalid_argument);
  EXPECT_EQ(costs.maxLevel(), 2);
  EXPECT_THROW(LevelCosts(-1), std::invalid_argument);
}

// The scene's detection costs: each cycle's detection time, at the level it ran.

TEST(SceneDetectionCosts, EachCycleRecordsItsDetectionAtItsLevel) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects);
  ASSERT_GT(scene->maxLevel(), 3);
  EXPECT_FALSE(scene->detectionCosts().levelWithin(1e6, scene->maxLevel()).estimate_ms);
  scene->setLevel(3);
  scene->cycle();
  const double first_ms = scene->stats().detection_ms;
  EXPECT_EQ(scene->detectionCosts().estimateMs(3), first_ms);
  scene->setLevel(1);
  scene->cycle();
  scene->cycle();
  EXPECT_TRUE(scene->detectionCosts().estimateMs(1));
  for (const int never_run : {0, 2, scene->maxLevel()}) {
    EXPECT_FALSE(scene->detectionCosts().estimateMs(never_run)) << never_run;
  }
  EXPECT_EQ(scene->detectionCosts().estimateMs(3), first_ms);
  EXPECT_EQ(scene->detectionCosts().maxLevel(), scene->maxLevel());
}

}  // namespace
}  // namespace deformable_collision
