#include "deformable_collision/scenes/demo_scenes.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

std::vector<Eigen::Vector3d> placed(std::vector<Eigen::Vector3d> points,
                                    const Eigen::Vector3d& at) {
  for (auto& p : points) p += at;
  return points;
}

ObjectConfig softObject(const std::string& name, DeformationMode mode, int clusters,
                        double mass_kg) {
  ObjectConfig object;
  object.name = name;
  object.kind = ObjectKind::kDynamic;
  object.shape.mode = mode;
  object.shape.clusters = clusters;
  object.shape.stiffness = 0.5;
  object.shape.beta = 0.6;
  object.shape.damping = 0.1;
  object.shape.mass_kg = mass_kg;
  return object;
}

ObjectConfig fixedObject(const std::string& name, ObjectKind kind) {
  ObjectConfig object;
  object.name = name;
  object.kind = kind;
  object.shape.mode = DeformationMode::kRigid;
  return object;
}

/// A slab of points on a regular grid (static floors and walls need no randomness).
std::vector<Eigen::Vector3d> slab(const Eigen::Vector3d& half_extents, double spacing,
                                  const Eigen::Vector3d& center) {
  std::vector<Eigen::Vector3d> points;
  const auto steps = [&](double half) { return std::max(1, int(std::lround(2 * half / spacing))); };
  const int nx = steps(half_extents.x()), ny = steps(half_extents.y()),
            nz = steps(half_extents.z());
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      for (int k = 0; k <= nz; ++k) {
        const Eigen::Vector3d unit(nx ? double(i) / nx : 0.5, ny ? double(j) / ny : 0.5,
                                   nz ? double(k) / nz : 0.5);
        points.push_back(center + (2 * unit - Eigen::Vector3d::Ones()).cwiseProduct(half_extents));
      }
    }
  }
  return points;
}

void requirePoints(std::size_t points, std::size_t least, DemoScene scene) {
  if (points < least) {
    throw std::invalid_argument(std::string("scene ") + toString(scene) + " needs at least " +
                                std::to_string(least) + " points, got " + std::to_string(points));
  }
}

void buildTwoObjects(Scene& scene, std::size_t points) {
  const std::size_t each = points / 2;
  const auto a =
      scene.addObject(softObject("ball_a", DeformationMode::kQuadratic, 4, 2.0),
                      placed(sampleEllipsoid(each, {0.3, 0.25, 0.25}, 1), {-0.45, 0, 0}));
  const auto b =
      scene.addObject(softObject("ball_b", DeformationMode::kQuadratic, 4, 2.0),
                      placed(sampleEllipsoid(each, {0.3, 0.25, 0.25}, 2), {0.45, 0.05, 0}));
  for (const auto& [object, speed] : {std::pair{a, 1.0}, std::pair{b, -1.0}}) {
    std::vector<Eigen::Vector3d> velocity(scene.body(object).pointCount(),
                                          Eigen::Vector3d(speed, 0, 0));
    scene.setVelocities(object, velocity);
  }
}

void buildPile(Scene& scene, std::size_t points, int objects) {
  // 6 x 6 columns for 300 objects; more objects widen the box rather than stack higher, so
  // that they land on each other about as hard and the walls stay higher than the stack.
  const int side = std::max(6, int(std::ceil(std::sqrt(objects / 9.0))));
  const int columns = side * side;
  const std::size_t each = points / objects;
  const double half = 0.6 + 0.1 * (side - 6);
  const double corner = -0.45 - 0.09 * (side - 6);
  scene.addObject(fixedObject("floor", ObjectKind::kStatic),
                  slab({half, half, 0.01}, 0.02, {0, 0, -0.01}));
  // Walls higher than the initial stack (about 1.6 m), so nothing falls out over them.
  scene.addObject(fixedObject("wall_x_minus", ObjectKind::kStatic),
                  slab({0.01, half, 1.0}, 0.02, {-half - 0.01, 0, 1.0}));
  scene.addObject(fixedObject("wall_x_plus", ObjectKind::kStatic),
                  slab({0.01, half, 1.0}, 0.02, {half + 0.01, 0, 1.0}));
  scene.addObject(fixedObject("wall_y_minus", ObjectKind::kStatic),
                  slab({half, 0.01, 1.0}, 0.02, {0, -half - 0.01, 1.0}));
  scene.addObject(fixedObject("wall_y_plus", ObjectKind::kStatic),
                  slab({half, 0.01, 1.0}, 0.02, {0, half + 0.01, 1.0}));
  std::mt19937_64 engine(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // Each object in its own 0.18 m cell, turned every which way, and every other layer
  // shifted by a quarter cell: ellipsoids dropped upright and in line stand as towers for
  // hundreds of cycles, and a pile is what the scene is for.
  for (int i = 0; i < objects; ++i) {
    const int column = i % columns;
    const int layer = i / columns;
    const double shift = layer % 2 ? 0.045 : -0.045;
    const Eigen::Vector3d at(corner + shift + 0.18 * (column % side),
                             corner + shift + 0.18 * (column / side), 0.12 + 0.18 * layer);
    const Eigen::Vector3d radii(0.05 + 0.03 * unit(engine), 0.05 + 0.03 * unit(engine),
                                0.04 + 0.03 * unit(engine));
    const Eigen::Vector3d axis(unit(engine) - 0.5, unit(engine) - 0.5, unit(engine) - 0.5);
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(M_PI * unit(engine), axis.normalized()).toRotationMatrix();
    std::vector<Eigen::Vector3d> points = sampleEllipsoid(each, radii, 100 + i);
    for (auto& p : points) p = turn * p;
    const DeformationMode mode = i % 2 ? DeformationMode::kQuadratic : DeformationMode::kLinear;
    scene.addObject(softObject("object_" + std::to_string(i), mode, 1, 0.2),
                    placed(std::move(points), at));
  }
}

void buildThreeObjects(Scene& scene, std::size_t points) {
  // A 1 m square floor of 2 cm spacing, 2 cm thick (5202 points); the rest go to the soft
  // objects.
  const auto floor_grid = slab({0.5, 0.5, 0.01}, 0.02, {0, 0, -0.01});
  const std::size_t soft = points - std::min(points, floor_grid.size());
  scene.addObject(fixedObject("floor", ObjectKind::kStatic), floor_grid);
  scene.addObject(softObject("ball", DeformationMode::kQuadratic, 3, 1.0),
                  placed(sampleEllipsoid(soft / 2, {0.2, 0.2, 0.2}, 3), {-0.15, 0, 0.3}));
  scene.addObject(softObject("bar", DeformationMode::kLinear, 4, 1.0),
                  placed(sampleBox(soft - soft / 2, {0.4, 0.08, 0.06}, 4), {0.05, 0, 0.7}));
}

void buildGripper(Scene& scene, std::size_t points) {
  scene.addObject(fixedObject("floor", ObjectKind::kStatic),
                  slab({0.4, 0.4, 0.01}, 0.02, {0, 0, -0.01}));
  scene.addObject(softObject("fruit", DeformationMode::kQuadratic, 3, 0.3),
                  placed(sampleEllipsoid(points, {0.1, 0.1, 0.1}, 5), {0, 0, 0.105}));
  scene.addObject(fixedObject("jaw_left", ObjectKind::kKinematic),
                  slab({0.02, 0.08, 0.08}, 0.01, {0, 0, 0}));
  scene.addObject(fixedObject("jaw_right", ObjectKind::kKinematic),
                  slab({0.02, 0.08, 0.08}, 0.01, {0, 0, 0}));
  driveDemoScene(DemoScene::kGripper, scene, 0.0);
}

constexpr std::size_t kPileObjects = 300;
constexpr std::size_t kMostPileObjects = 10000;

/// The pile's soft objects: `asked`, or 300 for 0.
/// @throw std::invalid_argument for a count other than 0 for another scene, or over 10000.
std::size_t pileObjects(DemoScene scene, std::size_t asked) {
  if (asked == 0) return kPileObjects;
  if (scene != DemoScene::kPile || asked > kMostPileObjects) {
    throw std::invalid_argument(
        std::string("scene ") + toString(scene) + " cannot be built with " + std::to_string(asked) +
        " objects: only the pile's count is chosen, up to " + std::to_string(kMostPileObjects));
  }
  return asked;
}

/// A scene's soft points when none are asked for, the fewest its objects can be built from,
/// and a contact distance of about their spacing at the default count.
struct SceneDefaults {
  std::size_t point_count;
  std::size_t least_point_count;
  double contact_distance_m;
};

SceneDefaults sceneDefaults(DemoScene scene, std::size_t pile_objects) {
  switch (scene) {
    case DemoScene::kTwoObjects:
      return {16000, 20, 0.025};
    case DemoScene::kPile:
      return {131000 * pile_objects / kPileObjects, pile_objects * 10, 0.02};
    case DemoScene::kThreeObjects:
      return {19000, 60, 0.02};
    case DemoScene::kGripper:
      return {10000, 50, 0.012};
  }
  return {0, 0, 0.0};
}

}  // namespace

std::size_t defaultPointCount(DemoScene scene) {
  return sceneDefaults(scene, kPileObjects).point_count;
}

std::unique_ptr<Scene> makeDemoScene(DemoScene scene, std::size_t points, SceneConfig config,
                                     std::size_t pile_objects) {
  const std::size_t objects = pileObjects(scene, pile_objects);
  const SceneDefaults defaults = sceneDefaults(scene, objects);
  if (points == 0) points = defaults.point_count;
  requirePoints(points, defaults.least_point_count, scene);
  config.gravity_mps2 =
      scene == DemoScene::kTwoObjects ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.0, 0.0, -9.81);
  config.contact_distance_m = std::max(config.contact_distance_m, defaults.contact_distance_m);
  auto built = std::make_unique<Scene>(config);
  switch (scene) {
    case DemoScene::kTwoObjects:
      buildTwoObjects(*built, points);
      break;
    case DemoScene::kPile:
      buildPile(*built, points, int(objects));
      break;
    case DemoScene::kThreeObjects:
      buildThreeObjects(*built, points);
      break;
    case DemoScene::kGripper:
      buildGripper(*built, points);
      break;
  }
  return built;
}

std::optional<Eigen::Isometry3d> demoKinematicPose(DemoScene scene, const std::string& object,
                                                   double time_s) {
  if (scene != DemoScene::kGripper) return std::nullopt;
  double side = 0.0;
  if (object == "jaw_left") side = -1.0;
  if (object == "jaw_right") side = 1.0;
  if (side == 0.0) return std::nullopt;
  // The jaws close from 0.2 m apart to 0.12 m (on a 0.2 m fruit) over two seconds, then hold.
  const double gap = 0.2 - 0.04 * std::clamp(time_s, 0.0, 2.0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(side * (gap / 2 + 0.02), 0.0, 0.1);
  return pose;
}

void driveDemoScene(DemoScene scene, Scene& built, double time_s) {
  for (std::size_t i = 0; i < built.objectCount(); ++i) {
    if (built.objectConfig(i).kind != ObjectKind::kKinematic) continue;
    if (const auto pose = demoKinematicPose(scene, built.objectConfig(i).name, time_s)) {
      built.setPose(i, *pose);
    }
  }
}

double meanDynamicPointSpeed(const Scene& scene) {
  double speed = 0.0;
  std::size_t points = 0;
  for (std::size_t o = 0; o < scene.objectCount(); ++o) {
    if (scene.objectConfig(o).kind != ObjectKind::kDynamic) continue;
    for (const Eigen::Vector3d& v : scene.body(o).velocities()) speed += v.norm();
    points += scene.body(o).pointCount();
  }
  return points > 0 ? speed / double(points) : 0.0;
}

}  // namespace deformable_collision
