// Publishes a built-in scene (deformable_collision/scenes/demo_scenes.h) as one PointCloud2
// per object on <object>/points, and the frames of its kinematic objects on tf: the input
// of the demo and of the node's tests. Scene camera_gripper is a depth camera's view
// instead (camera_gripper_publisher.h). With ~simulate the scene is stepped and every cloud
// shows the current points (for objects the node tracks); otherwise the points as they are
// after ~settle_s seconds of simulation (0: the rest shapes).
#include <dirent.h>
#include <netinet/in.h>
#include <ros/ros.h>
#include <ros/xmlrpc_manager.h>
#include <sensor_msgs/PointCloud2.h>
#include <sys/socket.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cmath>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "deformable_collision/scenes/demo_scenes.h"
#include "deformable_collision/tools/camera_gripper_publisher.h"
#include "deformable_collision/tools/scene_messages.h"

namespace {

using deformable_collision::DemoScene;

struct PublisherParams {
  std::string scene_name;
  DemoScene scene_kind;
  int points;
  int pile_objects;
  double rate_hz;
  bool simulate;
  double settle_s;
  std::string fixed_frame;
};

/// The private parameters, checked; std::nullopt after saying what is wrong.
std::optional<PublisherParams> readParams(const ros::NodeHandle& private_handle) {
  PublisherParams params;
  params.scene_name = private_handle.param<std::string>("scene", "gripper");
  params.points = private_handle.param("points", 0);
  params.pile_objects = private_handle.param("pile_objects", 0);
  params.rate_hz = private_handle.param("rate_hz", 10.0);
  params.simulate = private_handle.param("simulate", false);
  params.settle_s = private_handle.param("settle_s", 0.0);
  params.fixed_frame = private_handle.param<std::string>("fixed_frame", "world");

  const auto scene_kind = deformable_collision::parseDemoScene(params.scene_name);
  if (!scene_kind) {
    ROS_FATAL("~scene = '%s' must be %s or %s", params.scene_name.c_str(),
              deformable_collision::enumNameList(deformable_collision::kDemoSceneNames).c_str(),
              deformable_collision::kCameraGripperSceneName);
    return std::nullopt;
  }
  params.scene_kind = *scene_kind;
  if (!(params.rate_hz >= 10.0 && params.rate_hz <= 1000.0) || params.points < 0 ||
      params.pile_objects < 0 || !(params.settle_s >= 0.0 && params.settle_s <= 60.0)) {
    ROS_FATAL(
        "~rate_hz = %g must be in [10, 1000] (one scene step per cloud, dt <= 0.1 s), "
        "~points = %d and ~pile_objects = %d >= 0 and ~settle_s = %g in [0, 60]",
        params.rate_hz, params.points, params.pile_objects, params.settle_s);
    return std::nullopt;
  }
  return params;
}

/// The port that descriptor `fd` listens on as an IPv4 or IPv6 socket, or 0.
std::uint16_t listeningPort(int fd) {
  sockaddr_storage address{};
  socklen_t length = sizeof(address);
  int listening = 0;
  socklen_t flag_length = sizeof(listening);
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0 ||
      getsockopt(fd, SOL_SOCKET, SO_ACCEPTCONN, &listening, &flag_length) != 0 || !listening) {
    return 0;
  }
  if (address.ss_family == AF_INET) {
    return ntohs(reinterpret_cast<sockaddr_in*>(&address)->sin_port);
  }
  if (address.ss_family == AF_INET6) {
    return ntohs(reinterpret_cast<sockaddr_in6*>(&address)->sin6_port);
  }
  return 0;
}

/// roscpp's XML-RPC server (xmlrpcpp's) listens with a backlog of 5. A node that subscribes to
/// hundreds of this publisher's topics (the load test's 300) asks for them all at once; the
/// kernel drops the connections beyond the backlog, and TCP tries them again after 1, 3, 7,
/// 15 and 31 s, so that some of the node's objects came half a minute late. Linux lets a
/// listening socket listen again, which only sets its backlog: the server's socket is found
/// by its port among the process's descriptors.
void lengthenXmlRpcBacklog() {
  const auto port = static_cast<std::uint16_t>(ros::XMLRPCManager::instance()->getServerPort());
  bool lengthened = false;
  if (DIR* descriptors = opendir("/proc/self/fd")) {
    while (!lengthened) {
      const dirent* entry = readdir(descriptors);
      if (entry == nullptr) break;
      const int fd = std::atoi(entry->d_name);
      lengthened = fd > 2 && listeningPort(fd) == port && listen(fd, SOMAXCONN) == 0;
    }
    closedir(descriptors);
  }
  if (!lengthened) {
    ROS_WARN(
        "scene_publisher: its XML-RPC server keeps a backlog of 5: a node that subscribes "
        "to many of its topics at once may be connected to some only seconds later");
  }
}

/// One round of output: the frames of the kinematic objects, and each subscribed object's
/// cloud.
void publishScene(const PublisherParams& params, const deformable_collision::Scene& scene,
                  const ros::Time& now, double time_s, std::vector<ros::Publisher>& publishers,
                  tf2_ros::TransformBroadcaster& broadcaster,
                  deformable_collision::SceneMessages& messages) {
  std::vector<bool> wanted;
  for (const auto& publisher : publishers) wanted.push_back(publisher.getNumSubscribers() > 0);
  deformable_collision::SceneFrames frames;
  frames.fixed_frame = frames.cloud_frame = params.fixed_frame;
  deformable_collision::makeSceneMessages(params.scene_kind, scene, time_s, now, frames, wanted,
                                          messages);
  broadcaster.sendTransform(messages.frames.transforms);
  for (std::size_t i = 0; i < publishers.size(); ++i) {
    if (messages.clouds[i]) publishers[i].publish(messages.clouds[i]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "scene_publisher");
  ros::NodeHandle node_handle;
  lengthenXmlRpcBacklog();
  const ros::NodeHandle private_handle("~");
  const std::string scene_name = private_handle.param<std::string>("scene", "");
  if (scene_name == deformable_collision::kCameraGripperSceneName) {
    return deformable_collision::runCameraGripperPublisher(node_handle, private_handle);
  }
  const std::optional<PublisherParams> params = readParams(private_handle);
  if (!params) return 1;
  deformable_collision::SceneConfig config;
  config.dt_s = 1.0 / params->rate_hz;
  std::unique_ptr<deformable_collision::Scene> scene;
  try {
    scene = deformable_collision::makeDemoScene(params->scene_kind,
                                                static_cast<std::size_t>(params->points), config,
                                                static_cast<std::size_t>(params->pile_objects));
  } catch (const std::exception& e) {
    ROS_FATAL("cannot build scene '%s': %s", params->scene_name.c_str(), e.what());
    return 1;
  }

  // Settling runs before anything is published, on the scene's own clock, which the loop
  // below continues (kinematic objects keep their course).
  const int settle_cycles = static_cast<int>(std::lround(params->settle_s * params->rate_hz));
  for (int cycle = 0; cycle < settle_cycles && ros::ok(); ++cycle) {
    deformable_collision::driveDemoScene(params->scene_kind, *scene, cycle * config.dt_s);
    scene->cycle();
  }

  std::vector<ros::Publisher> publishers;
  for (std::size_t i = 0; i < scene->objectCount(); ++i) {
    publishers.push_back(node_handle.advertise<sensor_msgs::PointCloud2>(
        scene->objectConfig(i).name + "/points", 2));
  }
  tf2_ros::TransformBroadcaster broadcaster;
  deformable_collision::SceneMessages messages;
  ROS_INFO("scene_publisher: scene '%s' with %zu objects at %.1f Hz%s, settled for %d cycles",
           params->scene_name.c_str(), scene->objectCount(), params->rate_hz,
           params->simulate ? ", simulated" : "", settle_cycles);

  const ros::Time start = ros::Time::now();
  ros::Rate rate(params->rate_hz);
  while (ros::ok()) {
    const ros::Time now = ros::Time::now();
    const double time_s = settle_cycles * config.dt_s + (now - start).toSec();
    if (params->simulate) {
      deformable_collision::driveDemoScene(params->scene_kind, *scene, time_s);
      scene->cycle();
    }
    publishScene(*params, *scene, now, time_s, publishers, broadcaster, messages);
    ros::spinOnce();
    rate.sleep();
  }
  return 0;
}
