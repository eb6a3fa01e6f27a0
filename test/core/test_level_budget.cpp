#include "deformable_collision/core/lod/level_budget.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"

namespace deformable_collision {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Cost profiles over levels 0..11 (ms of detection + response per cycle).
// Monotone: each level dearer than the coarser one.
const std::vector<double> kMonotone = {0.4, 0.5, 0.65, 0.8, 1.0, 1.3, 1.7, 2.2, 2.9, 3.8, 4.9, 6.4};
// As S2 once measured it (bench/results/s2.md): level 1 dearer than level 2, levels 6 to 10
// dearer than the finest.
const std::vector<double> kLikeS2 = {1.0, 2.9, 1.2, 1.5, 1.9, 2.2, 7.5, 8.0, 7.8, 8.2, 7.0, 6.0};

/// A synthetic run: cycle c at level L costs profile[L] x (the step's factor from
/// step_cycle on) x (1 + noise x u), u uniform in [-1, 1] from a fixed seed.
struct ProfileCase {
  std::string name;
  std::vector<double> profile;
  double budget_ms;
  double noise;
  int step_cycle;  ///< -1: no step.
  double step_factor;
  int expected_level;  ///< The finest level within headroom x budget, after the step if any.
  int check_from;      ///< The expected level is checked from this cycle on.
};

struct RunFigures {
  int cycles_checked = 0;  ///< From the warm-up on.
  int within_budget = 0;
  int switches = 0;
  int at_expected = 0;  ///< From check_from on.
  int expected_checked = 0;
};

constexpr int kCycles = 3000;
constexpr int kWarmUp = 200;

RunFigures simulate(const ProfileCase& c) {
  LevelBudget budget(c.budget_ms, static_cast<int>(c.profile.size()) - 1);
  std::mt19937 random(20261124);
  RunFigures figures;
  int previous = budget.level();
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    const int level = budget.level();
    const double factor = c.step_cycle >= 0 && cycle >= c.step_cycle ? c.step_factor : 1.0;
    const double u = 2.0 * double(random()) / double(std::mt19937::max()) - 1.0;
    const double cost = c.profile[level] * factor * (1.0 + c.noise * u);
    budget.record(cost);
    if (cycle >= kWarmUp) {
      ++figures.cycles_checked;
      if (cost <= c.budget_ms) ++figures.within_budget;
      if (level != previous) ++figures.switches;
    }
    if (cycle >= c.check_from) {
      ++figures.expected_checked;
      if (level == c.expected_level) ++figures.at_expected;
    }
    previous = level;
  }
  return figures;
}

void PrintTo(const ProfileCase& c, std::ostream* out) { *out << c.name; }

class LevelBudgetProfileTest : public ::testing::TestWithParam<ProfileCase> {};

TEST_P(LevelBudgetProfileTest, StaysWithinBudgetAtTheFinestFittingLevelWithoutFlicker) {
  const ProfileCase& c = GetParam();
  const RunFigures run = simulate(c);
  EXPECT_GE(run.within_budget, 0.95 * run.cycles_checked)
      << run.within_budget << " of " << run.cycles_checked << " cycles within budget";
  EXPECT_GE(run.at_expected, 0.9 * run.expected_checked)
      << run.at_expected << " of " << run.expected_checked << " cycles at level "
      << c.expected_level;
  // Each try of a finer level is one switch there and, if it does not fit, one back; tries
  // come at most once per explore period, and a step adds a few switches of its own.
  const int period = LevelBudgetTuning{}.explore_period_cycles;
  EXPECT_LE(run.switches, 2 * run.cycles_checked / period + 6) << run.switches << " switches";
}

INSTANTIATE_TEST_SUITE_P(
    LevelBudget, LevelBudgetProfileTest,
    ::testing::Values(
        // Budget 3.2: within 0.8 x 3.2 = 2.56 are levels 0 to 7; level 8 (2.9) fits but
        // without headroom.
        ProfileCase{"Monotone", kMonotone, 3.2, 0.0, -1, 1.0, 7, kWarmUp},
        ProfileCase{"MonotoneNoisy", kMonotone, 3.2, 0.15, -1, 1.0, 7, kWarmUp},
        // Budget 3.0 (half the finest): levels 0 and 2 to 5 within 2.4; level 1 fits
        // without headroom, 6 to 11 not at all.
        ProfileCase{"LikeS2", kLikeS2, 3.0, 0.0, -1, 1.0, 5, kWarmUp},
        ProfileCase{"LikeS2Noisy", kLikeS2, 3.0, 0.15, -1, 1.0, 5, kWarmUp},
        // The scene gets dearer by 1.6 at cycle 1000: level 7 (3.52) overruns, level 6
        // (2.72) fits without headroom and, being where the fall from level 7 lands (its
        // estimate was within the headroom), is kept.
        ProfileCase{"MonotoneGetsDearer", kMonotone, 3.2, 0.1, 1000, 1.6, 6, 1100},
        // The scene gets cheaper by 0.35: the finest level (2.1) is within 2.4 now, though
        // levels 6 to 10 are not; it is found when its retry comes (at most 16 explore
        // periods after the last try).
        ProfileCase{"LikeS2GetsCheaper", kLikeS2, 3.0, 0.1, 1000, 0.35, 11, 2200}),
    [](const auto& info) { return info.param.name; });

/// The cost of a try's first cycle at a finer level: within the budget of 10 ms the tests
/// below use, but without headroom. The switch's cycle is not judged for headroom, only for
/// the budget.
constexpr double kFinerSwitchCostMs = 9.5;

TEST(LevelBudget, StartsAtTheCoarsestLevelAndClimbsOneLevelEveryTwoCyclesWhileThereIsHeadroom) {
  LevelBudget budget(10.0, 5);
  EXPECT_EQ(budget.level(), 0);
  for (int level = 0; level < 5; ++level) {
    ASSERT_EQ(budget.level(), level);
    budget.record(kFinerSwitchCostMs);  // a switch's cycle: the level stays
    ASSERT_EQ(budget.level(), level);
    EXPECT_FALSE(budget.estimateMs(level));
    budget.record(1.0);
    EXPECT_EQ(budget.estimateMs(level), 1.0);
  }
  EXPECT_EQ(budget.level(), 5);
  budget.record(kFinerSwitchCostMs);
  budget.record(1.0);
  EXPECT_EQ(budget.level(), 5);
}

TEST(LevelBudget, ATryThatOverrunsOnItsSwitchCycleComesBackAtOnceAndNotBeforeItsPeriod) {
  LevelBudget budget(10.0, 3);
  budget.record(kFinerSwitchCostMs);
  budget.record(1.0);  // level 0
  ASSERT_EQ(budget.level(), 1);
  budget.record(50.0);  // level 1 overruns on its first cycle
  EXPECT_EQ(budget.level(), 0);
  ASSERT_TRUE(budget.estimateMs(1));
  EXPECT_EQ(*budget.estimateMs(1), 50.0);
  budget.record(50.0);  // the switch's cycle back at level 0: not judged
  EXPECT_EQ(budget.level(), 0);
  const int period = LevelBudgetTuning{}.explore_period_cycles;
  int cycle = 0;
  while (budget.level() == 0 && cycle < 10 * period) {
    budget.record(1.0);
    ++cycle;
  }
  // The next try goes to level 2, never run, before level 1 is tried again; being blind
  // after a try that failed, it waits two periods.
  EXPECT_EQ(budget.level(), 2);
  EXPECT_GE(cycle, 2 * period - 4);
  EXPECT_LE(cycle, 2 * period);
}

TEST(LevelBudget, BlindTriesThatFailWaitLongerEachTimeUpToTheirMostDoublings) {
  // Levels 1 to 5 each overrun on a try's first cycle; level 0 has headroom.
  LevelBudget budget(10.0, 5);
  const int period = LevelBudgetTuning{}.explore_period_cycles;
  std::vector<int> try_cycles;
  for (int cycle = 0; cycle < 20 * period; ++cycle) {
    if (budget.level() > 0) try_cycles.push_back(cycle);
    budget.record(budget.level() == 0 ? 1.0 : 50.0);
  }
  ASSERT_GE(try_cycles.size(), 4u);
  // The climb's try of level 1, then tries 2, 4, 4, ... periods apart (two cycles more
  // each: the switch back and the cycle that judges level 0 again).
  const int most_periods = 1 << LevelBudgetTuning{}.max_blind_try_doublings;
  EXPECT_EQ(try_cycles[0], 2);
  for (std::size_t i = 1; i < try_cycles.size(); ++i) {
    const int expected = std::min(1 << i, most_periods) * period;
    EXPECT_GE(try_cycles[i] - try_cycles[i - 1], expected) << i;
    EXPECT_LE(try_cycles[i] - try_cycles[i - 1], expected + 2) << i;
  }
}

TEST(LevelBudget, ALevelLeftAfterASpikeComesBackWithinAPeriodWhileBlindTriesBackOff) {
  // Level 1 fits with headroom; levels 2 and 3 overrun at every try, so blind tries wait
  // the longest. One busy cycle at level 1 leaves it; it is back a period later.
  const std::vector<double> costs = {1.0, 5.0, 20.0, 20.0};
  LevelBudget budget(10.0, 3);
  for (int cycle = 0; cycle < 600; ++cycle) budget.record(costs[budget.level()]);
  ASSERT_EQ(budget.level(), 1);
  budget.record(40.0);
  ASSERT_EQ(budget.level(), 0);
  const int period = LevelBudgetTuning{}.explore_period_cycles;
  int cycle = 0;
  while (budget.level() == 0 && cycle < 10 * period) {
    budget.record(costs[0]);
    ++cycle;
  }
  EXPECT_EQ(budget.level(), 1);
  EXPECT_LE(cycle, period + 2);
}

TEST(LevelBudget, ALevelLeftAsTooSlowIsTriedAgainOnceTheRunningLevelShowsTheSceneGotCheaper) {
  // Level 1 costs twice level 0: too slow at 12 ms against 10, fine once the scene costs
  // half as much. The running level's cost shows the change: level 1 is tried within one
  // period, not after its backoff.
  LevelBudget budget(10.0, 1);
  double scale = 1.0;
  const auto cost = [&] { return scale * (budget.level() == 0 ? 6.0 : 12.0); };
  for (int cycle = 0; cycle < 400; ++cycle) budget.record(cost());
  ASSERT_EQ(budget.level(), 0);
  scale = 0.5;
  const int period = LevelBudgetTuning{}.explore_period_cycles;
  int cycle = 0;
  while (budget.level() == 0 && cycle < 10 * period) {
    budget.record(cost());
    ++cycle;
  }
  EXPECT_EQ(budget.level(), 1);
  EXPECT_LE(cycle, period + 2);
  for (int more = 0; more < 20; ++more) budget.record(cost());
  EXPECT_EQ(budget.level(), 1);
}

TEST(LevelBudget, ATryWhoseSwitchCycleFitsIsJudgedOnItsSecondCycleForHeadroom) {
  struct Case {
    const char* name;
    double second_cycle_ms;
    int level_after;
  };
  for (const Case& c : {Case{"overruns", 12.0, 0}, Case{"fits without headroom", 9.0, 0},
                        Case{"has headroom", 7.0, 1}}) {
    LevelBudget budget(10.0, 1);
    budget.record(kFinerSwitchCostMs);
    budget.record(1.0);
    ASSERT_EQ(budget.level(), 1) << c.name;
    budget.record(kFinerSwitchCostMs);
    ASSERT_EQ(budget.level(), 1) << c.name;
    budget.record(c.second_cycle_ms);
    EXPECT_EQ(budget.level(), c.level_after) << c.name;
    EXPECT_EQ(budget.estimateMs(1), c.second_cycle_ms) << c.name;
  }
}

TEST(LevelBudget, AChosenLevelIsKeptWhileItFitsAndLeftOnceItsEstimateOverruns) {
  LevelBudget budget(10.0, 1);
  budget.record(kFinerSwitchCostMs);
  budget.record(1.0);
  budget.record(kFinerSwitchCostMs);
  budget.record(7.0);  // the try of level 1 has headroom: kept
  ASSERT_EQ(budget.level(), 1);
  for (int cycle = 0; cycle < 20; ++cycle) {
    budget.record(cycle % 2 ? 9.5 : 7.5);  // within the budget, not within the headroom
    ASSERT_EQ(budget.level(), 1) << cycle;
  }
  budget.record(30.0);  // one cycle far over: the estimate overruns at once
  EXPECT_EQ(budget.level(), 0);
  // Going coarser, the switch's cycle resolves the overlaps the coarser spheres find and
  // may cost far more than the level will: it is not judged, whatever it costs.
  budget.record(1e3);
  EXPECT_EQ(budget.level(), 0);
  EXPECT_EQ(budget.estimateMs(0), 1.0);
}

TEST(LevelBudget, WhenNothingFitsItRunsTheCheapestLevel) {
  const std::vector<double> costs = {30.0, 25.0, 12.0, 40.0};
  LevelBudget budget(10.0, 3);
  for (int cycle = 0; cycle < 500; ++cycle) budget.record(costs[budget.level()]);
  EXPECT_EQ(budget.level(), 2);
  for (int level = 0; level <= 3; ++level) EXPECT_TRUE(budget.estimateMs(level)) << level;
}

TEST(LevelBudget, WhenNothingFitsADearStretchOfFinerLevelsIsNotRunThrough) {
  const std::vector<double> costs = {30.0, 25.0, 12.0, 40.0, 50.0, 60.0};
  LevelBudget budget(10.0, 5);
  for (int cycle = 0; cycle < 500; ++cycle) budget.record(costs[budget.level()]);
  EXPECT_EQ(budget.level(), 2);
  EXPECT_TRUE(budget.estimateMs(3));  // dearer than level 2: the finer levels end there
  EXPECT_FALSE(budget.estimateMs(4));
  EXPECT_FALSE(budget.estimateMs(5));
}

TEST(LevelBudget, ANewBudgetKeepsTheEstimates) {
  LevelBudget budget(10.0, 2);
  // 4, 8 and 12 ms at levels 0, 1, 2: level 2 is tried and left, level 1 kept.
  for (int cycle = 0; cycle < 10; ++cycle) budget.record(4.0 * (budget.level() + 1));
  ASSERT_EQ(budget.level(), 1);
  budget.record(8.0);  // the switch's cycle back at level 1
  budget.setBudget(5.0);
  budget.record(8.0);  // level 1 no longer fits
  EXPECT_EQ(budget.level(), 0);
  EXPECT_EQ(budget.budgetMs(), 5.0);
}

TEST(LevelBudget, LevelsFollowTheScenesDeepestLevel) {
  LevelBudget budget(10.0, 4);
  for (int cycle = 0; cycle < 20; ++cycle) budget.record(1.0);
  ASSERT_EQ(budget.level(), 4);
  budget.setMaxLevel(2);
  EXPECT_EQ(budget.level(), 2);
  EXPECT_EQ(budget.maxLevel(), 2);
  EXPECT_FALSE(budget.estimateMs(3));
  budget.setMaxLevel(6);
  EXPECT_TRUE(budget.estimateMs(2));
  EXPECT_FALSE(budget.estimateMs(5));
  budget.record(1.0);  // the switch's cycle at level 2
  budget.record(1.0);
  EXPECT_EQ(budget.level(), 3);  // the new levels are climbed again
}

TEST(LevelBudget, RefusesABadBudgetCostOrTuning) {
  for (const double bad : {0.0, -1.0, kNaN, kInf}) {
    EXPECT_THROW(LevelBudget(bad, 3), std::invalid_argument) << bad;
    LevelBudget budget(1.0, 3);
    EXPECT_THROW(budget.setBudget(bad), std::invalid_argument) << bad;
    EXPECT_EQ(budget.budgetMs(), 1.0);
  }
  EXPECT_THROW(LevelBudget(1.0, -1), std::invalid_argument);
  LevelBudget budget(1.0, 3);
  for (const double bad : {-0.1, kNaN, kInf}) {
    EXPECT_THROW(budget.record(bad), std::invalid_argument) << bad;
  }
  EXPECT_FALSE(budget.estimateMs(0));
  EXPECT_THROW(budget.setMaxLevel(-1), std::invalid_argument);
  const auto tuned = [](auto change) {
    LevelBudgetTuning tuning;
    change(tuning);
    return tuning;
  };
  for (const LevelBudgetTuning& bad :
       {tuned([](auto& t) { t.headroom = 0.0; }), tuned([](auto& t) { t.headroom = 1.5; }),
        tuned([](auto& t) { t.rise_weight = kNaN; }), tuned([](auto& t) { t.fall_weight = 0.0; }),
        tuned([](auto& t) { t.explore_period_cycles = 0; }),
        tuned([](auto& t) { t.max_backoff_doublings = -1; }),
        tuned([](auto& t) { t.max_blind_try_doublings = 33; })}) {
    EXPECT_THROW(LevelBudget(1.0, 3, bad), std::invalid_argument);
  }
}

// The scene in budget mode: three_objects (19k points) at a few ms per cycle.

TEST(SceneCycleBudget, AGenerousBudgetClimbsToTheFinestLevelAndStatsSaySo) {
  SceneConfig config;
  config.cycle_budget_ms = 1e4;
  auto scene = makeDemoScene(DemoScene::kThreeObjects, 0, config);
  ASSERT_EQ(scene->cycleBudget(), 1e4);
  const int finest = scene->maxLevel();
  ASSERT_GT(finest, 2);
  for (int level = 0; level <= finest; ++level) {
    for (int cycle = 0; cycle < 2; ++cycle) {
      scene->cycle();
      ASSERT_EQ(scene->stats().level, level) << "one level every two cycles from level 0";
      EXPECT_TRUE(scene->stats().level_auto);
      EXPECT_EQ(scene->stats().cycle_budget_ms, 1e4);
    }
  }
  for (int cycle = 0; cycle < 5; ++cycle) {
    scene->cycle();
    EXPECT_EQ(scene->stats().level, finest);
  }
}

TEST(SceneCycleBudget, AnImpossibleBudgetSettlesOnACheapLevel) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects);
  // Detection + response by level, as LevelBudget's own tests give them: cheaper down to
  // level 2; level 3 dearer than level 2, but not clearly (by 12%, less than the 20% a
  // switch to the cheapest level needs); every finer level far dearer.
  const std::vector<double> cost_ms = {3.0, 2.0, 1.0, 1.12};
  constexpr double kFinerCostMs = 5.0;
  ASSERT_GT(scene->maxLevel(), 3);
  // A loaded machine only adds to a cycle's time: up to 10% here. Level 2's estimate then
  // stays within [1.0, 1.1] and level 3's within [1.12, 1.232], whose 80% is below 1.0, so
  // the levels below are the same whatever the draws.
  std::mt19937 random(20261124);
  std::uniform_real_distribution<double> load(1.0, 1.1);
  scene->setCycleCostSource([&](const CycleStats& cycle) {
    const bool listed = cycle.level < static_cast<int>(cost_ms.size());
    return (listed ? cost_ms[cycle.level] : kFinerCostMs) * load(random);
  });
  scene->setCycleBudget(1e-9);
  // Two cycles per level (the first pays for the switch and is not judged): level 0, then
  // each finer level never run while going finer made the cycles cheaper. Level 3 is dearer
  // than level 2, so level 4 is never tried; and level 3 stays, since level 2 is not clearly
  // cheaper (without that gap, the hysteresis, the level would go back to 2).
  std::vector<int> expected = {0, 0, 1, 1, 2, 2};
  expected.resize(3 * LevelBudgetTuning{}.explore_period_cycles, 3);
  std::vector<int> levels;
  for (std::size_t cycle = 0; cycle < expected.size(); ++cycle) {
    scene->cycle();
    levels.push_back(scene->stats().level);
  }
  EXPECT_EQ(levels, expected);
}

TEST(SceneCycleBudget, SetLevelLeavesBudgetModeAndNoBudgetKeepsThePickedLevel) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects);
  scene->setCycleBudget(1e4);
  for (int cycle = 0; cycle < 6; ++cycle) scene->cycle();
  scene->setCycleBudget(std::nullopt);
  EXPECT_FALSE(scene->cycleBudget());
  EXPECT_EQ(scene->level(), 3);  // picked after two cycles each at levels 0, 1 and 2
  scene->cycle();
  EXPECT_EQ(scene->stats().level, 3);
  EXPECT_FALSE(scene->stats().level_auto);
  EXPECT_EQ(scene->stats().cycle_budget_ms, 0.0);

  scene->setCycleBudget(1e4);  // entered again: from level 0
  scene->cycle();
  EXPECT_EQ(scene->stats().level, 0);
  scene->setLevel(2);
  EXPECT_FALSE(scene->cycleBudget());
  scene->cycle();
  EXPECT_EQ(scene->stats().level, 2);
  EXPECT_FALSE(scene->stats().level_auto);
}

TEST(SceneCycleBudget, ACostSourceGivingABadCostFailsTheCycle) {
  for (const double bad : {-1.0, kNaN, kInf}) {
    auto scene = makeDemoScene(DemoScene::kThreeObjects);
    scene->setCycleBudget(5.0);
    scene->setCycleCostSource([bad](const CycleStats&) { return bad; });
    EXPECT_THROW(scene->cycle(), std::invalid_argument) << bad;
  }
}

TEST(SceneCycleBudget, ABadBudgetIsRefusedAndChangesNothing) {
  auto scene = makeDemoScene(DemoScene::kThreeObjects);
  scene->setCycleBudget(5.0);
  for (const double bad : {0.0, -2.0, kNaN, kInf}) {
    EXPECT_THROW(scene->setCycleBudget(bad), std::invalid_argument) << bad;
    EXPECT_EQ(scene->cycleBudget(), 5.0);
    SceneConfig config;
    config.cycle_budget_ms = bad;
    try {
      Scene refused(config);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("SceneConfig.cycle_budget_ms"), std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace deformable_collision
