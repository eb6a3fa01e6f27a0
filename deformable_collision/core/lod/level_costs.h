#pragma once

#include <optional>
#include <vector>

namespace deformable_collision {

/// Per level of detail, what something measured at that level has cost (ms): a moving
/// average for each level on its own. Costs are not monotone in the level (docs/design.md,
/// "Level from a cycle budget"), so a level never measured has no estimate, and none is
/// inferred from another level's. The scene keeps one of its cycles' detection times
/// (Scene::detectionCosts), from which a contact query with a budget takes its level
/// (levelWithin). record() allocates nothing.
class LevelCosts {
 public:
  /// Weight of a new cost above a level's estimate, and below it. Rises count more, so that
  /// a scene that got dearer shows within a cycle or two (as in LevelBudgetTuning).
  static constexpr double kRiseWeight = 0.5;
  static constexpr double kFallWeight = 0.2;

  /// Levels 0..max_level, none measured.
  /// @throw std::invalid_argument if max_level < 0.
  explicit LevelCosts(int max_level = 0);

  /// Levels are now 0..max_level (objects came or went): the kept levels keep their
  /// estimates. Allocates only when the levels grow.
  /// @throw std::invalid_argument if max_level < 0.
  void setMaxLevel(int max_level);
  int maxLevel() const { return static_cast<int>(levels_.size()) - 1; }

  /// Takes a cost measured at `level` into its estimate (the first one is the estimate).
  /// @throw std::out_of_range if level is outside [0, maxLevel()];
  /// std::invalid_argument if cost_ms is negative or not finite.
  void record(int level, double cost_ms);

  /// The expected cost at `level`; std::nullopt if none was measured there (or level is
  /// outside [0, maxLevel()]).
  std::optional<double> estimateMs(int level) const;

  /// Why levelWithin() took its level.
  enum class Basis {
    kWithinBudget,  ///< The finest level expected within the budget.
    kCheapest,      ///< None is: the cheapest measured level (the coarsest of equals).
    kNoneMeasured,  ///< No level has an estimate: level 0, the coarsest.
  };
  struct LevelForBudget {
    int level = 0;
    Basis basis = Basis::kNoneMeasured;
    std::optional<double> estimate_ms;  ///< The level's; std::nullopt with kNoneMeasured.
  };
  /// The finest level in [0, max_level] whose estimate is within `budget_ms`; if none is,
  /// the cheapest one measured; if none is measured, level 0. Levels beyond maxLevel() have
  /// no estimate. An estimate is what the level cost, not a promise of what it will cost.
  /// @throw std::invalid_argument if budget_ms is not finite and > 0, or max_level < 0.
  LevelForBudget levelWithin(double budget_ms, int max_level) const;

 private:
  struct Estimate {
    double ms = 0.0;
    bool measured = false;
  };
  std::vector<Estimate> levels_;
};

}  // namespace deformable_collision
