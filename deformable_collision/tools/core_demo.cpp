// The core on a built-in scene, until the nodelet exists: three soft objects released from
// deformed states (and one rigid object falling), stepped for a fixed simulated time, with a
// report of sizes, time per step and how far each object is from its rest shape.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "deformable_collision/core/shape_matching.h"
#include "deformable_collision/core/shapes.h"

namespace dc = deformable_collision;

namespace {

struct DemoObject {
  std::string name;
  dc::ShapeMatchingBody body;
  Eigen::Vector3d gravity_mps2;
  double step_seconds = 0.0;
};

/// RMS distance of the points from their clusters' rigidly moved rest positions: zero when
/// every cluster has its rest shape.
double shapeErrorM(const dc::ShapeMatchingBody& body) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto& deformation = body.deformation(k);
    const Eigen::Matrix3d r = deformation.rotation.toRotationMatrix();
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      const Eigen::Vector3d rigid = r * cluster.rest_offsets[j] + deformation.center_of_mass;
      sum += (body.positions()[cluster.points[j]] - rigid).squaredNorm();
      ++count;
    }
  }
  return std::sqrt(sum / count);
}

std::vector<Eigen::Vector3d> transformed(const std::vector<Eigen::Vector3d>& points,
                                         const Eigen::Matrix3d& linear) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(linear * p);
  return out;
}

}  // namespace

int main() {
  const double dt_s = 0.01;
  const int steps = 300;
  std::vector<DemoObject> objects;

  dc::ShapeMatchingConfig bar;
  bar.mode = dc::DeformationMode::kQuadratic;
  bar.clusters = 4;
  bar.stiffness = 0.3;
  bar.beta = 0.6;
  bar.damping = 0.05;
  objects.push_back({"bar (quadratic, bent)",
                     dc::ShapeMatchingBody(dc::sampleBox(20000, {0.4, 0.05, 0.05}, 1), bar),
                     Eigen::Vector3d::Zero()});

  dc::ShapeMatchingConfig ball;
  ball.mode = dc::DeformationMode::kLinear;
  ball.clusters = 3;
  ball.stiffness = 0.2;
  ball.damping = 0.05;
  objects.push_back({"ball (linear, squashed)",
                     dc::ShapeMatchingBody(dc::sampleEllipsoid(10000, {0.1, 0.1, 0.1}, 2), ball),
                     Eigen::Vector3d::Zero()});

  dc::ShapeMatchingConfig box;
  box.mode = dc::DeformationMode::kRigid;
  box.stiffness = 1.0;
  box.damping = 0.0;
  objects.push_back({"box (rigid, falling)",
                     dc::ShapeMatchingBody(dc::sampleBox(5000, {0.05, 0.05, 0.05}, 3), box),
                     Eigen::Vector3d(0.0, 0.0, -9.81)});

  std::vector<Eigen::Vector3d> bent = objects[0].body.restPositions();
  for (auto& p : bent) p.z() += 2.0 * p.x() * p.x();
  objects[0].body.setPositions(bent);
  objects[1].body.setPositions(
      transformed(objects[1].body.restPositions(), Eigen::Vector3d(1.4, 1.4, 0.5).asDiagonal()));

  std::printf("deformable_collision core demo: %d steps of %.3f s\n", steps, dt_s);
  std::printf("%-26s %8s %8s %14s %12s %14s %14s\n", "object", "points", "clusters",
              "ms/step", "ns/point", "shape err 0 m", "shape err end m");
  for (auto& object : objects) {
    const double initial_error = shapeErrorM(object.body);
    const auto start = std::chrono::steady_clock::now();
    for (int s = 0; s < steps; ++s) object.body.step(dt_s, object.gravity_mps2);
    object.step_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / steps;
    std::printf("%-26s %8zu %8zu %14.3f %12.2f %14.5f %14.5f\n", object.name.c_str(),
                object.body.pointCount(), object.body.clusterCount(), 1e3 * object.step_seconds,
                1e9 * object.step_seconds / object.body.pointCount(), initial_error,
                shapeErrorM(object.body));
  }
  const auto& box_center = objects[2].body.deformation(0).center_of_mass;
  std::printf("rigid box fell %.3f m in %.2f s (free fall: %.3f m)\n", -box_center.z(),
              steps * dt_s, 0.5 * 9.81 * std::pow(steps * dt_s, 2));
  return 0;
}
