// Registration over the zoo (scenes/registration_zoo.h): five shapes unlike each other, each
// under five kinds of deformation, seen by one depth camera from one side (320 x 240, 1 mm
// noise, 5% dropout, 1% flying pixels). Every case deforms over its motion frames, then rests.
// Per case, with the same defaults for every shape: the rest model left in place and ours
// (Scene::registerCloud of a tracked object) scored per material point against the ground
// truth, on the side the camera sees and the hidden side, at the end of the motion and after
// the rest; the share of the deformation recovered at the end; the registration's time per
// cloud; after the rest, the model's surface error and the registration's estimate of it
// (SurfaceError).
//
//   bench_registration_zoo [--points N] [--mode rigid|linear|quadratic] [--clusters K]
//                          [--iterations I] [--model-points M] [--cloud-points C]
//                          [--shape NAME] [--deformation NAME] [--cloud camera|truth]
//                          [--method ours|model_limit|seen_limit] [--frames-csv PATH]
//
// --cloud truth gives the registration the ground truth's seen points instead of the camera's
// cloud: what error is left then is the method's, not the camera's. --method model_limit is
// no registration: each cluster's least-squares fit to the ground truth of all its points,
// the best the model can place them; seen_limit fits each cluster to the truth of its seen
// points only, with the correspondences known: what a perfect matching of the seen side
// leaves on the hidden side.
// Prints one CSV line per case (the columns of bench/results/registration_zoo.csv); with
// --frames-csv, writes every frame's error (shape, deformation, frame, seen_mm, hidden_mm)
// for the error-against-time plot.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/registration_zoo.h"

namespace {

using deformable_collision::kZooDeformations;
using deformable_collision::kZooShapes;
using deformable_collision::ObjectKind;
using deformable_collision::RegistrationZooCase;
using deformable_collision::RegistrationZooConfig;
using deformable_collision::Scene;
using deformable_collision::SceneConfig;
using deformable_collision::ShapeMatchingBody;
using deformable_collision::ShapeMatchingConfig;
using deformable_collision::ZooDeformation;
using deformable_collision::ZooErrors;
using deformable_collision::ZooShape;

struct Settings {
  RegistrationZooConfig zoo;
  ShapeMatchingConfig shape;
  deformable_collision::RegistrationConfig registration;
  std::string only_shape, only_deformation, frames_csv;
  bool truth_cloud = false;  ///< The seen ground truth as the cloud: no noise, holes or outliers.
  bool model_limit = false;  ///< No registration: each cluster's fit to the truth.
  bool seen_limit = false;   ///< ... of its seen points only.
};

[[noreturn]] void usageError(const std::string& what) {
  std::fprintf(stderr, "bench_registration_zoo: %s\n", what.c_str());
  std::exit(2);
}

Settings parse(int argc, char** argv) {
  Settings s;
  s.shape.clusters = 6;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--points") {
      s.zoo.points = std::strtoul(value, nullptr, 10);
    } else if (key == "--mode") {
      const auto mode = deformable_collision::parseDeformationMode(value);
      if (!mode) usageError(std::string("unknown mode ") + value);
      s.shape.mode = *mode;
    } else if (key == "--clusters") {
      s.shape.clusters = std::atoi(value);
    } else if (key == "--iterations") {
      s.registration.iterations = std::atoi(value);
    } else if (key == "--model-points") {
      s.registration.max_model_points = std::strtoul(value, nullptr, 10);
    } else if (key == "--cloud-points") {
      s.registration.max_cloud_points = std::strtoul(value, nullptr, 10);
    } else if (key == "--shape") {
      s.only_shape = value;
    } else if (key == "--deformation") {
      s.only_deformation = value;
    } else if (key == "--cloud") {
      s.truth_cloud = std::string(value) == "truth";
    } else if (key == "--method") {
      s.seen_limit = std::string(value) == "seen_limit";
      s.model_limit = s.seen_limit || std::string(value) == "model_limit";
      if (!s.model_limit && std::string(value) != "ours") usageError("unknown method");
    } else if (key == "--frames-csv") {
      s.frames_csv = value;
    } else {
      usageError("unknown option " + key);
    }
  }
  return s;
}

struct CaseResult {
  ZooErrors rest_end, ours_end, ours_rested;
  deformable_collision::SurfaceError estimate;  ///< The last cloud's (ours only).
  double ms_per_cloud = 0.0, worst_ms = 0.0;
  int held = 0;
};

/// The rigid motion that takes the rest places of the points `seen` marks (all without it)
/// nearest to their true places (Kabsch).
Eigen::Isometry3d seenRigidMotion(const std::vector<Eigen::Vector3d>& rest,
                                  const std::vector<Eigen::Vector3d>& truth,
                                  const std::vector<std::uint8_t>* seen) {
  Eigen::Index count = 0;
  for (std::size_t i = 0; i < rest.size(); ++i) count += !seen || (*seen)[i];
  Eigen::Matrix3Xd from(3, count), to(3, count);
  for (std::size_t i = 0, column = 0; i < rest.size(); ++i) {
    if (seen && !(*seen)[i]) continue;
    from.col(column) = rest[i];
    to.col(column++) = truth[i];
  }
  return Eigen::Isometry3d(Eigen::umeyama(from, to, false));
}

/// Not a registration: each cluster's least-squares transform (of the body's mode) to the
/// ground truth of its points, the points at the mean of their clusters' places. With
/// `seen`, only the points the camera sees count in full; the others keep a faint pull to
/// their rest places moved as the seen points move rigidly, which decides only what the
/// seen ones leave free.
void placeByBestFit(const ShapeMatchingBody& body, const std::vector<Eigen::Vector3d>& truth,
                    const std::vector<std::uint8_t>* seen,
                    std::vector<Eigen::Vector3d>& positions) {
  constexpr double kUnseenWeight = 1e-3;
  const bool quadratic = body.config().mode == deformable_collision::DeformationMode::kQuadratic;
  const int features = quadratic ? 9 : 3;
  const Eigen::Isometry3d moved = seenRigidMotion(body.restPositions(), truth, seen);
  std::vector<int> clusters_of_point(truth.size(), 0);
  positions.assign(truth.size(), Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < body.clusterCount(); ++k) {
    const auto& cluster = body.cluster(k);
    const auto n = static_cast<Eigen::Index>(cluster.points.size());
    Eigen::MatrixXd rows(n, features + 1), targets(n, 3);
    Eigen::VectorXd weights(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const std::uint32_t i = cluster.points[j];
      rows.row(j).head(features) = deformable_collision::quadraticFeatures(cluster.rest_offsets[j])
                                       .head(features)
                                       .transpose();
      rows(j, features) = 1.0;
      const bool counts = !seen || (*seen)[i];
      weights(j) = counts ? 1.0 : kUnseenWeight;
      targets.row(j) =
          (counts ? truth[i] : Eigen::Vector3d(moved * body.restPositions()[i])).transpose();
    }
    const Eigen::MatrixXd fit = (rows.transpose() * weights.asDiagonal() * rows)
                                    .ldlt()
                                    .solve(rows.transpose() * weights.asDiagonal() * targets);
    const Eigen::MatrixXd placed = rows * fit;
    for (Eigen::Index j = 0; j < n; ++j) {
      positions[cluster.points[j]] += placed.row(j).transpose();
      ++clusters_of_point[cluster.points[j]];
    }
  }
  for (std::size_t i = 0; i < positions.size(); ++i) positions[i] /= clusters_of_point[i];
}

/// What the registration is given this frame: the camera's cloud, or the seen ground truth.
void frameCloud(const RegistrationZooCase& zoo_case, bool truth,
                std::vector<Eigen::Vector3d>& cloud) {
  if (!truth) {
    cloud = zoo_case.cloud();
    return;
  }
  cloud.clear();
  for (std::size_t i = 0; i < zoo_case.groundTruth().size(); ++i) {
    if (zoo_case.groundTruthVisible()[i]) cloud.push_back(zoo_case.groundTruth()[i]);
  }
}

/// One case's model: a tracked object of a scene of its own, registered (ours) or placed by
/// the best fit to the truth (the bounds).
class ZooModel {
 public:
  ZooModel(const RegistrationZooCase& zoo_case, const Settings& s) : settings_(s) {
    SceneConfig config;
    config.registration = s.registration;
    scene_ = std::make_unique<Scene>(config);
    object_ = scene_->addObject({"object", ObjectKind::kTracked, s.shape}, zoo_case.restModel());
  }
  /// Places the model for this frame; the ms its registration took (0 for the bounds).
  double place(const RegistrationZooCase& zoo_case, const std::vector<Eigen::Vector3d>& cloud) {
    if (settings_.model_limit) {
      placeByBestFit(scene_->body(object_), zoo_case.groundTruth(),
                     settings_.seen_limit ? &zoo_case.groundTruthVisible() : nullptr, best_fit_);
      return 0.0;
    }
    const auto start = std::chrono::steady_clock::now();
    const auto report = scene_->registerCloud(object_, cloud, zoo_case.cameraPose().translation());
    held_ += report.held;
    if (!report.held) estimate_ = report.surface_error;
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
  }
  const std::vector<Eigen::Vector3d>& positions() const {
    return settings_.model_limit ? best_fit_ : scene_->body(object_).positions();
  }
  int held() const { return held_; }
  const deformable_collision::SurfaceError& estimate() const { return estimate_; }

 private:
  const Settings& settings_;
  std::unique_ptr<Scene> scene_;
  std::size_t object_ = 0;
  std::vector<Eigen::Vector3d> best_fit_;
  int held_ = 0;
  deformable_collision::SurfaceError estimate_;
};

CaseResult runCase(RegistrationZooCase& zoo_case, const Settings& s, std::FILE* frames) {
  ZooModel model(zoo_case, s);
  CaseResult r;
  std::vector<Eigen::Vector3d> cloud;
  for (int frame = 0; frame < zoo_case.frames(); ++frame) {
    zoo_case.render(frame);
    frameCloud(zoo_case, s.truth_cloud, cloud);
    const double ms = model.place(zoo_case, cloud);
    r.ms_per_cloud += ms / zoo_case.frames();
    r.worst_ms = std::max(r.worst_ms, ms);
    r.ours_rested = zoo_case.score(model.positions());
    if (frame == s.zoo.motion_frames - 1) {
      r.ours_end = r.ours_rested;
      r.rest_end = zoo_case.score(zoo_case.restModel());
    }
    if (frames) {
      std::fprintf(frames, "%s,%s,%d,%.4f,%.4f\n", zooShapeName(zoo_case.shape()),
                   zooDeformationName(zoo_case.deformation()), frame, 1e3 * r.ours_rested.seen_m,
                   1e3 * r.ours_rested.hidden_m);
    }
  }
  r.held = model.held();
  r.estimate = model.estimate();
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const Settings s = parse(argc, argv);
  std::FILE* frames = nullptr;
  if (!s.frames_csv.empty()) {
    frames = std::fopen(s.frames_csv.c_str(), "w");
    if (!frames) usageError("cannot write " + s.frames_csv);
    std::fprintf(frames, "shape,deformation,frame,seen_mm,hidden_mm\n");
  }
  std::printf(
      "shape,deformation,rest_seen_mm,rest_hidden_mm,end_seen_mm,end_hidden_mm,"
      "end_seen_off_mm,end_hidden_off_mm,rested_seen_mm,rested_hidden_mm,recovered_seen,"
      "recovered_hidden,ms_per_cloud,worst_ms,held,rested_seen_off_mm,rested_hidden_off_mm,"
      "estimate_seen_mm,estimate_hidden_mm\n");
  for (const ZooShape shape : kZooShapes) {
    if (!s.only_shape.empty() && s.only_shape != zooShapeName(shape)) continue;
    for (const ZooDeformation deformation : kZooDeformations) {
      if (!s.only_deformation.empty() && s.only_deformation != zooDeformationName(deformation))
        continue;
      RegistrationZooCase zoo_case(shape, deformation, s.zoo);
      const CaseResult r = runCase(zoo_case, s, frames);
      std::printf(
          "%s,%s,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.3f,%.2f,%.2f,%d,%.2f,%.2f,%.2f,%."
          "2f\n",
          zooShapeName(shape), zooDeformationName(deformation), 1e3 * r.rest_end.seen_m,
          1e3 * r.rest_end.hidden_m, 1e3 * r.ours_end.seen_m, 1e3 * r.ours_end.hidden_m,
          1e3 * r.ours_end.seen_off_surface_m, 1e3 * r.ours_end.hidden_off_surface_m,
          1e3 * r.ours_rested.seen_m, 1e3 * r.ours_rested.hidden_m,
          1.0 - r.ours_rested.seen_m / r.rest_end.seen_m,
          1.0 - r.ours_rested.hidden_m / r.rest_end.hidden_m, r.ms_per_cloud, r.worst_ms, r.held,
          1e3 * r.ours_rested.seen_off_surface_m, 1e3 * r.ours_rested.hidden_off_surface_m,
          1e3 * r.estimate.seen_m, 1e3 * r.estimate.hidden_m);
      std::fflush(stdout);
    }
  }
  if (frames) std::fclose(frames);
  return 0;
}
