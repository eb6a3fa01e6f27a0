#pragma once
// What the Scene tests share: the floor they stand objects on, the dropped box, and
// measures of a scene's motion.

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <limits>
#include <memory>
#include <vector>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace test {

using Points = std::vector<Eigen::Vector3d>;

/// A 0.8 m square floor, two layers 2 cm apart, 2 cm spacing, top at z = 0.
inline Points floorPoints() {
  Points floor;
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) {
      for (int k = 0; k < 2; ++k) floor.emplace_back(0.02 * i, 0.02 * j, -0.02 * k);
    }
  }
  return floor;
}

/// A scene as these tests use it: `config` with a 2 cm contact distance and `level`, and
/// floorPoints() as a static floor.
inline std::unique_ptr<Scene> sceneOnFloor(int level, SceneConfig config = {}) {
  config.contact_distance_m = 0.02;
  config.level = level;
  auto scene = std::make_unique<Scene>(config);
  ObjectConfig floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kStatic;
  scene->addObject(floor, floorPoints());
  return scene;
}

inline double lowestZ(const ShapeMatchingBody& body) {
  double z = std::numeric_limits<double>::infinity();
  for (const auto& p : body.positions()) z = std::min(z, p.z());
  return z;
}

inline Eigen::Vector3d meanPosition(const ShapeMatchingBody& body) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : body.positions()) sum += p;
  return sum / static_cast<double>(body.positions().size());
}

inline double fastestPoint(const Scene& scene) {
  double speed = 0.0;
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    for (const auto& v : scene.body(o).velocities()) speed = std::max(speed, v.norm());
  }
  return speed;
}

inline bool allFinite(const Scene& scene) {
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    for (const auto& p : scene.body(o).positions()) {
      if (!p.allFinite()) return false;
    }
    for (const auto& v : scene.body(o).velocities()) {
      if (!v.allFinite()) return false;
    }
  }
  return true;
}

/// The dropped box: rigid, 10 cm, 2000 points, 0.2 m above the floor.
inline ObjectConfig droppedBoxConfig() {
  ObjectConfig box;
  box.name = "box";
  box.shape.mode = DeformationMode::kRigid;
  box.shape.stiffness = 1.0;
  return box;
}

inline Points droppedBoxPoints() {
  Points points = sampleBox(2000, {0.1, 0.1, 0.1}, 3);
  for (auto& p : points) p.z() += 0.2;
  return points;
}

inline std::size_t addDroppedBox(Scene& scene) {
  return scene.addObject(droppedBoxConfig(), droppedBoxPoints());
}

}  // namespace test
}  // namespace deformable_collision
