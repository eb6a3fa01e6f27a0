// dynamic_reconfigure of a running node (rostest reconfigure.test), through the servers'
// set_parameters services as rqt_reconfigure calls them: each change is answered with the
// values in force, takes effect in the next cycles (a level in ~stats, a contact when the
// distance grows, forces that a contact stiffness makes), a refused one keeps the old values,
// and ~stats counts both. Every wait
// has a timeout.
#include <dynamic_reconfigure/Reconfigure.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>

#include "deformable_collision/ContactArray.h"
#include "deformable_collision/Stats.h"
#include "node_test_support.h"

namespace deformable_collision {
namespace test {
namespace {

const std::string kServer = "/deformable_collision/reconfigure";

/// One parameter as a partial request: the server changes only what the request names.
template <typename Value>
dynamic_reconfigure::Config oneParameter(const std::string& name, Value value) {
  dynamic_reconfigure::Config config;
  if constexpr (std::is_same_v<Value, bool>) {
    config.bools.resize(1);
    config.bools[0].name = name;
    config.bools[0].value = value;
  } else if constexpr (std::is_integral_v<Value>) {
    config.ints.resize(1);
    config.ints[0].name = name;
    config.ints[0].value = value;
  } else {
    config.doubles.resize(1);
    config.doubles[0].name = name;
    config.doubles[0].value = value;
  }
  return config;
}

class ReconfigureTest : public ::testing::Test {
 protected:
  void SetUp() override {
    floor_ = handle_.advertise<sensor_msgs::PointCloud2>("/reconfigure/floor", 1, true);
    probe_ = handle_.advertise<sensor_msgs::PointCloud2>("/reconfigure/probe", 1, true);
    ball_ = handle_.advertise<sensor_msgs::PointCloud2>("/reconfigure/ball", 1, true);
    floor_.publish(cloudOf(grid(21, 21, 2, 0.02, {0.0, 0.0, -0.01}), "world"));
    // A 10 cm cube 1 cm into the floor; a block 4 cm above the floor beside it.
    probe_.publish(cloudOf(grid(6, 6, 6, 0.02, {0.0, 0.0, 0.04}), "world"));
    ball_.publish(cloudOf(grid(5, 5, 3, 0.02, {0.12, 0.12, 0.06}), "world"));
    contacts_ = handle_.subscribe<ContactArray>(
        "/deformable_collision/contacts", 10,
        boost::function<void(const ContactArray::ConstPtr&)>(
            [this](const ContactArray::ConstPtr& m) { last_contacts_ = m; }));
    stats_ = handle_.subscribe<Stats>("/deformable_collision/stats", 10,
                                      boost::function<void(const Stats::ConstPtr&)>(
                                          [this](const Stats::ConstPtr& m) { last_stats_ = m; }));
    ASSERT_TRUE(waitFor([&] { return last_stats_ && last_stats_->objects == 3; }))
        << "the three objects from their clouds";
    ASSERT_TRUE(waitFor([&] { return last_contacts_ && !last_contacts_->contacts.empty(); }));
  }

  /// Calls `server`'s set_parameters; the values in force after it.
  dynamic_reconfigure::Config set(const std::string& server,
                                  const dynamic_reconfigure::Config& request) {
    dynamic_reconfigure::Reconfigure call;
    call.request.config = request;
    EXPECT_TRUE(ros::service::waitForService(server + "/set_parameters", ros::Duration(10.0)));
    EXPECT_TRUE(ros::service::call(server + "/set_parameters", call)) << server;
    return call.response.config;
  }

  template <typename Value>
  static Value valueOf(const dynamic_reconfigure::Config& config, const std::string& name) {
    if constexpr (std::is_same_v<Value, bool>) {
      for (const auto& p : config.bools)
        if (p.name == name) return p.value;
    } else if constexpr (std::is_integral_v<Value>) {
      for (const auto& p : config.ints)
        if (p.name == name) return p.value;
    } else {
      for (const auto& p : config.doubles)
        if (p.name == name) return p.value;
    }
    ADD_FAILURE() << name << " is not in the answer";
    return Value{};
  }

  /// Whether the last ~contacts has one of `object`'s.
  bool touches(const std::string& object) const {
    for (const Contact& c : last_contacts_->contacts) {
      if (c.object_a == object || c.object_b == object) return true;
    }
    return false;
  }

  /// The largest contact force on the probe, in the last ~contacts.
  double largestProbeForce() const {
    double largest = 0.0;
    for (const Contact& c : last_contacts_->contacts) {
      if (c.object_a != "probe" && c.object_b != "probe") continue;
      largest = std::max(largest, std::hypot(c.force_n.x, c.force_n.y, c.force_n.z));
    }
    return largest;
  }

  ros::NodeHandle handle_;
  ros::Publisher floor_, probe_, ball_;
  ros::Subscriber contacts_, stats_;
  ContactArray::ConstPtr last_contacts_;
  Stats::ConstPtr last_stats_;
};

TEST_F(ReconfigureTest, EveryParameterChangesWhileRunningAndBadValuesAreRefused) {
  const std::uint32_t accepted = last_stats_->reconfigurations_accepted;
  const std::uint32_t refused = last_stats_->reconfigurations_refused;

  // At the finest level, the block 4 cm above the floor touches it once the contact
  // distance is more.
  EXPECT_TRUE(waitFor([&] { return !touches("ball"); }, 2.0)) << "4 cm apart, 2 cm reach";
  EXPECT_EQ(
      valueOf<double>(set(kServer, oneParameter("contact_distance_m", 0.06)), "contact_distance_m"),
      0.06);
  EXPECT_TRUE(waitFor([&] { return touches("ball"); })) << "a contact at the new distance";
  // The level: taken by the next cycles; beyond the trees, refused.
  EXPECT_EQ(valueOf<int>(set(kServer, oneParameter("level", 1)), "level"), 1);
  EXPECT_TRUE(waitFor([&] { return last_stats_->level == 1; })) << "the cycles at level 1";
  EXPECT_EQ(valueOf<int>(set(kServer, oneParameter("level", 200)), "level"), 1)
      << "level 200 is beyond every tree: the old level kept";
  // Budget mode needs a budget.
  EXPECT_FALSE(valueOf<bool>(set(kServer, oneParameter("level_auto", true)), "level_auto"));
  dynamic_reconfigure::Config automatic = oneParameter("level_auto", true);
  automatic.doubles = oneParameter("cycle_budget_ms", 5.0).doubles;
  EXPECT_TRUE(valueOf<bool>(set(kServer, automatic), "level_auto"));
  EXPECT_EQ(valueOf<int>(set(kServer, oneParameter("level_auto", false)), "level"), 1);
  EXPECT_EQ(valueOf<double>(set(kServer, oneParameter("friction", 0.9)), "friction"), 0.9);
  EXPECT_TRUE(valueOf<bool>(set(kServer, oneParameter("markers_colliding_only", true)),
                            "markers_colliding_only"));
  EXPECT_EQ(valueOf<double>(set(kServer, oneParameter("force_marker_scale_m_per_n", 0.02)),
                            "force_marker_scale_m_per_n"),
            0.02);
  EXPECT_EQ(
      valueOf<int>(set(kServer, oneParameter("register_iterations", 3)), "register_iterations"), 3);
  EXPECT_EQ(valueOf<int>(set(kServer, oneParameter("register_max_cloud_points", 800)),
                         "register_max_cloud_points"),
            800);

  // The tracked probe's contact stiffness makes its contacts' forces.
  EXPECT_TRUE(waitFor([&] { return largestProbeForce() == 0.0; })) << "no stiffness, no force";
  const std::string probe = kServer + "/objects/probe";
  EXPECT_EQ(valueOf<double>(set(probe, oneParameter("contact_stiffness_n_per_m", 500.0)),
                            "contact_stiffness_n_per_m"),
            500.0);
  EXPECT_TRUE(waitFor([&] { return largestProbeForce() > 0.0; })) << "500 N/m of indentation";
  EXPECT_EQ(valueOf<double>(set(probe, oneParameter("stiffness", 0.9)), "stiffness"), 0.5)
      << "a tracked object has no stiffness to change: the old kept";
  // The dynamic ball's material; the static floor has nothing to change.
  const dynamic_reconfigure::Config ball =
      set(kServer + "/objects/ball", oneParameter("damping", 0.3));
  EXPECT_EQ(valueOf<double>(ball, "damping"), 0.3);
  EXPECT_FALSE(ros::service::exists(kServer + "/objects/floor/set_parameters", false));

  EXPECT_TRUE(waitFor([&] {
    return last_stats_->reconfigurations_accepted == accepted + 11 &&
           last_stats_->reconfigurations_refused == refused + 3;
  })) << last_stats_->reconfigurations_accepted - accepted
      << " accepted, " << last_stats_->reconfigurations_refused - refused << " refused";
}

}  // namespace
}  // namespace test
}  // namespace deformable_collision

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_reconfigure");
  ros::NodeHandle handle;
  return RUN_ALL_TESTS();
}
