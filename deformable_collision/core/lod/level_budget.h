#pragma once

#include <cstdint>
#include <optional>
#include <vector>

namespace deformable_collision {

/// How LevelBudget trades quick reaction for a steady level. The defaults suit cycles of
/// a few ms whose cost jitters by a few tens of percent (a loaded machine).
struct LevelBudgetTuning {
  /// A finer level is taken only if its expected cost is within this fraction of the
  /// budget, while the running level is kept as long as it fits the whole budget: a level
  /// that only just fits is not worth a switch that the next noisy cycle takes back.
  double headroom = 0.8;
  /// Weight of a new cost above a level's estimate, and below it (in (0, 1]). Rises count
  /// more, so that a scene that got dearer leaves the level within a cycle or two.
  double rise_weight = 0.5;
  double fall_weight = 0.2;
  /// Least cycles between tries of a finer level (never run, or too slow when last run)
  /// while the running one has headroom; an estimate older than this is replaced by the
  /// next cost measured at its level.
  int explore_period_cycles = 50;
  /// A level found too slow at each try waits twice as long for the next, at most
  /// 2^max_backoff_doublings periods.
  int max_backoff_doublings = 4;
  /// Blind tries (see LevelBudget) wait twice as long after each try in a row that failed,
  /// at most 2^max_blind_try_doublings periods: a scene whose finer levels are all too slow
  /// pays for few tries, a scene with levels never run still finds them soon.
  int max_blind_try_doublings = 2;
};

/// Picks the level of detail of each cycle from a budget for its detection and response
/// (the paper's section 6: "depending on the time available, the hierarchies are tested
/// down to a certain layer"; docs/design.md, "Level from a cycle budget"). Costs need not
/// grow with the level, so each level keeps its own estimate, a moving average of what
/// cycles at it cost, and every level with an estimate is considered: the next level is
/// the finest one expected within headroom x budget, the running one kept while its
/// estimate fits the budget. Finer levels are tried one at a time when the running level
/// has headroom, and left at once if they do not fit with headroom: the next finer one
/// never run at once (the first cycles climb from level 0); a level left as too slow when
/// the running level's estimate has since fallen enough that it would scale to fit with
/// headroom, or when its retry is due if it was left as the running level, at most once
/// per explore_period_cycles; blind tries (levels never run, or tries that failed and are
/// due for a retry) after explore_period_cycles, doubled for each try in a row that
/// failed. The first cycle at a level after a switch pays for the switch and is left out
/// of its estimate: a level is judged from its second cycle on, so each switch stays for at
/// least two cycles, but for a try whose first cycle overran the budget (going finer, the
/// switch costs little), which is left at once. record() allocates nothing.
class LevelBudget {
 public:
  /// Starts at level 0 (the coarsest) with no estimates; its first cycle is a switch.
  /// @throw std::invalid_argument if budget_ms is not finite and > 0, max_level < 0, or a
  /// tuning value is outside its range.
  LevelBudget(double budget_ms, int max_level, const LevelBudgetTuning& tuning = {});

  /// Changes the budget from the next choice on, keeping the estimates.
  /// @throw std::invalid_argument if budget_ms is not finite and > 0.
  void setBudget(double budget_ms);
  /// Levels are now 0..max_level (objects came or went): the kept levels keep their
  /// estimates, and the running level is clamped. Allocates only when the levels grow.
  /// @throw std::invalid_argument if max_level < 0.
  void setMaxLevel(int max_level);

  /// Takes the cost (detection + response, ms) of the cycle just run at level() into that
  /// level's estimate and picks the level of the next cycle (the first cycle after a switch:
  /// neither, the level stays).
  /// @throw std::invalid_argument if cost_ms is negative or not finite.
  void record(double cost_ms);

  /// The level the next cycle runs at, in [0, maxLevel()].
  int level() const { return level_; }
  int maxLevel() const { return static_cast<int>(levels_.size()) - 1; }
  double budgetMs() const { return budget_ms_; }
  /// The expected cost at `level`, or std::nullopt if no cycle has run there (or level is
  /// outside [0, maxLevel()]).
  std::optional<double> estimateMs(int level) const;

 private:
  struct LevelCost {
    double estimate_ms = 0.0;
    std::uint64_t measured_cycle = 0;  ///< The cycle of its last cost.
    std::uint64_t retry_cycle = 0;     ///< Before this cycle, no try comes back to it.
    int failed_tries = 0;              ///< Tries in a row that left it as too slow.
    /// The level it was last left for and that level's estimate after its first judged
    /// cycle there: the scene's cost since scales this level's estimate.
    int reference_level = -1;
    double reference_ms = 0.0;
    /// It was last left as the running level, not as a try that failed.
    bool left_running = false;
    bool measured = false;
  };

  void takeCost(LevelCost& level, double cost_ms) const;
  bool fits(const LevelCost& level) const;
  bool comfortable(const LevelCost& level) const;
  /// `level` was left for the running level, whose estimate has fallen since so far that
  /// `level`'s estimate, scaled alike, is within headroom x budget.
  bool expectedComfortable(const LevelCost& level) const;
  /// Leaves level_ as too slow for levelAfterLeaving(), and notes what it was left for.
  void leave();
  /// The level after a cycle at level_ that is kept: finer if one is known to be
  /// comfortable, a try of a finer one if due, or level_.
  int levelAfterKeeping();
  /// The level after a cycle at level_ that is too slow: one expected to fit, else one
  /// never run, else the cheapest.
  int levelAfterLeaving();
  /// A finer level to try now, or -1.
  int finerLevelToTry() const;
  /// The finest level whose estimate passes `test`, or -1.
  template <typename Test>
  int finestLevel(Test test) const;
  void deferRetry(LevelCost& level) const;

  LevelBudgetTuning tuning_;
  double budget_ms_;
  std::vector<LevelCost> levels_;
  int level_ = 0;
  /// While a try of a finer level runs: the level to come back to if it does not fit; -1.
  int return_level_ = -1;
  /// The next cost is the first at level_ after a switch (or since the start).
  bool settling_ = true;
  std::uint64_t cycle_ = 0;
  std::uint64_t last_try_cycle_ = 0;
  /// Tries in a row that failed, at most max_blind_try_doublings: the blind tries' doublings.
  int failed_tries_in_a_row_ = 0;
  /// A level just left, whose reference is the next judged cycle's level and estimate; -1.
  int awaiting_reference_ = -1;
};

}  // namespace deformable_collision
