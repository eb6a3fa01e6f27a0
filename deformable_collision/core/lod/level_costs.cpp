#include "deformable_collision/core/lod/level_costs.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace deformable_collision {
namespace {

void checkMaxLevel(int max_level) {
  if (max_level < 0) {
    throw std::invalid_argument("max_level " + std::to_string(max_level) + " must be >= 0");
  }
}

}  // namespace

LevelCosts::LevelCosts(int max_level) { setMaxLevel(max_level); }

void LevelCosts::setMaxLevel(int max_level) {
  checkMaxLevel(max_level);
  levels_.resize(static_cast<std::size_t>(max_level) + 1);
}

void LevelCosts::record(int level, double cost_ms) {
  if (level < 0 || level > maxLevel()) {
    throw std::out_of_range("level " + std::to_string(level) + " is outside [0, " +
                            std::to_string(maxLevel()) + "]");
  }
  if (!(cost_ms >= 0.0) || !std::isfinite(cost_ms)) {
    std::ostringstream message;
    message << "cost " << cost_ms << " ms at level " << level << " must be finite and >= 0";
    throw std::invalid_argument(message.str());
  }
  Estimate& estimate = levels_[level];
  if (!estimate.measured) {
    estimate.ms = cost_ms;
    estimate.measured = true;
    return;
  }
  const double weight = cost_ms > estimate.ms ? kRiseWeight : kFallWeight;
  estimate.ms += weight * (cost_ms - estimate.ms);
}

std::optional<double> LevelCosts::estimateMs(int level) const {
  if (level < 0 || level > maxLevel() || !levels_[level].measured) return std::nullopt;
  return levels_[level].ms;
}

LevelCosts::LevelForBudget LevelCosts::levelWithin(double budget_ms, int max_level) const {
  if (!(budget_ms > 0.0) || !std::isfinite(budget_ms)) {
    std::ostringstream message;
    message << "budget " << budget_ms << " ms must be finite and > 0";
    throw std::invalid_argument(message.str());
  }
  checkMaxLevel(max_level);
  const int last = std::min(max_level, maxLevel());
  for (int level = last; level >= 0; --level) {
    const Estimate& estimate = levels_[level];
    if (estimate.measured && estimate.ms <= budget_ms) {
      return {level, Basis::kWithinBudget, estimate.ms};
    }
  }
  LevelForBudget cheapest;  // level 0, none measured, until a measured level comes
  for (int level = 0; level <= last; ++level) {
    const Estimate& estimate = levels_[level];
    if (estimate.measured && (!cheapest.estimate_ms || estimate.ms < *cheapest.estimate_ms)) {
      cheapest = {level, Basis::kCheapest, estimate.ms};
    }
  }
  return cheapest;
}

}  // namespace deformable_collision
