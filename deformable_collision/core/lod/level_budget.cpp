#include "deformable_collision/core/lod/level_budget.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace deformable_collision {
namespace {

void checkBudget(double budget_ms) {
  if (!(budget_ms > 0.0) || !std::isfinite(budget_ms)) {
    std::ostringstream message;
    message << "cycle budget " << budget_ms << " ms must be finite and > 0";
    throw std::invalid_argument(message.str());
  }
}

void checkMaxLevel(int max_level) {
  if (max_level < 0) {
    throw std::invalid_argument("max_level " + std::to_string(max_level) + " must be >= 0");
  }
}

void checkTuning(const LevelBudgetTuning& tuning) {
  const auto inUnitInterval = [](double x) { return x > 0.0 && x <= 1.0; };
  if (!inUnitInterval(tuning.headroom) || !inUnitInterval(tuning.rise_weight) ||
      !inUnitInterval(tuning.fall_weight)) {
    std::ostringstream message;
    message << "LevelBudgetTuning: headroom " << tuning.headroom << ", rise_weight "
            << tuning.rise_weight << " and fall_weight " << tuning.fall_weight
            << " must be in (0, 1]";
    throw std::invalid_argument(message.str());
  }
  const auto inDoublingRange = [](int doublings) { return doublings >= 0 && doublings <= 32; };
  if (tuning.explore_period_cycles < 1 || !inDoublingRange(tuning.max_backoff_doublings) ||
      !inDoublingRange(tuning.max_blind_try_doublings)) {
    throw std::invalid_argument(
        "LevelBudgetTuning: explore_period_cycles " + std::to_string(tuning.explore_period_cycles) +
        " must be >= 1, max_backoff_doublings " + std::to_string(tuning.max_backoff_doublings) +
        " and max_blind_try_doublings " + std::to_string(tuning.max_blind_try_doublings) +
        " in [0, 32]");
  }
}

}  // namespace

LevelBudget::LevelBudget(double budget_ms, int max_level, const LevelBudgetTuning& tuning)
    : tuning_(tuning), budget_ms_(budget_ms) {
  checkBudget(budget_ms);
  checkMaxLevel(max_level);
  checkTuning(tuning);
  levels_.resize(static_cast<std::size_t>(max_level) + 1);
}

void LevelBudget::setBudget(double budget_ms) {
  checkBudget(budget_ms);
  budget_ms_ = budget_ms;
}

void LevelBudget::setMaxLevel(int max_level) {
  checkMaxLevel(max_level);
  levels_.resize(static_cast<std::size_t>(max_level) + 1);
  if (awaiting_reference_ > max_level) awaiting_reference_ = -1;
  if (level_ > max_level) {
    level_ = max_level;
    return_level_ = -1;
    settling_ = true;
  }
}

std::optional<double> LevelBudget::estimateMs(int level) const {
  if (level < 0 || level > maxLevel() || !levels_[level].measured) return std::nullopt;
  return levels_[level].estimate_ms;
}

void LevelBudget::record(double cost_ms) {
  if (!(cost_ms >= 0.0) || !std::isfinite(cost_ms)) {
    std::ostringstream message;
    message << "cycle cost " << cost_ms << " ms must be finite and >= 0";
    throw std::invalid_argument(message.str());
  }
  ++cycle_;
  if (settling_) {
    // The first cycle at a level pays for the switch (the response resolves the overlaps the
    // other level left); the level's own cost shows from the next cycle on.
    settling_ = false;
    if (return_level_ >= 0 && cost_ms > budget_ms_) {
      // Going finer leaves fewer overlaps than it finds, so a try's switch cycle costs about
      // what its next ones do: one that overran already would not show the headroom a try
      // needs on its second cycle, which would overrun too.
      takeCost(levels_[level_], cost_ms);
      leave();
      settling_ = true;
    }
    return;
  }
  LevelCost& ran = levels_[level_];
  takeCost(ran, cost_ms);
  if (awaiting_reference_ >= 0) {
    levels_[awaiting_reference_].reference_level = level_;
    levels_[awaiting_reference_].reference_ms = ran.estimate_ms;
    awaiting_reference_ = -1;
  }
  // A try of a finer level must show headroom to stay; a level already chosen stays while
  // it fits: the gap between the two is the hysteresis.
  const bool keep = return_level_ >= 0 ? comfortable(ran) : fits(ran);
  const int previous = level_;
  if (keep) {
    level_ = levelAfterKeeping();
  } else {
    leave();
  }
  settling_ = level_ != previous;
}

void LevelBudget::leave() {
  const int left = level_;
  const bool was_try = return_level_ >= 0;
  level_ = levelAfterLeaving();
  LevelCost& cost = levels_[left];
  cost.left_running = !was_try;
  // The level it was left for is the reference once its next cycle is judged: its estimate
  // may be from cycles long ago.
  cost.reference_level = -1;
  awaiting_reference_ = level_ != left ? left : -1;
}

void LevelBudget::takeCost(LevelCost& level, double cost_ms) const {
  const bool stale = !level.measured ||
                     cycle_ - level.measured_cycle > std::uint64_t(tuning_.explore_period_cycles);
  if (stale) {
    level.estimate_ms = cost_ms;
  } else {
    const double weight = cost_ms > level.estimate_ms ? tuning_.rise_weight : tuning_.fall_weight;
    level.estimate_ms += weight * (cost_ms - level.estimate_ms);
  }
  level.measured = true;
  level.measured_cycle = cycle_;
}

bool LevelBudget::fits(const LevelCost& level) const {
  return level.measured && level.estimate_ms <= budget_ms_;
}

bool LevelBudget::comfortable(const LevelCost& level) const {
  return level.measured && level.estimate_ms <= tuning_.headroom * budget_ms_;
}

bool LevelBudget::expectedComfortable(const LevelCost& level) const {
  if (!level.measured || level.reference_level != level_ || !(level.reference_ms > 0.0)) {
    return false;
  }
  const double scale = levels_[level_].estimate_ms / level.reference_ms;
  return level.estimate_ms * scale <= tuning_.headroom * budget_ms_;
}

template <typename Test>
int LevelBudget::finestLevel(Test test) const {
  for (int level = maxLevel(); level >= 0; --level) {
    if (test(levels_[level])) return level;
  }
  return -1;
}

int LevelBudget::levelAfterKeeping() {
  LevelCost& ran = levels_[level_];
  ran.failed_tries = 0;
  if (return_level_ >= 0) failed_tries_in_a_row_ = 0;
  return_level_ = -1;
  const int finer = finestLevel([this](const LevelCost& l) { return comfortable(l); });
  if (finer > level_) return finer;
  if (!comfortable(ran)) return level_;
  const int tried = finerLevelToTry();
  if (tried < 0) return level_;
  return_level_ = level_;
  last_try_cycle_ = cycle_;
  return tried;
}

int LevelBudget::finerLevelToTry() const {
  // The first cycles climb from level 0, a level every two cycles, while each has headroom.
  if (level_ < maxLevel() && !levels_[level_ + 1].measured) return level_ + 1;
  const std::uint64_t period = std::uint64_t(tuning_.explore_period_cycles);
  if (cycle_ < last_try_cycle_ + period) return -1;
  // Blind tries (of a level never run, or of one whose try failed and whose retry is due)
  // wait longer after each try in a row that failed; a level that the running one's cost
  // says got cheap enough is tried at once.
  const bool blind_try_due = cycle_ >= last_try_cycle_ + (period << failed_tries_in_a_row_);
  // Coarse to fine: a coarser level is likelier to fit; levels never run before retries,
  // which would otherwise take every blind try from the finer levels. A level that ran
  // until it overran (a busy spell of the host, or the scene got dearer for a while) is
  // no blind try: it comes back when its own retry is due.
  int retry = -1;
  for (int level = level_ + 1; level <= maxLevel(); ++level) {
    const LevelCost& cost = levels_[level];
    const bool retry_due = cost.measured && cycle_ >= cost.retry_cycle;
    if (expectedComfortable(cost) || (cost.left_running && retry_due) ||
        (blind_try_due && !cost.measured)) {
      return level;
    }
    if (blind_try_due && retry < 0 && retry_due) retry = level;
  }
  return retry;
}

int LevelBudget::levelAfterLeaving() {
  deferRetry(levels_[level_]);
  if (return_level_ >= 0) {
    failed_tries_in_a_row_ = std::min(failed_tries_in_a_row_ + 1, tuning_.max_blind_try_doublings);
    const int back = return_level_;
    return_level_ = -1;
    return back;
  }
  int next = finestLevel([this](const LevelCost& l) { return comfortable(l); });
  if (next < 0) next = finestLevel([this](const LevelCost& l) { return fits(l); });
  if (next >= 0) return next;
  // Nothing known fits: a level never run may, the coarser ones first; the next finer one
  // only while going finer has made the cycles cheaper (this level is the cheapest known),
  // so that a dear stretch of levels is not run through one overrun after another.
  for (int level = level_ - 1; level >= 0; --level) {
    if (!levels_[level].measured) return level;
  }
  int cheapest = level_;
  for (int level = 0; level <= maxLevel(); ++level) {
    if (levels_[level].measured && levels_[level].estimate_ms < levels_[cheapest].estimate_ms) {
      cheapest = level;
    }
  }
  if (cheapest == level_ && level_ < maxLevel() && !levels_[level_ + 1].measured) {
    return level_ + 1;
  }
  // The cheapest level, if clearly cheaper than this one: levels of about the same cost
  // would otherwise take turns with the noise of each cycle.
  const double running_ms = levels_[level_].estimate_ms;
  return levels_[cheapest].estimate_ms < tuning_.headroom * running_ms ? cheapest : level_;
}

void LevelBudget::deferRetry(LevelCost& level) const {
  const int doublings = std::min(level.failed_tries, tuning_.max_backoff_doublings);
  level.retry_cycle = cycle_ + (std::uint64_t(tuning_.explore_period_cycles) << doublings);
  level.failed_tries = std::min(level.failed_tries + 1, tuning_.max_backoff_doublings);
}

}  // namespace deformable_collision
