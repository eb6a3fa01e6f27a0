// The checks of a reconfiguration (reconfigure_checks.h), case by case; what a running node
// does with one is reconfigure.test's, and any sequence of them fuzz_reconfigure's.
#include "deformable_collision/ros/reconfigure_checks.h"

#include <gtest/gtest.h>

#include <string>

namespace deformable_collision {
namespace {

DeformableCollisionConfig nodeConfig(int level, bool level_auto, double budget_ms) {
  DeformableCollisionConfig config = DeformableCollisionConfig::__getDefault__();
  config.level = level;
  config.level_auto = level_auto;
  config.cycle_budget_ms = budget_ms;
  return config;
}

TEST(NodeReconfigure, NodeLevelWithinTheTreesOrAutoWithABudget) {
  struct Case {
    DeformableCollisionConfig requested;
    const char* problem;  ///< Empty: accepted.
  };
  const Case cases[] = {
      {nodeConfig(-1, false, 0.0), ""},
      {nodeConfig(0, false, 0.0), ""},
      {nodeConfig(7, false, 0.0), ""},
      {nodeConfig(8, false, 0.0), "level = 8 is beyond the deepest tree's 7"},
      {nodeConfig(-1, true, 2.0), ""},
      {nodeConfig(12, true, 2.0), ""},  // the level is not read in auto
      {nodeConfig(-1, true, 0.0), "level_auto needs cycle_budget_ms > 0"},
  };
  for (const Case& c : cases) {
    const std::string problem = nodeReconfigureProblem(c.requested, 7);
    if (std::string(c.problem).empty()) {
      EXPECT_EQ(problem, "") << c.requested.level;
    } else {
      EXPECT_NE(problem.find(c.problem), std::string::npos) << problem;
    }
  }
}

ObjectMaterialConfig material(double stiffness, double damping, double contact_stiffness) {
  ObjectMaterialConfig config = ObjectMaterialConfig::__getDefault__();
  config.stiffness = stiffness;
  config.damping = damping;
  config.contact_stiffness_n_per_m = contact_stiffness;
  return config;
}

TEST(NodeReconfigure, AnObjectChangesOnlyWhatItsKindHas) {
  const ObjectMaterialConfig current = material(0.5, 0.1, 0.0);
  struct Case {
    ObjectMaterialConfig requested;
    ObjectKind kind;
    const char* problem;
  };
  const Case cases[] = {
      {material(0.5, 0.1, 0.0), ObjectKind::kStatic, ""},
      {material(0.8, 0.2, 0.0), ObjectKind::kDynamic, ""},
      {material(0.8, 0.1, 0.0), ObjectKind::kTracked, "stiffness and damping are a dynamic"},
      {material(0.5, 0.3, 0.0), ObjectKind::kKinematic, "stiffness and damping are a dynamic"},
      {material(0.5, 0.1, 250.0), ObjectKind::kTracked, ""},
      {material(0.5, 0.1, 250.0), ObjectKind::kDynamic, "contact_stiffness_n_per_m is a tracked"},
  };
  for (const Case& c : cases) {
    const std::string problem = objectReconfigureProblem(c.requested, current, c.kind);
    if (std::string(c.problem).empty()) {
      EXPECT_EQ(problem, "") << toString(c.kind);
    } else {
      EXPECT_NE(problem.find(c.problem), std::string::npos) << problem;
    }
  }
}

}  // namespace
}  // namespace deformable_collision
