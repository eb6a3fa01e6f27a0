// Records a built-in scene in a bag as a robot's recording holds it: each object's cloud on
// /scene/<object>/points, the soft and static ones seen from a camera frame that circles the
// scene, and on /tf that frame and the kinematic objects' frames, five times per cloud. The
// scene is simulated, so the clouds show its objects deforming. tf may be recorded late, as
// a slow tf publisher's comes after the data it places, and goes on 1 s after the last cloud.
// `rosbag play --clock` gives it to the node (launch/demo.launch's objects) without a camera; the
// bag test replays it. Usage: scene_bag OUTPUT.bag [scene=gripper] [duration_s=4] [rate_hz=10
// (clouds per second)]
//        [points=0 (the scene's default)] [tf_lag_s=0 (tf recorded this late)]
#include <ros/time.h>
#include <rosbag/bag.h>

#include <cmath>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>

#include "deformable_collision/tools/scene_messages.h"

namespace dc = deformable_collision;

namespace {

/// The bag's clock starts here, as a recording's would start at its wall time.
constexpr double kStartS = 1000.0;
constexpr int kFramesPerCloud = 5;
/// tf goes on this long after the last cloud.
constexpr double kTailS = 1.0;
constexpr const char* kCameraFrame = "camera";

struct BagParams {
  std::string file;
  dc::DemoScene scene = dc::DemoScene::kGripper;
  double duration_s = 4.0;
  double rate_hz = 10.0;
  std::size_t points = 0;
  double tf_lag_s = 0.0;
};

std::optional<BagParams> readArguments(int argc, char** argv) {
  if (argc < 2 || argc > 7) return std::nullopt;
  BagParams params;
  params.file = argv[1];
  if (argc > 2) {
    const auto scene = dc::parseDemoScene(argv[2]);
    if (!scene) return std::nullopt;
    params.scene = *scene;
  }
  if (argc > 3) params.duration_s = std::atof(argv[3]);
  if (argc > 4) params.rate_hz = std::atof(argv[4]);
  if (argc > 5) params.points = static_cast<std::size_t>(std::atol(argv[5]));
  if (argc > 6) params.tf_lag_s = std::atof(argv[6]);
  // Each frame is one step of the scene, which takes at most 0.1 s.
  const bool valid = params.duration_s > 0.0 && params.duration_s <= 600.0 &&
                     params.rate_hz * kFramesPerCloud >= 10.0 && params.rate_hz <= 200.0 &&
                     params.tf_lag_s >= 0.0 && params.tf_lag_s <= 10.0;
  return valid ? std::optional<BagParams>(params) : std::nullopt;
}

/// The camera 0.6 m from the scene's centre and 0.5 m above it, looking at it (z forward,
/// x right, y down) as it goes round at 0.3 rad/s.
Eigen::Isometry3d cameraPose(double time_s) {
  const Eigen::Vector3d target(0.0, 0.0, 0.05);
  const double angle = 0.3 * time_s;
  const Eigen::Vector3d position =
      target + Eigen::Vector3d(0.6 * std::cos(angle), 0.6 * std::sin(angle), 0.5);
  const Eigen::Vector3d forward = (target - position).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << right, forward.cross(right), forward;
  pose.translation() = position;
  return pose;
}

void writeBag(const BagParams& params) {
  dc::SceneConfig config;
  config.dt_s = 1.0 / (params.rate_hz * kFramesPerCloud);
  const auto scene = dc::makeDemoScene(params.scene, params.points, config);
  rosbag::Bag bag(params.file, rosbag::bagmode::Write);
  dc::SceneFrames frames;
  frames.cloud_frame = kCameraFrame;
  dc::SceneMessages messages;
  const std::vector<bool> every(scene->objectCount(), true);
  const std::vector<bool> none(scene->objectCount(), false);
  const int steps = static_cast<int>(std::lround(params.duration_s / config.dt_s));
  // As a recording stopped by hand, it goes on for a while after the last cloud (tf only):
  // a bag played in a loop then starts again after the node has done with that cloud.
  const int tail_steps = static_cast<int>(std::lround(kTailS / config.dt_s));
  for (int step = 0; step < steps + tail_steps; ++step) {
    const double time_s = step * config.dt_s;
    const ros::Time stamp(kStartS + time_s);
    dc::driveDemoScene(params.scene, *scene, time_s);
    scene->cycle();
    frames.cloud_frame_pose = cameraPose(time_s);
    const bool clouds = step < steps && step % kFramesPerCloud == 0;
    dc::makeSceneMessages(params.scene, *scene, time_s, stamp, frames, clouds ? every : none,
                          messages);
    // Without a lag, the frames first: as a recording's tf that comes with its data.
    bag.write("/tf", stamp + ros::Duration(params.tf_lag_s), messages.frames);
    for (std::size_t i = 0; i < messages.clouds.size(); ++i) {
      if (!messages.clouds[i]) continue;
      bag.write("/scene/" + scene->objectConfig(i).name + "/points", stamp, *messages.clouds[i]);
    }
  }
  std::printf(
      "scene_bag: %s, scene %s, %.1f s, clouds of %zu objects at %.1f Hz, tf at %.1f Hz %.3f s "
      "late\n",
      params.file.c_str(), dc::toString(params.scene), params.duration_s, scene->objectCount(),
      params.rate_hz, params.rate_hz * kFramesPerCloud, params.tf_lag_s);
}

}  // namespace

int main(int argc, char** argv) {
  const std::optional<BagParams> params = readArguments(argc, argv);
  if (!params) {
    std::fprintf(stderr,
                 "usage: scene_bag OUTPUT.bag [scene (%s)] [duration_s in (0, 600]] "
                 "[rate_hz in [2, 200]] [points] [tf_lag_s in [0, 10]]\n",
                 dc::enumNameList(dc::kDemoSceneNames).c_str());
    return 2;
  }
  ros::Time::init();
  try {
    writeBag(*params);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "scene_bag: %s\n", e.what());
    return 1;
  }
  return 0;
}
