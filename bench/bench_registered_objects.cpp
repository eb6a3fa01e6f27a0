// Registered objects and the cycle: N zoo objects (scenes/registration_zoo.h; the five shapes
// in turn, each under the combined deformation, 0.5 m apart) on a static floor, each
// registered every frame to its own depth camera's cloud. Two ways on the same clouds, each
// timed on this one thread:
// - cycle: Scene::registerCloud of every object, then Scene::cycle(): the registrations in
//   the cycle's time;
// - reader: RegistrationFitter::fit of every object (the node's reader thread's work,
//   reported apart), then, as the node's cycle, Scene::observeRegistered of every fit,
//   Scene::cycle() and Scene::pointsNearObject of every object for the next fits.
//
//   bench_registered_objects [--objects N[,N...]] [--points P] [--frames F]
//
// Prints one CSV line per object count and way: objects, way, the cycle's registration work
// per frame (take_ms_mean: the registrations, or the fits taken over and the points near each
// object gathered), the whole cycle's time (cycle_ms_mean, cycle_ms_max), the reader's per
// frame (reader_ms_mean), held clouds, and final_positions_equal (the two ways' objects at
// the last frame, bit for bit).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/scenes/registration_zoo.h"

namespace {

using deformable_collision::ObjectConfig;
using deformable_collision::ObjectKind;
using deformable_collision::RegistrationFitter;
using deformable_collision::RegistrationReport;
using deformable_collision::RegistrationZooCase;
using deformable_collision::RegistrationZooConfig;
using deformable_collision::Scene;
using deformable_collision::SceneConfig;
using deformable_collision::TrackedFit;
using deformable_collision::ZooDeformation;
using deformable_collision::bench::Clock;
using deformable_collision::bench::millisecondsSince;
using Points = std::vector<Eigen::Vector3d>;

constexpr double kSpacingM = 0.5;

struct Settings {
  std::vector<int> objects{1, 2, 5, 10};
  std::size_t points = 8000;
  int frames = 50;
};

[[noreturn]] void usageError(const std::string& what) {
  std::fprintf(stderr, "bench_registered_objects: %s\n", what.c_str());
  std::exit(2);
}

Settings parse(int argc, char** argv) {
  Settings s;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--objects") {
      s.objects.clear();
      std::istringstream list(value);
      for (std::string item; std::getline(list, item, ',');) s.objects.push_back(std::stoi(item));
    } else if (key == "--points") {
      s.points = std::stoul(value);
    } else if (key == "--frames") {
      s.frames = std::stoi(value);
    } else {
      usageError("unknown option " + key);
    }
  }
  if (s.objects.empty() || s.frames < 1) usageError("no objects or frames");
  return s;
}

/// Every object's clouds and camera positions, frame by frame, moved to its place.
struct ObjectClouds {
  Points rest;
  std::vector<Points> clouds;
  std::vector<Eigen::Vector3d> viewpoints;
};

std::vector<ObjectClouds> renderObjects(int count, const Settings& s) {
  RegistrationZooConfig config;
  config.points = s.points;
  config.motion_frames = std::max(1, s.frames - config.rest_frames);
  std::vector<ObjectClouds> objects(count);
  for (int k = 0; k < count; ++k) {
    const auto shape =
        deformable_collision::kZooShapes[k % deformable_collision::kZooShapes.size()];
    RegistrationZooCase zoo_case(shape, ZooDeformation::kCombined, config);
    const Eigen::Vector3d offset(kSpacingM * k, 0.0, 0.0);
    for (const auto& p : zoo_case.restModel()) objects[k].rest.push_back(p + offset);
    for (int frame = 0; frame < s.frames; ++frame) {
      zoo_case.render(std::min(frame, zoo_case.frames() - 1));
      Points cloud = zoo_case.cloud();
      for (auto& p : cloud) p += offset;
      objects[k].clouds.push_back(std::move(cloud));
      objects[k].viewpoints.push_back(zoo_case.cameraPose().translation() + offset);
    }
  }
  return objects;
}

/// A 1 cm floor grid under all the objects, touching the lowest.
Points floorUnder(const std::vector<ObjectClouds>& objects) {
  double bottom = 0.0;
  for (const auto& o : objects) {
    for (const auto& p : o.rest) bottom = std::min(bottom, p.z());
  }
  Points floor;
  const int columns = static_cast<int>((kSpacingM * (objects.size() - 1) + 0.6) / 0.01);
  for (int i = 0; i <= columns; ++i) {
    for (int j = -30; j <= 30; ++j) floor.emplace_back(-0.3 + 0.01 * i, 0.01 * j, bottom - 0.003);
  }
  return floor;
}

std::unique_ptr<Scene> makeScene(const std::vector<ObjectClouds>& objects, const Points& floor) {
  auto scene = std::make_unique<Scene>(SceneConfig{});
  scene->addObject({"floor", ObjectKind::kStatic, {}}, floor);
  for (std::size_t k = 0; k < objects.size(); ++k) {
    ObjectConfig object{"object_" + std::to_string(k), ObjectKind::kTracked, {}};
    object.shape.clusters = 6;
    scene->addObject(object, objects[k].rest);
  }
  return scene;
}

struct WayFigures {
  double take_sum_ms = 0.0, cycle_sum_ms = 0.0, cycle_max_ms = 0.0, reader_sum_ms = 0.0;
  int held = 0;
  void addCycle(double ms) {
    cycle_sum_ms += ms;
    cycle_max_ms = std::max(cycle_max_ms, ms);
  }
};

WayFigures onTheCycle(Scene& scene, const std::vector<ObjectClouds>& objects, int frames) {
  WayFigures figures;
  for (int frame = 0; frame < frames; ++frame) {
    const auto start = Clock::now();
    for (std::size_t k = 0; k < objects.size(); ++k) {
      figures.held +=
          scene.registerCloud(k + 1, objects[k].clouds[frame], objects[k].viewpoints[frame]).held;
    }
    figures.take_sum_ms += millisecondsSince(start);
    scene.cycle();
    figures.addCycle(millisecondsSince(start));
  }
  return figures;
}

WayFigures onTheReader(Scene& scene, const std::vector<ObjectClouds>& objects, int frames) {
  WayFigures figures;
  std::vector<RegistrationFitter> fitters;
  std::vector<Points> near(objects.size()), read(objects.size());
  std::vector<TrackedFit> fits(objects.size());
  std::vector<RegistrationReport> reports(objects.size());
  for (std::size_t k = 0; k < objects.size(); ++k) {
    fitters.push_back(scene.registrationFitter(k + 1));
    scene.pointsNearObject(k + 1, near[k]);
  }
  for (int frame = 0; frame < frames; ++frame) {
    const auto reader_start = Clock::now();
    for (std::size_t k = 0; k < objects.size(); ++k) {
      fitters[k].setPointsNearObject(near[k]);
      read[k] = objects[k].clouds[frame];
      reports[k] = fitters[k].fit(read[k], objects[k].viewpoints[frame], fits[k]);
      figures.held += reports[k].held;
    }
    figures.reader_sum_ms += millisecondsSince(reader_start);
    const auto start = Clock::now();
    for (std::size_t k = 0; k < objects.size(); ++k) {
      if (!reports[k].held)
        scene.observeRegistered(k + 1, read[k], fits[k], reports[k].surface_error);
    }
    const double taken_ms = millisecondsSince(start);
    scene.cycle();
    const auto gather_start = Clock::now();
    for (std::size_t k = 0; k < objects.size(); ++k) scene.pointsNearObject(k + 1, near[k]);
    figures.take_sum_ms += taken_ms + millisecondsSince(gather_start);
    figures.addCycle(millisecondsSince(start));
  }
  return figures;
}

void printWay(int objects, const char* way, const WayFigures& figures, int frames, bool equal) {
  std::printf("%d,%s,%.4f,%.4f,%.4f,%.4f,%d,%d\n", objects, way, figures.take_sum_ms / frames,
              figures.cycle_sum_ms / frames, figures.cycle_max_ms, figures.reader_sum_ms / frames,
              figures.held, equal ? 1 : 0);
}

}  // namespace

int main(int argc, char** argv) {
  const Settings s = parse(argc, argv);
  std::printf(
      "objects,way,take_ms_mean,cycle_ms_mean,cycle_ms_max,reader_ms_mean,held,"
      "final_positions_equal\n");
  for (const int count : s.objects) {
    const auto objects = renderObjects(count, s);
    const Points floor = floorUnder(objects);
    auto cycle_scene = makeScene(objects, floor);
    auto reader_scene = makeScene(objects, floor);
    const WayFigures cycle = onTheCycle(*cycle_scene, objects, s.frames);
    const WayFigures reader = onTheReader(*reader_scene, objects, s.frames);
    bool equal = true;
    for (int k = 1; k <= count; ++k) {
      equal = equal && cycle_scene->body(k).positions() == reader_scene->body(k).positions();
    }
    printWay(count, "cycle", cycle, s.frames, equal);
    printWay(count, "reader", reader, s.frames, equal);
    std::fflush(stdout);
  }
}
