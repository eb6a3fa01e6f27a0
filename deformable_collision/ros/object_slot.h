#pragma once

#include <Eigen/Geometry>
#include <ros/ros.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "deformable_collision/core/registration/cloud_registration.h"
#include "deformable_collision/core/scene/registration_fitter.h"
#include "deformable_collision/ros/counted_publisher.h"
#include "deformable_collision/ros/near_points_handoff.h"
#include "deformable_collision/ros/node_config.h"

namespace deformable_collision {

/// One configured object of the node, as its reader and its cycle share it.
struct ObjectSlot {
  using Clock = std::chrono::steady_clock;

  ObjectParams params;
  ros::Subscriber subscriber;
  CountedPublisher deformed;
  CountedPublisher wrench;  ///< Kinematic objects: ~wrench/<object>.
  /// on_cloud register: the registration of the object's clouds, which the cycle makes with
  /// the object before it sets `exists` and the reader then takes over and runs.
  std::optional<RegistrationFitter> fitter;
  /// Set by the cycle once the object is in the scene.
  std::atomic<bool> exists{false};
  /// on_cloud register: the other objects' points near it, from the cycle to the reader.
  NearPointsHandoff near_points;
  /// Guarded by the reader's report mutex: the last report of a dropped cloud, and the
  /// drops since.
  std::optional<Clock::time_point> last_report;
  std::size_t drops_unreported = 0;
  /// For the diagnostics: the clouds received and dropped since start, the arrival of the
  /// last (Clock ticks since its epoch; 0: none yet) and the mean interval between arrivals.
  /// The reader writes them (a drop may come from the cycle too).
  std::atomic<std::uint64_t> clouds_received{0};
  std::atomic<std::uint64_t> clouds_dropped{0};
  std::atomic<Clock::rep> last_arrival{0};
  std::atomic<double> mean_interval_s{0.0};
  // The cycle's.
  std::optional<std::size_t> index;            ///< In the scene, once a cloud set its rest shape.
  std::optional<Eigen::Isometry3d> last_pose;  ///< Kinematic objects.
  bool float64 = false;  ///< ~deformed/<object> in FLOAT64, like the last cloud.
  /// on_cloud register: model_file's points in model_frame until tf places them (a robot
  /// link: its surface in its frame until tf has that frame's pose), the last cloud's
  /// registration the cycle took, and the clouds held since start and since the last report.
  std::vector<Eigen::Vector3d> model_points;
  RegistrationReport registration;
  std::uint64_t clouds_held = 0;
  std::optional<Clock::time_point> last_held_report;
  std::size_t held_unreported = 0;
};

}  // namespace deformable_collision
