#include "deformable_collision/ros/cloud_handoff.h"

#include <gtest/gtest.h>

#include <atomic>
#include <optional>
#include <set>
#include <thread>

#include "deformable_collision/core/scene/scene.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "deformable_collision/scenes/shapes.h"

namespace deformable_collision {
namespace {

using Points = std::vector<Eigen::Vector3d>;

/// A cloud of `count` points whose first x is `sequence`, so that the taker can tell which it got.
ReadCloud numbered(std::size_t count, double sequence) {
  ReadCloud cloud;
  cloud.points.assign(count, Eigen::Vector3d::Zero());
  cloud.points[0].x() = sequence;
  return cloud;
}

TEST(CloudHandoff, PassesTheBufferItselfNotACopy) {
  CloudHandoff handoff({true});
  ReadCloud read = numbered(10, 1.0);
  const Eigen::Vector3d* data = read.points.data();
  read.stamp = ros::Time(12.5);
  handoff.put(0, read);
  std::vector<ReadCloud> taken(1);
  std::vector<std::size_t> objects;
  handoff.takeForCycle(taken, objects);
  ASSERT_EQ(objects, std::vector<std::size_t>{0});
  EXPECT_EQ(taken[0].points.data(), data);
  EXPECT_EQ(taken[0].stamp, ros::Time(12.5));
  EXPECT_EQ(handoff.coalesced(), 0u);
}

TEST(CloudHandoff, ANewerCloudReplacesOneNotYetTaken) {
  CloudHandoff handoff({true, false});
  for (double sequence : {1.0, 2.0, 3.0}) {
    ReadCloud read = numbered(4, sequence);
    handoff.put(0, read);
  }
  ReadCloud other = numbered(4, 7.0);
  handoff.put(1, other);
  std::vector<ReadCloud> taken(2);
  std::vector<std::size_t> objects;
  handoff.takeForCycle(taken, objects);
  EXPECT_EQ(objects, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(taken[0].points[0].x(), 3.0);
  EXPECT_EQ(taken[1].points[0].x(), 7.0);
  EXPECT_EQ(handoff.coalesced(), 2u);
  handoff.takeForCycle(taken, objects);
  EXPECT_TRUE(objects.empty()) << "each cloud is taken once";
}

TEST(CloudHandoff, ReadyWhenOneOrEveryObjectThatStartsCyclesHasACloud) {
  CloudHandoff handoff({true, false, true});
  ReadCloud read = numbered(1, 0.0);
  EXPECT_FALSE(handoff.ready(false));
  handoff.put(1, read);
  EXPECT_FALSE(handoff.ready(false)) << "object 1 does not start cycles";
  handoff.put(0, read);
  EXPECT_TRUE(handoff.ready(false));
  EXPECT_FALSE(handoff.ready(true));
  handoff.put(0, read);
  EXPECT_FALSE(handoff.ready(true)) << "a second cloud of the same object is not another object's";
  handoff.put(2, read);
  EXPECT_TRUE(handoff.ready(true));
  std::vector<ReadCloud> taken(3);
  std::vector<std::size_t> objects;
  handoff.takeForCycle(taken, objects);
  EXPECT_FALSE(handoff.ready(false));
  EXPECT_FALSE(CloudHandoff({false}).ready(true)) << "no object starts cycles";
}

TEST(CloudHandoff, AnObjectTakenEarlyStaysReadyUntilTheCycleTakes) {
  CloudHandoff handoff({true, true});
  ReadCloud read = numbered(1, 0.0);
  std::vector<ReadCloud> taken(2);
  std::vector<std::size_t> objects;
  handoff.put(0, read);
  handoff.takeEarly(taken, objects);
  EXPECT_EQ(objects, std::vector<std::size_t>{0});
  EXPECT_TRUE(handoff.ready(false)) << "its cloud, applied early, is still the next cycle's";
  EXPECT_FALSE(handoff.ready(true));
  handoff.put(1, read);
  EXPECT_TRUE(handoff.ready(true)) << "one object's cloud taken early, the other's waiting";
  handoff.takeForCycle(taken, objects);
  EXPECT_EQ(objects, std::vector<std::size_t>{1});
  EXPECT_FALSE(handoff.ready(false));
  EXPECT_FALSE(handoff.ready(true));
}

TEST(CloudHandoff, AnObjectTakenEarlyLeavesItsNextCloudsToTheCycle) {
  CloudHandoff handoff({true, false});
  std::vector<ReadCloud> taken(2);
  std::vector<std::size_t> objects;
  ReadCloud read = numbered(4, 1.0);
  handoff.put(0, read);
  handoff.takeEarly(taken, objects);
  ASSERT_EQ(objects, std::vector<std::size_t>{0});
  EXPECT_EQ(taken[0].points[0].x(), 1.0);
  for (double sequence : {2.0, 3.0}) {
    read = numbered(4, sequence);
    handoff.put(0, read);
  }
  read = numbered(4, 7.0);
  handoff.put(1, read);
  handoff.takeEarly(taken, objects);
  EXPECT_EQ(objects, std::vector<std::size_t>{1}) << "one cloud per object before the cycle";
  EXPECT_EQ(taken[1].points[0].x(), 7.0);
  EXPECT_EQ(handoff.coalesced(), 1u) << "cloud 2, replaced while it waited";
  handoff.takeForCycle(taken, objects);
  ASSERT_EQ(objects, std::vector<std::size_t>{0});
  EXPECT_EQ(taken[0].points[0].x(), 3.0);
}

TEST(CloudHandoff, AnObjectFasterThanTheCyclesTwiceInARowWaitsForACycleWithOneOfItsClouds) {
  CloudHandoff handoff({true});
  std::vector<ReadCloud> taken(1);
  std::vector<std::size_t> objects;
  const auto put = [&](double sequence) {
    ReadCloud read = numbered(4, sequence);
    handoff.put(0, read);
  };
  const auto early = [&] {
    handoff.takeEarly(taken, objects);
    return objects.size();
  };
  // A cycle with two clouds of the object, the first offered early: how many were taken early.
  const auto two_clouds = [&](double first) {
    put(first);
    const std::size_t taken_early = early();
    put(first + 1.0);
    handoff.takeForCycle(taken, objects);
    return taken_early;
  };
  ASSERT_EQ(two_clouds(1.0), 1u);
  ASSERT_EQ(objects, std::vector<std::size_t>{0}) << "cloud 2 replaces the early cloud 1";
  EXPECT_EQ(two_clouds(3.0), 1u) << "one cycle with two clouds (a late cycle, say) does not count";
  put(5.0);
  EXPECT_EQ(early(), 0u) << "two cycles in a row with two clouds: cloud 5 waits for the cycle";
  handoff.takeForCycle(taken, objects);
  ASSERT_EQ(objects, std::vector<std::size_t>{0});
  EXPECT_EQ(taken[0].points[0].x(), 5.0);
  put(6.0);
  EXPECT_EQ(early(), 1u) << "a cycle with one cloud of it: early again";
  handoff.takeForCycle(taken, objects);
  // One fast cycle, one with its early cloud alone, one fast again: never two in a row.
  ASSERT_EQ(two_clouds(7.0), 1u);
  put(9.0);
  ASSERT_EQ(early(), 1u);
  handoff.takeForCycle(taken, objects);
  ASSERT_EQ(two_clouds(10.0), 1u);
  put(12.0);
  EXPECT_EQ(early(), 1u) << "a cycle with its early cloud alone ends a run of fast cycles";
  handoff.takeForCycle(taken, objects);
  for (double sequence : {13.0, 15.0}) {
    put(sequence);
    put(sequence + 1.0);
    handoff.takeForCycle(taken, objects);
    ASSERT_EQ(objects, std::vector<std::size_t>{0});
    EXPECT_EQ(taken[0].points[0].x(), sequence + 1.0);
  }
  put(17.0);
  EXPECT_EQ(early(), 0u) << "clouds replaced while they waited count as well";
}

TEST(CloudHandoff, ThreeBuffersCirculateOnceGrown) {
  CloudHandoff handoff({true});
  ReadCloud read;
  std::vector<ReadCloud> taken(1);
  std::vector<std::size_t> objects;
  objects.reserve(1);
  std::set<const Eigen::Vector3d*> buffers;
  for (int round = 0; round < 12; ++round) {
    read.points.resize(100);  // a reader refilling its buffer: no allocation once grown
    if (round >= 3) buffers.insert(read.points.data());
    handoff.put(0, read);
    handoff.takeForCycle(taken, objects);
  }
  EXPECT_LE(buffers.size(), 3u);
}

// The reader thread converts clouds, fits them and hands them over while the cycle thread
// takes them, early and for its cycles, and runs the scene's cycle on them, as the node does:
// the reader makes the tracked object from its first cloud and fits every later one, and it
// also prepares, while the cycle runs, a second object that the cycle adds and then gives
// new rest shapes to. Under ThreadSanitizer (the thread build of test/sanitized) any
// unsynchronised access between the two is reported.
TEST(CloudHandoff, AReaderAndACycleRunConcurrently) {
  constexpr int kClouds = 300;
  constexpr int kCloudsPerShape = 10;
  const Points shape = sampleBox(200, Eigen::Vector3d(0.05, 0.05, 0.05), 7);
  SceneConfig config;
  config.contact_distance_m = 0.02;
  Scene scene(config);
  ObjectConfig tracked;
  tracked.name = "tracked";
  tracked.kind = ObjectKind::kTracked;
  ObjectConfig reshaped;
  reshaped.name = "reshaped";
  reshaped.kind = ObjectKind::kStatic;

  CloudHandoff handoff({true, false});
  std::atomic<bool> reading{true};
  std::thread reader([&] {
    ReadCloud read;
    ReadCloud shape_read;
    sensor_msgs::PointCloud2 message;
    Points moved = shape;
    std::optional<TrackedFitter> fitter;
    for (int sequence = 1; sequence <= kClouds; ++sequence) {
      for (std::size_t i = 0; i < shape.size(); ++i)
        moved[i] = shape[i] + Eigen::Vector3d(1e-4 * sequence, 0, 0);
      writeCloudPoints(moved, message, sensor_msgs::PointField::FLOAT64);
      if (!readCloudPoints(message, NonFinitePoints::kKeepAsNaN, 1000, read.points).ok()) {
        ADD_FAILURE() << "cloud " << sequence << " not read";
      }
      read.prepared = Scene::PreparedObject();
      read.fitted = false;
      if (fitter) {
        fitter->fit(read.points, read.fit);
        read.fitted = true;
      } else {
        read.prepared = scene.prepareObject(tracked, read.points);
        fitter = read.prepared.trackedFitter();
      }
      read.stamp = ros::Time(sequence);
      handoff.put(0, read);
      if (sequence % kCloudsPerShape == 0) {
        shape_read.points =
            sampleBox(50 + sequence / kCloudsPerShape, Eigen::Vector3d(0.1, 0.1, 0.1),
                      static_cast<std::uint32_t>(sequence));
        for (auto& p : shape_read.points) p.z() += 0.5;
        shape_read.prepared = scene.prepareObject(reshaped, shape_read.points);
        shape_read.stamp = ros::Time(sequence);
        handoff.put(1, shape_read);
      }
    }
    reading = false;
  });

  std::vector<ReadCloud> taken(2);
  std::vector<std::size_t> objects;
  objects.reserve(2);
  int cycles = 0;
  int superseded = 0;  // applied early, then replaced before a cycle used it
  bool pending = false;
  double last_stamp = 0.0;
  std::optional<std::size_t> tracked_index;
  std::optional<std::size_t> reshaped_index;
  std::size_t last_shape_points = 0;
  int shapes_applied = 0;
  const auto apply = [&] {
    for (const std::size_t taken_object : objects) {
      ReadCloud& cloud = taken[taken_object];
      if (taken_object == 1) {
        if (reshaped_index) {
          scene.resetRestShape(*reshaped_index, std::move(cloud.prepared));
        } else {
          reshaped_index = scene.addObject(std::move(cloud.prepared));
        }
        last_shape_points = cloud.points.size();
        ++shapes_applied;
        continue;
      }
      EXPECT_GT(cloud.stamp.toSec(), last_stamp) << "clouds come newest last";
      last_stamp = cloud.stamp.toSec();
      // The first cloud taken carries the object, made from the first cloud read.
      ASSERT_EQ(tracked_index.has_value(), cloud.prepared.empty());
      if (!tracked_index) tracked_index = scene.addObject(std::move(cloud.prepared));
      if (cloud.fitted) scene.observeFitted(*tracked_index, cloud.points, cloud.fit);
      superseded += pending;
      pending = true;
    }
  };
  for (int round = 0;; ++round) {
    const bool done = !reading;  // read before the takes: then the last cloud is in them
    handoff.takeEarly(taken, objects);
    apply();
    if (round % 2 == 1) {
      handoff.takeForCycle(taken, objects);
      apply();
      if (pending) {
        scene.cycle();
        ++cycles;
        pending = false;
      }
    }
    if (done && !pending && !handoff.ready(false)) break;
    std::this_thread::yield();
  }
  reader.join();
  handoff.takeForCycle(taken, objects);  // a last shape, which needs no cycle
  apply();
  EXPECT_EQ(last_stamp, kClouds) << "the newest cloud is always taken";
  EXPECT_EQ(cycles + superseded + shapes_applied + handoff.coalesced(),
            static_cast<std::uint64_t>(kClouds + kClouds / kCloudsPerShape));
  ASSERT_TRUE(tracked_index.has_value());
  EXPECT_NEAR(scene.body(*tracked_index).positions()[0].x(), shape[0].x() + 1e-4 * kClouds, 1e-9);
  ASSERT_TRUE(reshaped_index.has_value());
  EXPECT_EQ(last_shape_points, 50u + kClouds / kCloudsPerShape);
  EXPECT_EQ(scene.body(*reshaped_index).positions().size(), last_shape_points);
}

// A tracked object's first cloud makes it; a cloud that replaces the first before the cycle
// took it is a fit of that object, and must bring the object along.
TEST(CloudHandoff, AReplacedCloudPassesItsPreparedObjectToANewerOneWithout) {
  Scene scene(SceneConfig{});
  ObjectConfig tracked;
  tracked.name = "tracked";
  tracked.kind = ObjectKind::kTracked;
  CloudHandoff handoff({true});
  ReadCloud first = numbered(4, 1.0);
  first.prepared = scene.prepareObject(tracked, sampleBox(50, Eigen::Vector3d(0.1, 0.1, 0.1), 1));
  handoff.put(0, first);
  ReadCloud second = numbered(4, 2.0);
  handoff.put(0, second);
  EXPECT_TRUE(second.prepared.empty()) << "the replaced first cloud gave its object on";
  std::vector<ReadCloud> taken(1);
  std::vector<std::size_t> objects;
  handoff.takeForCycle(taken, objects);
  EXPECT_EQ(taken[0].points[0].x(), 2.0);
  ASSERT_FALSE(taken[0].prepared.empty());
  EXPECT_EQ(taken[0].prepared.trackedFitter().pointCount(), 50u);

  // A newer cloud with an object of its own keeps it; the older one comes back with its own.
  ReadCloud reset_first = numbered(4, 3.0);
  reset_first.prepared =
      scene.prepareObject(tracked, sampleBox(60, Eigen::Vector3d(0.1, 0.1, 0.1), 2));
  handoff.put(0, reset_first);
  ReadCloud reset_second = numbered(4, 4.0);
  reset_second.prepared =
      scene.prepareObject(tracked, sampleBox(70, Eigen::Vector3d(0.1, 0.1, 0.1), 3));
  handoff.put(0, reset_second);
  handoff.takeForCycle(taken, objects);
  EXPECT_EQ(taken[0].prepared.trackedFitter().pointCount(), 70u);
  ASSERT_FALSE(reset_second.prepared.empty());
  EXPECT_EQ(reset_second.prepared.trackedFitter().pointCount(), 60u);
}

/// A registered cloud numbered `sequence`: held, or a fit of that hidden side's error.
ReadCloud registered(double sequence, bool held, double hidden_error_m = 0.0) {
  ReadCloud cloud = numbered(4, sequence);
  cloud.registration.emplace();
  cloud.registration->held = held;
  cloud.fitted = !held;
  cloud.fit_error.hidden_m = hidden_error_m;
  return cloud;
}

// A held registration carries no fit: the fit it replaced is still the object's newest, and
// the cycle must get it with the held cloud's report. A fit replaces a fit as any cloud does.
TEST(CloudHandoff, AHeldRegistrationKeepsTheFitItReplaced) {
  CloudHandoff handoff({true});
  ReadCloud fit = registered(1.0, false, 0.002);
  handoff.put(0, fit);
  ReadCloud held = registered(2.0, true);
  handoff.put(0, held);
  std::vector<ReadCloud> taken(1);
  std::vector<std::size_t> objects;
  handoff.takeForCycle(taken, objects);
  ASSERT_TRUE(taken[0].registration.has_value());
  EXPECT_TRUE(taken[0].registration->held);
  EXPECT_TRUE(taken[0].fitted);
  EXPECT_EQ(taken[0].points[0].x(), 1.0) << "the older cloud's fitted points";
  EXPECT_EQ(taken[0].fit_error.hidden_m, 0.002);

  ReadCloud first = registered(3.0, false, 0.001);
  handoff.put(0, first);
  ReadCloud second = registered(4.0, false, 0.003);
  handoff.put(0, second);
  handoff.takeForCycle(taken, objects);
  EXPECT_EQ(taken[0].points[0].x(), 4.0);
  EXPECT_EQ(taken[0].fit_error.hidden_m, 0.003);
  EXPECT_FALSE(taken[0].registration->held);
}

}  // namespace
}  // namespace deformable_collision
