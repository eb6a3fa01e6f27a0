#include "deformable_collision/scenes/zoo_shapes.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>

#include "deformable_collision/scenes/deforming_sponge.h"

namespace deformable_collision {
namespace {

/// Uniform in [0, 1) from the top 53 bits, identical on every standard library.
double unit(std::mt19937_64& engine) { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }

/// A direction uniform on the unit sphere (rejection from the cube).
Eigen::Vector3d direction(std::mt19937_64& engine) {
  for (;;) {
    const Eigen::Vector3d u(2 * unit(engine) - 1, 2 * unit(engine) - 1, 2 * unit(engine) - 1);
    const double length = u.norm();
    if (length <= 1.0 && length > 1e-3) return u / length;
  }
}

/// A unit vector perpendicular to `axis` (unit).
Eigen::Vector3d perpendicular(const Eigen::Vector3d& axis) {
  const Eigen::Vector3d other =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return axis.cross(other).normalized();
}

struct Sample {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};

/// A solid whose surface can be drawn uniformly and whose inside can be told.
class Primitive {
 public:
  virtual ~Primitive() = default;
  virtual double area() const = 0;
  virtual Sample sample(std::mt19937_64& engine) const = 0;
  /// Negative inside, positive outside (a signed distance or a function of the same sign).
  virtual double inside(const Eigen::Vector3d& p) const = 0;
};

class Ellipsoid : public Primitive {
 public:
  Ellipsoid(const Eigen::Vector3d& centre, const Eigen::Vector3d& radii)
      : centre_(centre), radii_(radii) {}
  double area() const override {
    // Knud Thomsen's formula: within about 1%.
    constexpr double p = 1.6075;
    const double a = std::pow(radii_.x(), p), b = std::pow(radii_.y(), p),
                 c = std::pow(radii_.z(), p);
    return 4 * M_PI * std::pow((a * b + a * c + b * c) / 3.0, 1.0 / p);
  }
  Sample sample(std::mt19937_64& engine) const override {
    // The sphere's uniform directions, kept in proportion to the area they map to.
    const Eigen::Vector3d r = radii_;
    const double largest = std::max({r.y() * r.z(), r.x() * r.z(), r.x() * r.y()});
    for (;;) {
      const Eigen::Vector3d u = direction(engine);
      const Eigen::Vector3d stretch(r.y() * r.z() * u.x(), r.x() * r.z() * u.y(),
                                    r.x() * r.y() * u.z());
      if (unit(engine) * largest > stretch.norm()) continue;
      return {centre_ + u.cwiseProduct(r), u.cwiseQuotient(r).normalized()};
    }
  }
  double inside(const Eigen::Vector3d& p) const override {
    return ((p - centre_).cwiseQuotient(radii_).norm() - 1.0) * radii_.minCoeff();
  }

 private:
  Eigen::Vector3d centre_, radii_;
};

class Capsule : public Primitive {
 public:
  Capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius)
      : a_(a), b_(b), radius_(radius) {}
  double area() const override {
    return 2 * M_PI * radius_ * (b_ - a_).norm() + 4 * M_PI * radius_ * radius_;
  }
  Sample sample(std::mt19937_64& engine) const override {
    const double length = (b_ - a_).norm();
    const Eigen::Vector3d axis = (b_ - a_) / length;
    const double side = 2 * M_PI * radius_ * length;
    if (unit(engine) * area() < side) {
      const Eigen::Vector3d u = perpendicular(axis), v = axis.cross(u);
      const double angle = 2 * M_PI * unit(engine);
      const Eigen::Vector3d normal = std::cos(angle) * u + std::sin(angle) * v;
      return {a_ + unit(engine) * length * axis + radius_ * normal, normal};
    }
    // A cap: a sphere's direction turned to the end's outer half.
    const bool at_b = unit(engine) < 0.5;
    const Eigen::Vector3d outward = at_b ? axis : Eigen::Vector3d(-axis);
    Eigen::Vector3d u = direction(engine);
    if (u.dot(outward) < 0.0) u -= 2 * u.dot(outward) * outward;
    return {(at_b ? b_ : a_) + radius_ * u, u};
  }
  double inside(const Eigen::Vector3d& p) const override {
    const Eigen::Vector3d ab = b_ - a_;
    const double t = std::clamp((p - a_).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (p - (a_ + t * ab)).norm() - radius_;
  }

 private:
  Eigen::Vector3d a_, b_;
  double radius_;
};

class Box : public Primitive {
 public:
  explicit Box(const Eigen::Vector3d& half) : half_(half) {}
  double area() const override {
    return 8 * (half_.x() * half_.y() + half_.x() * half_.z() + half_.y() * half_.z());
  }
  Sample sample(std::mt19937_64& engine) const override {
    const double faces[3] = {half_.y() * half_.z(), half_.x() * half_.z(), half_.x() * half_.y()};
    double pick = unit(engine) * (faces[0] + faces[1] + faces[2]);
    int axis = 0;
    while (axis < 2 && pick >= faces[axis]) pick -= faces[axis++];
    Eigen::Vector3d p(2 * unit(engine) - 1, 2 * unit(engine) - 1, 2 * unit(engine) - 1);
    const double sign = unit(engine) < 0.5 ? -1.0 : 1.0;
    p[axis] = sign;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    normal[axis] = sign;
    return {p.cwiseProduct(half_), normal};
  }
  double inside(const Eigen::Vector3d& p) const override {
    return (p.cwiseAbs() - half_).maxCoeff();
  }

 private:
  Eigen::Vector3d half_;
};

using Primitives = std::vector<std::unique_ptr<Primitive>>;

/// `count` samples of the union of `parts`: each part drawn by its area, a sample inside
/// another part left out (so joints are concave creases, not buried faces).
ZooSurface sampleUnion(const Primitives& parts, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  double total_area = 0.0;
  for (const auto& part : parts) total_area += part->area();
  ZooSurface s;
  std::size_t drawn = 0;
  while (s.points.size() < count) {
    double pick = unit(engine) * total_area;
    std::size_t k = 0;
    while (k + 1 < parts.size() && pick >= parts[k]->area()) pick -= parts[k++]->area();
    const Sample sample = parts[k]->sample(engine);
    ++drawn;
    bool buried = false;
    for (std::size_t other = 0; other < parts.size() && !buried; ++other) {
      buried = other != k && parts[other]->inside(sample.point) < 0.0;
    }
    if (buried) continue;
    s.points.push_back(sample.point);
    s.normals.push_back(sample.normal);
  }
  // The union's area is the parts' times the share of samples kept.
  s.spacing_m = std::sqrt(total_area / static_cast<double>(drawn));
  return s;
}

/// A banana: capsules along an arc 90 degrees long, thickest in the middle.
Primitives banana() {
  constexpr int kSegments = 10;
  constexpr double kArcRadiusM = 0.14;
  Primitives parts;
  for (int i = 0; i < kSegments; ++i) {
    const auto at = [](double s) {
      const double angle = (s - 0.5) * 0.5 * M_PI;
      return Eigen::Vector3d(kArcRadiusM * std::sin(angle), 0.0,
                             kArcRadiusM * (1.0 - std::cos(angle)));
    };
    const double s0 = static_cast<double>(i) / kSegments, s1 = (i + 1.0) / kSegments;
    const double middle = 0.5 * (s0 + s1);
    const double radius = 0.011 + 0.007 * std::sin(M_PI * middle);
    parts.push_back(std::make_unique<Capsule>(at(s0), at(s1), radius));
  }
  return parts;
}

/// A toy figure: a body, a head, two arms out to the sides and two legs.
Primitives toy() {
  Primitives parts;
  parts.push_back(
      std::make_unique<Ellipsoid>(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.035, 0.028, 0.05)));
  parts.push_back(
      std::make_unique<Ellipsoid>(Eigen::Vector3d(0, 0, 0.075), Eigen::Vector3d(0.03, 0.03, 0.03)));
  for (const double side : {-1.0, 1.0}) {
    parts.push_back(std::make_unique<Capsule>(Eigen::Vector3d(side * 0.03, 0, 0.025),
                                              Eigen::Vector3d(side * 0.095, 0, 0.05), 0.013));
    parts.push_back(std::make_unique<Capsule>(Eigen::Vector3d(side * 0.018, 0, -0.035),
                                              Eigen::Vector3d(side * 0.025, 0, -0.11), 0.016));
  }
  return parts;
}

ZooSurface sponge(std::size_t count, std::uint64_t seed) {
  DeformingSpongeConfig config;
  config.points = count;
  config.seed = seed;
  const DeformingSponge model(config);
  return {model.restPoints(), model.restNormals(), model.sampleSpacing()};
}

ZooSurface primitives(ZooShape shape, std::size_t count, std::uint64_t seed) {
  Primitives parts;
  switch (shape) {
    case ZooShape::kFruit:
      parts.push_back(std::make_unique<Ellipsoid>(Eigen::Vector3d::Zero(),
                                                  Eigen::Vector3d(0.045, 0.038, 0.04)));
      break;
    case ZooShape::kBanana:
      parts = banana();
      break;
    case ZooShape::kPlate:
      parts.push_back(std::make_unique<Box>(Eigen::Vector3d(0.1, 0.07, 0.004)));
      break;
    default:
      parts = toy();
      break;
  }
  return sampleUnion(parts, count, seed);
}

}  // namespace

const char* zooShapeName(ZooShape shape) {
  switch (shape) {
    case ZooShape::kSponge:
      return "sponge";
    case ZooShape::kFruit:
      return "fruit";
    case ZooShape::kBanana:
      return "banana";
    case ZooShape::kPlate:
      return "plate";
    case ZooShape::kToy:
      return "toy";
  }
  return "?";
}

ZooSurface zooShapeSurface(ZooShape shape, std::size_t count, std::uint64_t seed) {
  if (count < 100) throw std::invalid_argument("zooShapeSurface: count must be >= 100");
  ZooSurface s = shape == ZooShape::kSponge ? sponge(count, seed) : primitives(shape, count, seed);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : s.points) mean += p;
  mean /= static_cast<double>(s.points.size());
  for (auto& p : s.points) p -= mean;
  return s;
}

}  // namespace deformable_collision
