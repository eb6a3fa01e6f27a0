#pragma once

#include <Eigen/Core>
#include <ros/time.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "deformable_collision/core/scene/scene.h"

namespace deformable_collision {

/// One object's cloud as the reader read it: its points, transformed and checked, and what
/// the cycle needs to know of it.
struct ReadCloud {
  std::vector<Eigen::Vector3d> points;
  /// The sensor's origin in the target frame, for a cloud in a frame of its own (a camera's).
  std::optional<Eigen::Vector3d> viewpoint;
  ros::Time stamp;
  std::chrono::steady_clock::time_point arrival;
  bool float64 = false;  ///< Any coordinate was FLOAT64: the object's outputs keep that precision.
  /// The object made from this cloud (its first, or any with on_cloud: reset) by the reader,
  /// for the cycle to add: its clusters and hierarchy are built off the cycle's thread.
  Scene::PreparedObject prepared;
  /// A tracked object's cloud as the reader fitted it (TrackedFitter), for the cycle to take
  /// over with `points` (Scene::observeFitted): the fit, too, is made off the cycle's thread.
  TrackedFit fit;
  /// Whether `fit` holds the fit of this cloud, and `points` then its fitted points.
  bool fitted = false;
  /// on_cloud register: the reader's registration of the cloud (RegistrationFitter). Not
  /// held, it is the fit in `fit` and `points`; held, `fit` may hold a fit it replaced.
  std::optional<RegistrationReport> registration;
  SurfaceError fit_error;  ///< The estimated error of the registration that made `fit`.
};

/// The newest read cloud of each object, passed from the thread that reads clouds to the
/// thread that cycles by swapping buffers under one mutex: no point is copied, and once each
/// object's three buffers (being read, waiting, taken) have grown to its clouds nothing is
/// allocated. A cloud not yet taken when a newer one of its object comes is replaced and
/// counted as coalesced, so at most one cloud per object ever waits.
///
/// While a cycle may not start yet (rate_hz), the cycle thread takes clouds early, one per
/// object until the cycle takes, and applies them then; the cycle itself takes the rest.
/// An object whose clouds came faster than the cycles (two or more for each of the last
/// two cycles) is not taken early: its cloud would be replaced before the cycle, and its
/// early work lost. One such cycle alone (a cycle that came late) does not count.
class CloudHandoff {
 public:
  /// `starts_cycle[i]`: whether object i's clouds count for ready().
  explicit CloudHandoff(std::vector<bool> starts_cycle);

  /// Reader: makes `cloud` object's waiting cloud; `cloud` gets back a buffer to read the
  /// next one into (its contents are stale). A cloud replaced before it was taken passes its
  /// prepared object on to the newer one if that has none (a tracked object's first cloud
  /// makes the object, and the clouds after it are fits of that object), and its fit if the
  /// newer one is a held registration (the object's newest fit is still the older one's).
  void put(std::size_t object, ReadCloud& cloud);
  /// Whether, since the last takeForCycle(), a cloud of an object that starts cycles came
  /// (waiting, or taken early); with `all`, one of every such object.
  bool ready(bool all) const;
  /// Cycle, before it may start: swaps each waiting cloud of an object that had none taken
  /// early since the last takeForCycle() into taken[object] and lists those objects in
  /// `objects` (whose capacity is reused), in the order their clouds came. The clouds of
  /// the others stay waiting, for the cycle, and so do those of an object that had two
  /// clouds or more for each of the last two cycles, until a cycle has one cloud of it: an
  /// object faster than the cycles costs one cloud's work a cycle, and two in the two cycles
  /// in which it became so.
  void takeEarly(std::vector<ReadCloud>& taken, std::vector<std::size_t>& objects);
  /// Cycle, as it starts: swaps every waiting cloud into taken[object] (listing those
  /// objects as takeEarly() does), and ready() counts anew.
  void takeForCycle(std::vector<ReadCloud>& taken, std::vector<std::size_t>& objects);
  /// Clouds replaced before they were taken, since construction.
  std::uint64_t coalesced() const;

 private:
  /// A held registration `newer` takes over the fit of the `older` cloud it replaced.
  static void keepOlderFit(ReadCloud& newer, ReadCloud& older);

  mutable std::mutex mutex_;
  std::vector<ReadCloud> waiting_;
  std::vector<bool> is_waiting_;
  std::vector<bool> taken_early_;           ///< Since the last takeForCycle().
  std::vector<bool> replaced_since_cycle_;  ///< A waiting cloud replaced since then.
  /// Cycles in a row that had two clouds or more of the object, up to kCyclesFasterToWait.
  static constexpr int kCyclesFasterToWait = 2;
  std::vector<int> cycles_faster_;
  std::vector<std::size_t> waiting_objects_;
  std::vector<std::size_t> early_objects_;
  const std::vector<bool> starts_cycle_;
  std::size_t objects_starting_cycles_ = 0;
  /// Objects that start cycles with a cloud waiting or taken early: what ready() counts.
  std::size_t fresh_starting_cycles_ = 0;
  std::uint64_t coalesced_ = 0;
};

}  // namespace deformable_collision
