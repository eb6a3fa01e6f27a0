// The registration benchmark (issue: real depth cameras): a sponge of N model points squeezed,
// bent and twisted over F frames, seen at 30 Hz by the camera_gripper scene's virtual depth
// camera (320 x 240, 1 mm noise, dropout, jaws inside the crop as outliers). Per cloud: the
// registration's time and the model's error against the ground truth, on the side the camera
// sees and on the hidden side, in all and off the surface (along the true normal).
//
//   bench_registration [--points N] [--frames F] [--mode rigid|linear|quadratic]
//                      [--clusters K] [--iterations I] [--cloud-points C] [--model-points M]
//                      [--method ours|pcl_icp|pcl_icp_clusters|model_limit] [--static 1]
//                      [--cloud camera|truth] [--exclude-near-jaws 0|1]
//
// --method: ours is Scene::registerCloud of the sponge in a scene with the jaws, which leaves
// out the cloud's points near the jaws (--exclude-near-jaws 0 keeps them); pcl_icp is PCL's rigid
// ICP of the whole model, and pcl_icp_clusters of each of the body's K clusters alone, on the same
// thinned clouds with the same rounds and largest match distance (PclIcpRegistration);
// --model-points is ours alone, PCL matches to every rest point of a part.
// --static 1 leaves the rest model in place (no registration): the baseline a registration
// must beat. --method model_limit is no registration: each cluster's transform (by --mode)
// is the least-squares fit to the ground truth of all its points, the best the model can
// place its points. --cloud truth gives the registration the ground truth's points that the
// camera sees instead of the camera's cloud: no noise, no outliers, no holes, every seen
// point of the surface, so what error is left is not the camera's.
// The error off the surface is the part of a point's error along the true surface normal;
// the rest is a slide along the surface, which a match of surface to surface cannot see.
// Contacts: the model's points and the jaws, in a scene of their own (the sponge tracked,
// the jaws kinematic, 5 mm contact distance, the finest level), against the same scene
// given the ground truth: per jaw and frame, the coverage (the largest distance from a true
// contact to the nearest of the model's), and how often the model missed a jaw that
// touched or touched one that did not. The cycle time is that scene's cycle after the
// registration: what a node's cycle adds to it.
// Prints one line per setting: the means over the frames of the seen and hidden error (mean
// over points), the largest error over all frames, the registration time per cloud, and how
// often the model was held: clouds with too few matches (ours), or clouds times parts that
// had fewer than three matches and kept their last transform (PCL).
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/core/shape_matching/shape_matching.h"
#include "deformable_collision/scenes/camera_gripper_scene.h"
#include "pcl_icp_registration.h"

namespace {

using deformable_collision::CameraGripperConfig;
using deformable_collision::CameraGripperScene;
using deformable_collision::RegistrationConfig;
using deformable_collision::ShapeMatchingBody;
using deformable_collision::ShapeMatchingConfig;
using deformable_collision::bench::PclIcpRegistration;

using deformable_collision::JawSide;
using deformable_collision::ObjectKind;
using deformable_collision::Scene;
using deformable_collision::SceneConfig;
using deformable_collision::SceneContact;

/// The contact distance of the scenes of the sponge and the jaws.
constexpr double kContactDistanceM = 0.005;

const char* jawName(JawSide side) { return side == JawSide::kLeft ? "left_jaw" : "right_jaw"; }

struct Settings {
  std::size_t points = 20000;
  int frames = 100;
  std::string mode = "linear";
  int clusters = 6;
  std::string method = "ours";
  bool leave_in_place = false;
  bool truth_cloud = false;
  RegistrationConfig registration;
};

struct Errors {
  double seen_mean_m = 0.0, hidden_mean_m = 0.0;  ///< Mean over frames of the mean over points.
  double seen_off_surface_m = 0.0, hidden_off_surface_m = 0.0;  ///< The same, along the normal.
  double seen_max_m = 0.0, hidden_max_m = 0.0;                  ///< Largest over frames and points.
  double registration_ms = 0.0;                                 ///< Mean per cloud.
  double worst_registration_ms = 0.0;
  std::size_t held = 0;
  double cycle_ms = 0.0;                            ///< The contact scene's cycle, mean per cloud.
  double coverage_m = 0.0, worst_coverage_m = 0.0;  ///< Mean over jaw-frames both touched.
  std::size_t jaw_frames_touched = 0;    ///< Jaw-frames where the true sponge touched the jaw.
  std::size_t missed = 0, spurious = 0;  ///< Jaw-frames touched by the truth or the model alone.
};

/// The sponge and the two jaws in a scene of their own: the sponge's contacts with each jaw
/// for its points from anywhere (the ground truth, a registration).
class JawContacts {
 public:
  JawContacts(const CameraGripperScene& scene, const ShapeMatchingConfig& shape) {
    SceneConfig config;
    config.contact_distance_m = kContactDistanceM;
    scene_ = std::make_unique<Scene>(config);
    sponge_ = scene_->addObject({"sponge", ObjectKind::kTracked, shape}, scene.restModel());
    for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
      jaws_[static_cast<int>(side)] =
          scene_->addObject({jawName(side), ObjectKind::kKinematic, {}}, scene.jawPoints());
    }
  }

  /// Places the sponge's points and the jaws at `time_s` and runs one cycle; its ms.
  double update(const CameraGripperScene& scene, double time_s,
                const std::vector<Eigen::Vector3d>& sponge_m) {
    scene_->observe(sponge_, sponge_m);
    for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
      scene_->setPose(jaws_[static_cast<int>(side)], scene.jawPose(side, time_s));
    }
    const auto start = std::chrono::steady_clock::now();
    scene_->cycle();
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    for (auto& positions : contact_positions_) positions.clear();
    for (const SceneContact& c : scene_->contacts()) {
      for (int side = 0; side < 2; ++side) {
        if (c.object_a == jaws_[side] || c.object_b == jaws_[side]) {
          contact_positions_[side].push_back(c.contact.position);
        }
      }
    }
    return ms;
  }

  const std::vector<Eigen::Vector3d>& contacts(int side) const { return contact_positions_[side]; }

 private:
  std::unique_ptr<Scene> scene_;
  std::size_t sponge_ = 0;
  std::size_t jaws_[2] = {0, 0};
  std::vector<Eigen::Vector3d> contact_positions_[2];
};

/// Adds one frame's contacts of the model against the truth's to `errors`.
void compareContacts(const JawContacts& truth, const JawContacts& model, Errors& errors) {
  for (int side = 0; side < 2; ++side) {
    const auto& expected = truth.contacts(side);
    const auto& found = model.contacts(side);
    if (expected.empty() != found.empty()) ++(expected.empty() ? errors.spurious : errors.missed);
    if (expected.empty()) continue;
    ++errors.jaw_frames_touched;
    if (found.empty()) continue;
    double coverage = 0.0;
    for (const auto& e : expected) {
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto& f : found) nearest = std::min(nearest, (e - f).squaredNorm());
      coverage = std::max(coverage, std::sqrt(nearest));
    }
    errors.coverage_m += coverage;
    errors.worst_coverage_m = std::max(errors.worst_coverage_m, coverage);
  }
}

/// One way of following the sponge: what run() times and scores.
class Registrar {
 public:
  virtual ~Registrar() = default;
  /// Registers one cloud (world frame) seen from `viewpoint_m`; returns how much it held.
  virtual std::size_t registerCloud(const std::vector<Eigen::Vector3d>& cloud_m,
                                    const Eigen::Vector3d& viewpoint_m) = 0;
  /// The model's points in the world frame, in model order.
  virtual const std::vector<Eigen::Vector3d>& positions() const = 0;
  /// Places what else a registration knows of at `time_s` (the jaws), before its cloud.
  virtual void placeSurroundings(const CameraGripperScene& /*scene*/, double /*time_s*/) {}
};

/// Ours as a node runs it: Scene::registerCloud on the sponge, a tracked object of a scene
/// that also holds the jaws, posed before each cloud.
class OursRegistrar : public Registrar {
 public:
  OursRegistrar(const CameraGripperScene& scene, const ShapeMatchingConfig& shape,
                const Settings& s)
      : leave_in_place_(s.leave_in_place) {
    SceneConfig config;
    config.contact_distance_m = kContactDistanceM;
    config.registration = s.registration;
    scene_ = std::make_unique<Scene>(config);
    sponge_ = scene_->addObject({"sponge", ObjectKind::kTracked, shape}, scene.restModel());
    for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
      jaws_[static_cast<int>(side)] =
          scene_->addObject({jawName(side), ObjectKind::kKinematic, {}}, scene.jawPoints());
    }
  }
  void placeSurroundings(const CameraGripperScene& scene, double time_s) override {
    for (const JawSide side : {JawSide::kLeft, JawSide::kRight}) {
      scene_->setPose(jaws_[static_cast<int>(side)], scene.jawPose(side, time_s));
    }
  }
  std::size_t registerCloud(const std::vector<Eigen::Vector3d>& cloud_m,
                            const Eigen::Vector3d& viewpoint_m) override {
    if (leave_in_place_) return 0;
    return scene_->registerCloud(sponge_, cloud_m, viewpoint_m).held ? 1 : 0;
  }
  const std::vector<Eigen::Vector3d>& positions() const override {
    return scene_->body(sponge_).positions();
  }

 private:
  std::unique_ptr<Scene> scene_;
  std::size_t sponge_ = 0;
  std::size_t jaws_[2] = {0, 0};
  bool leave_in_place_;
};

class PclIcpRegistrar : public Registrar {
 public:
  PclIcpRegistrar(const std::vector<Eigen::Vector3d>& rest_points,
                  const std::vector<std::vector<std::uint32_t>>& parts,
                  const RegistrationConfig& config)
      : registration_(rest_points, parts, config) {}
  std::size_t registerCloud(const std::vector<Eigen::Vector3d>& cloud_m,
                            const Eigen::Vector3d& /*viewpoint_m*/) override {
    return registration_.registerCloud(cloud_m);
  }
  const std::vector<Eigen::Vector3d>& positions() const override {
    return registration_.positions();
  }

 private:
  PclIcpRegistration registration_;
};

/// Not a registration: the model's best fit to the ground truth (Settings::method model_limit).
class ModelLimitRegistrar : public Registrar {
 public:
  ModelLimitRegistrar(ShapeMatchingBody body, const CameraGripperScene& scene)
      : body_(std::move(body)), scene_(scene), positions_(body_.pointCount()) {}
  std::size_t registerCloud(const std::vector<Eigen::Vector3d>& /*cloud_m*/,
                            const Eigen::Vector3d& /*viewpoint_m*/) override;
  const std::vector<Eigen::Vector3d>& positions() const override { return positions_; }

 private:
  ShapeMatchingBody body_;
  const CameraGripperScene& scene_;
  std::vector<Eigen::Vector3d> positions_;
};

std::size_t ModelLimitRegistrar::registerCloud(const std::vector<Eigen::Vector3d>& /*cloud_m*/,
                                               const Eigen::Vector3d& /*viewpoint_m*/) {
  const auto mode = body_.config().mode;
  const int feature_count = mode == deformable_collision::DeformationMode::kQuadratic ? 9 : 3;
  std::vector<int> clusters_of_point(positions_.size(), 0);
  for (auto& p : positions_) p.setZero();
  for (std::size_t k = 0; k < body_.clusterCount(); ++k) {
    const auto& cluster = body_.cluster(k);
    // Rows [q~ 1] of the cluster's points against their true positions.
    Eigen::MatrixXd features(cluster.points.size(), feature_count + 1);
    Eigen::MatrixXd truth(cluster.points.size(), 3);
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      features.row(j).head(feature_count) =
          deformable_collision::quadraticFeatures(cluster.rest_offsets[j])
              .head(feature_count)
              .transpose();
      features(j, feature_count) = 1.0;
      truth.row(j) = scene_.groundTruth()[cluster.points[j]].transpose();
    }
    Eigen::MatrixXd transform =
        (features.transpose() * features).ldlt().solve(features.transpose() * truth);
    if (mode == deformable_collision::DeformationMode::kRigid) {
      // The rotation nearest the fit's linear part, and the translation that goes with it.
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(transform.topRows(3).transpose(),
                                            Eigen::ComputeFullU | Eigen::ComputeFullV);
      Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();
      if (rotation.determinant() < 0.0) {
        Eigen::Matrix3d flip = Eigen::Matrix3d::Identity();
        flip(2, 2) = -1.0;
        rotation = svd.matrixU() * flip * svd.matrixV().transpose();
      }
      transform.topRows(3) = rotation.transpose();
      transform.row(3) =
          (truth.colwise().mean() - features.leftCols(3).colwise().mean() * rotation.transpose());
    }
    const Eigen::MatrixXd placed = features * transform;
    for (std::size_t j = 0; j < cluster.points.size(); ++j) {
      positions_[cluster.points[j]] += placed.row(j).transpose();
      ++clusters_of_point[cluster.points[j]];
    }
  }
  for (std::size_t i = 0; i < positions_.size(); ++i) positions_[i] /= clusters_of_point[i];
  return 0;
}

[[noreturn]] void usageError(const std::string& what) {
  std::fprintf(stderr, "bench_registration: %s\n", what.c_str());
  std::exit(2);
}

Settings parse(int argc, char** argv) {
  Settings s;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--points") s.points = std::strtoul(value, nullptr, 10);
    else if (key == "--frames") s.frames = std::atoi(value);
    else if (key == "--mode") s.mode = value;
    else if (key == "--clusters") s.clusters = std::atoi(value);
    else if (key == "--iterations") s.registration.iterations = std::atoi(value);
    else if (key == "--cloud-points")
      s.registration.max_cloud_points = std::strtoul(value, nullptr, 10);
    else if (key == "--model-points")
      s.registration.max_model_points = std::strtoul(value, nullptr, 10);
    else if (key == "--method") s.method = value;
    else if (key == "--static") s.leave_in_place = std::atoi(value) != 0;
    else if (key == "--cloud") s.truth_cloud = std::string(value) == "truth";
    else if (key == "--exclude-near-jaws")
      s.registration.exclude_near_other_objects = std::atoi(value) != 0;
    else usageError("unknown option " + key);
  }
  if (s.method != "ours" && s.method != "pcl_icp" && s.method != "pcl_icp_clusters" &&
      s.method != "model_limit") {
    usageError("unknown method " + s.method + " (ours, pcl_icp, pcl_icp_clusters, model_limit)");
  }
  if (s.leave_in_place && s.method != "ours")
    usageError("--static 1 is a setting of --method ours");
  return s;
}

std::unique_ptr<Registrar> makeRegistrar(const Settings& s, const CameraGripperScene& scene) {
  const std::vector<Eigen::Vector3d> rest_points = scene.restModel();
  ShapeMatchingConfig shape;
  shape.mode = *deformable_collision::parseDeformationMode(s.mode);
  shape.clusters = s.clusters;
  if (s.method == "ours") return std::make_unique<OursRegistrar>(scene, shape, s);
  ShapeMatchingBody body(rest_points, shape);
  if (s.method == "model_limit")
    return std::make_unique<ModelLimitRegistrar>(std::move(body), scene);
  std::vector<std::vector<std::uint32_t>> parts;
  if (s.method == "pcl_icp") {
    parts.emplace_back(rest_points.size());
    for (std::uint32_t i = 0; i < rest_points.size(); ++i) parts.back()[i] = i;
  } else {
    for (std::size_t k = 0; k < body.clusterCount(); ++k) parts.push_back(body.cluster(k).points);
  }
  return std::make_unique<PclIcpRegistrar>(rest_points, parts, s.registration);
}

/// Adds one frame's errors of `positions` against the scene's ground truth to `errors`.
void score(const std::vector<Eigen::Vector3d>& positions, const CameraGripperScene& scene,
           int frames, Errors& errors) {
  double seen_sum = 0.0, hidden_sum = 0.0, seen_off_sum = 0.0, hidden_off_sum = 0.0;
  std::size_t seen = 0, hidden = 0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Eigen::Vector3d error = positions[i] - scene.groundTruth()[i];
    const double e = error.norm();
    const double off = std::abs(error.dot(scene.groundTruthNormals()[i]));
    if (scene.groundTruthVisible()[i]) {
      seen_sum += e, seen_off_sum += off, ++seen,
          errors.seen_max_m = std::max(errors.seen_max_m, e);
    } else {
      hidden_sum += e, hidden_off_sum += off, ++hidden,
          errors.hidden_max_m = std::max(errors.hidden_max_m, e);
    }
  }
  const auto mean = [frames](double sum, std::size_t count) {
    return (count ? sum / count : 0.0) / frames;
  };
  errors.seen_mean_m += mean(seen_sum, seen);
  errors.hidden_mean_m += mean(hidden_sum, hidden);
  errors.seen_off_surface_m += mean(seen_off_sum, seen);
  errors.hidden_off_surface_m += mean(hidden_off_sum, hidden);
}

Errors run(const Settings& s) {
  CameraGripperConfig scene_config;
  scene_config.sponge.points = s.points;
  constexpr double kRateHz = 30.0;
  // One squeeze-bend-release over the run: the largest deformation at its middle.
  scene_config.cycle_s = s.frames / kRateHz;
  CameraGripperScene scene(scene_config);
  const std::unique_ptr<Registrar> registrar = makeRegistrar(s, scene);
  ShapeMatchingConfig shape;
  shape.mode = *deformable_collision::parseDeformationMode(s.mode);
  shape.clusters = s.clusters;
  JawContacts truth_contacts(scene, shape), model_contacts(scene, shape);
  Errors errors;
  std::vector<Eigen::Vector3d> cloud;
  for (int frame = 1; frame <= s.frames; ++frame) {
    const double time_s = frame / kRateHz;
    scene.render(time_s);
    const Eigen::Isometry3d camera = scene.cameraPose(time_s);
    cloud.clear();
    if (s.truth_cloud) {
      for (std::size_t i = 0; i < scene.groundTruth().size(); ++i) {
        if (scene.groundTruthVisible()[i]) cloud.push_back(scene.groundTruth()[i]);
      }
    } else {
      for (const auto& p : scene.cloud()) cloud.push_back(camera * p.cast<double>());
    }
    registrar->placeSurroundings(scene, time_s);
    const auto start = std::chrono::steady_clock::now();
    errors.held += registrar->registerCloud(cloud, camera.translation());
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    errors.registration_ms += ms / s.frames;
    errors.worst_registration_ms = std::max(errors.worst_registration_ms, ms);
    score(registrar->positions(), scene, s.frames, errors);
    truth_contacts.update(scene, time_s, scene.groundTruth());
    errors.cycle_ms += model_contacts.update(scene, time_s, registrar->positions()) / s.frames;
    compareContacts(truth_contacts, model_contacts, errors);
  }
  const std::size_t both_touched = errors.jaw_frames_touched - errors.missed;
  if (both_touched > 0) errors.coverage_m /= static_cast<double>(both_touched);
  return errors;
}

}  // namespace

int main(int argc, char** argv) {
  const Settings s = parse(argc, argv);
  const Errors e = run(s);
  std::printf(
      "method %s%s points %zu frames %d mode %s clusters %d %s cloud_points %zu model_points %zu | "
      "seen mean %.2f max %.2f off surface %.2f mm | hidden mean %.2f max %.2f off surface %.2f mm "
      "| "
      "registration %.2f ms (worst %.2f) | held %zu | cycle %.2f ms | contacts: coverage %.2f mm "
      "(worst %.2f), missed %zu and spurious %zu of %zu jaw-frames touched\n",
      s.method.c_str(), s.truth_cloud ? " cloud truth" : "", s.points, s.frames, s.mode.c_str(),
      s.clusters,
      s.leave_in_place ? "static"
                       : ("iterations " + std::to_string(s.registration.iterations)).c_str(),
      s.registration.max_cloud_points, s.registration.max_model_points, 1e3 * e.seen_mean_m,
      1e3 * e.seen_max_m, 1e3 * e.seen_off_surface_m, 1e3 * e.hidden_mean_m, 1e3 * e.hidden_max_m,
      1e3 * e.hidden_off_surface_m, e.registration_ms, e.worst_registration_ms, e.held, e.cycle_ms,
      1e3 * e.coverage_m, 1e3 * e.worst_coverage_m, e.missed, e.spurious, e.jaw_frames_touched);
  return 0;
}
