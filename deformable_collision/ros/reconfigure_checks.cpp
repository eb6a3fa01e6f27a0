#include "deformable_collision/ros/reconfigure_checks.h"

#include <sstream>

namespace deformable_collision {

std::string nodeReconfigureProblem(const DeformableCollisionConfig& requested, int max_level) {
  std::ostringstream problem;
  if (requested.level_auto && !(requested.cycle_budget_ms > 0.0)) {
    problem << "level_auto needs cycle_budget_ms > 0";
  } else if (!requested.level_auto && requested.level > max_level) {
    problem << "level = " << requested.level << " is beyond the deepest tree's " << max_level
            << " (-1: the finest)";
  }
  return problem.str();
}

std::string objectReconfigureProblem(const ObjectMaterialConfig& requested,
                                     const ObjectMaterialConfig& current, ObjectKind kind) {
  const bool material_changed =
      requested.stiffness != current.stiffness || requested.damping != current.damping;
  if (material_changed && kind != ObjectKind::kDynamic) {
    return "stiffness and damping are a dynamic object's; this one is " +
           std::string(toString(kind));
  }
  if (requested.contact_stiffness_n_per_m != current.contact_stiffness_n_per_m &&
      kind != ObjectKind::kTracked) {
    return "contact_stiffness_n_per_m is a tracked object's; this one is " +
           std::string(toString(kind));
  }
  return "";
}

void applyToScene(Scene& scene, const DeformableCollisionConfig& requested,
                  const DeformableCollisionConfig& current) {
  if (requested.level_auto) {
    if (!current.level_auto || requested.cycle_budget_ms != current.cycle_budget_ms)
      scene.setCycleBudget(requested.cycle_budget_ms);
  } else if (current.level_auto || requested.level != current.level) {
    scene.setLevel(requested.level);
  }
  if (requested.contact_distance_m != current.contact_distance_m)
    scene.setContactDistance(requested.contact_distance_m);
  scene.setFriction(requested.friction);
}

void applyMaterial(Scene& scene, std::size_t index, ObjectKind kind,
                   const ObjectMaterialConfig& material) {
  if (kind == ObjectKind::kDynamic) {
    scene.setMaterial(index, material.stiffness, material.damping);
  } else if (kind == ObjectKind::kTracked) {
    scene.setContactStiffness(index, material.contact_stiffness_n_per_m);
  }
}

}  // namespace deformable_collision
