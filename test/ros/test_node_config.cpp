#include "deformable_collision/ros/node_config.h"

#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace deformable_collision {
namespace {

using XmlRpc::XmlRpcValue;

XmlRpcValue object(const std::string& name, const std::string& topic) {
  XmlRpcValue value;
  value["name"] = name;
  value["topic"] = topic;
  return value;
}

/// The parameters of a scene with one object of each kind.
XmlRpcValue validParams() {
  XmlRpcValue params;
  params["fixed_frame"] = "odom";
  params["rate_hz"] = 50;  // an integer where a number is expected must be accepted
  params["dt_s"] = 0.02;
  params["level"] = 3;
  params["contact_distance_m"] = 0.01;
  params["max_points_per_object"] = 5000;
  params["max_coordinate_m"] = 500.0;
  params["threads"] = 3;
  params["gravity_mps2"][0] = 0.0;
  params["gravity_mps2"][1] = 0.0;
  params["gravity_mps2"][2] = -1.62;
  params["markers"]["colliding_only"] = true;
  params["markers"]["force_scale_m_per_n"] = 0.05;
  params["contact_forces"] = false;
  params["diagnostics"]["period_s"] = 2.0;
  params["diagnostics"]["latency_warn_ms"] = 30.0;
  params["diagnostics"]["latency_error_ms"] = 300.0;
  XmlRpcValue& objects = params["objects"];
  objects[0] = object("floor", "/floor/points");
  objects[0]["dynamic"] = false;
  objects[1] = object("fruit", "fruit/points");
  objects[1]["mode"] = "quadratic";
  objects[1]["clusters"] = 3;
  objects[1]["stiffness"] = 0.8;
  objects[1]["expected_rate_hz"] = 15.0;
  objects[1]["beta"] = 0.4;
  objects[1]["mass_kg"] = 0.25;
  objects[1]["self_collision"] = true;
  objects[1]["self_rest_distance_m"] = 0.03;
  objects[2] = object("jaw", "/jaw/points");
  objects[2]["dynamic"] = false;
  objects[2]["follow_frame"] = "gripper_link";
  objects[3] = object("hand", "/hand/points");
  objects[3]["dynamic"] = false;
  objects[3]["on_cloud"] = "track";
  objects[3]["mode"] = "rigid";
  objects[3]["contact_stiffness_n_per_m"] = 350.0;
  return params;
}

/// parseNodeConfig of parameters that use no deprecated key.
NodeConfig parseWithoutWarnings(const XmlRpcValue& params) {
  std::vector<std::string> warnings;
  NodeConfig config = parseNodeConfig(params, warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  return config;
}

TEST(NodeConfig, ReadsEveryValueAndDerivesTheKinds) {
  const NodeConfig config = parseWithoutWarnings(validParams());
  EXPECT_EQ(config.fixed_frame, "odom");
  EXPECT_DOUBLE_EQ(config.rate_hz, 50.0);
  EXPECT_DOUBLE_EQ(config.scene.dt_s, 0.02);
  EXPECT_EQ(config.scene.level, 3);
  EXPECT_DOUBLE_EQ(config.scene.contact_distance_m, 0.01);
  EXPECT_EQ(config.max_points_per_object, 5000u);
  EXPECT_DOUBLE_EQ(config.max_coordinate_m, 500.0);
  EXPECT_EQ(config.scene.threads, 3);
  EXPECT_TRUE(config.scene.gravity_mps2.isApprox(Eigen::Vector3d(0, 0, -1.62)));
  EXPECT_TRUE(config.markers_colliding_only);
  EXPECT_DOUBLE_EQ(config.force_marker_scale_m_per_n, 0.05);
  EXPECT_FALSE(config.scene.contact_forces);
  EXPECT_DOUBLE_EQ(config.diagnostics.period_s, 2.0);
  EXPECT_DOUBLE_EQ(config.diagnostics.latency_warn_ms, 30.0);
  EXPECT_DOUBLE_EQ(config.diagnostics.latency_error_ms, 300.0);
  ASSERT_EQ(config.objects.size(), 4u);
  EXPECT_DOUBLE_EQ(config.objects[0].expected_rate_hz, 0.0);
  EXPECT_DOUBLE_EQ(config.objects[1].expected_rate_hz, 15.0);

  EXPECT_EQ(config.objects[0].object.kind, ObjectKind::kStatic);
  const ObjectParams& fruit = config.objects[1];
  EXPECT_EQ(fruit.object.kind, ObjectKind::kDynamic);
  EXPECT_EQ(fruit.topic, "fruit/points");
  EXPECT_EQ(fruit.on_cloud, OnCloud::kIgnore);
  EXPECT_EQ(fruit.object.shape.mode, DeformationMode::kQuadratic);
  EXPECT_EQ(fruit.object.shape.clusters, 3);
  EXPECT_DOUBLE_EQ(fruit.object.shape.stiffness, 0.8);
  EXPECT_DOUBLE_EQ(fruit.object.shape.beta, 0.4);
  EXPECT_DOUBLE_EQ(fruit.object.shape.mass_kg, 0.25);
  EXPECT_TRUE(fruit.object.self_collision);
  EXPECT_DOUBLE_EQ(fruit.object.self_rest_distance_m, 0.03);
  EXPECT_EQ(config.objects[2].object.kind, ObjectKind::kKinematic);
  EXPECT_EQ(config.objects[2].object.shape.mode, DeformationMode::kRigid);
  EXPECT_EQ(config.objects[2].follow_frame, "gripper_link");
  EXPECT_EQ(config.objects[3].object.kind, ObjectKind::kTracked);
  EXPECT_EQ(config.objects[3].on_cloud, OnCloud::kTrack);
  EXPECT_DOUBLE_EQ(config.objects[3].object.contact_stiffness_n_per_m, 350.0);
}

TEST(NodeConfig, DefaultsFillWhatIsLeftOut) {
  XmlRpcValue params;
  params["objects"][0] = object("ball", "ball/points");
  const NodeConfig config = parseWithoutWarnings(params);
  const NodeConfig defaults;
  EXPECT_EQ(config.fixed_frame, defaults.fixed_frame);
  EXPECT_DOUBLE_EQ(config.rate_hz, defaults.rate_hz);
  EXPECT_DOUBLE_EQ(config.max_coordinate_m, 1e4);
  EXPECT_EQ(config.scene.level, -1);
  EXPECT_EQ(config.objects[0].object.kind, ObjectKind::kDynamic);
  EXPECT_EQ(config.objects[0].object.shape.mode, DeformationMode::kLinear);
  EXPECT_DOUBLE_EQ(config.objects[0].object.contact_stiffness_n_per_m, 0.0);
  EXPECT_FALSE(config.objects[0].object.self_collision);
  EXPECT_DOUBLE_EQ(config.objects[0].object.self_rest_distance_m, 0.0);
  EXPECT_DOUBLE_EQ(config.force_marker_scale_m_per_n, 0.01);
  EXPECT_TRUE(config.scene.contact_forces);
  EXPECT_GE(config.scene.threads, 1);
  EXPECT_LE(config.scene.threads, 8);
}

struct BadParamCase {
  std::string name;
  std::function<void(XmlRpcValue&)> spoil;
  std::string expected;  ///< The message must contain it (the parameter's name).
};

class BadParamTest : public ::testing::TestWithParam<BadParamCase> {};

/// Spoils `params` as the case says and expects them refused with the case's words.
void expectRefused(XmlRpcValue params, const BadParamCase& c) {
  c.spoil(params);
  try {
    std::vector<std::string> warnings;
    parseNodeConfig(params, warnings);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
  }
}

TEST_P(BadParamTest, ThrowsNamingTheParameter) { expectRefused(validParams(), GetParam()); }

INSTANTIATE_TEST_SUITE_P(
    NodeConfig, BadParamTest,
    ::testing::Values(
        BadParamCase{"NotADictionary", [](XmlRpcValue& p) { p = XmlRpcValue(3); }, "dictionary"},
        BadParamCase{"ZeroRate", [](XmlRpcValue& p) { p["rate_hz"] = 0.0; }, "rate_hz = 0"},
        BadParamCase{"RateAsString", [](XmlRpcValue& p) { p["rate_hz"] = "fast"; }, "rate_hz must be a number"},
        BadParamCase{"LargeStep", [](XmlRpcValue& p) { p["dt_s"] = 0.5; }, "dt_s = 0.5"},
        BadParamCase{"LevelBelowMinusOne", [](XmlRpcValue& p) { p["level"] = -2; }, "level = -2"},
        BadParamCase{"LevelNotInteger", [](XmlRpcValue& p) { p["level"] = 2.5; }, "level must be an integer"},
        BadParamCase{"LevelAnotherWord", [](XmlRpcValue& p) { p["level"] = "fast"; }, "level = 'fast' must be an integer in [-1, 255] or 'auto'"},
        BadParamCase{"LevelAutoWithoutBudget", [](XmlRpcValue& p) { p["level"] = "auto"; }, "level = 'auto' needs cycle_budget_ms"},
        BadParamCase{"BudgetWithoutAuto", [](XmlRpcValue& p) { p["cycle_budget_ms"] = 5.0; }, "cycle_budget_ms is read only with level: auto"},
        BadParamCase{"BudgetWithFinest", [](XmlRpcValue& p) { p["level"] = -1; p["cycle_budget_ms"] = 5.0; }, "cycle_budget_ms is read only with level: auto"},
        BadParamCase{"ZeroBudget", [](XmlRpcValue& p) { p["level"] = "auto"; p["cycle_budget_ms"] = 0.0; }, "cycle_budget_ms = 0 must be in (0, 1e+06]"},
        BadParamCase{"NegativeBudget", [](XmlRpcValue& p) { p["level"] = "auto"; p["cycle_budget_ms"] = -3; }, "cycle_budget_ms = -3 must be in (0, 1e+06]"},
        BadParamCase{"InfiniteBudget", [](XmlRpcValue& p) { p["level"] = "auto"; p["cycle_budget_ms"] = std::numeric_limits<double>::infinity(); }, "cycle_budget_ms = inf"},
        BadParamCase{"NaNBudget", [](XmlRpcValue& p) { p["level"] = "auto"; p["cycle_budget_ms"] = std::numeric_limits<double>::quiet_NaN(); }, "cycle_budget_ms = nan"},
        BadParamCase{"BudgetAsString", [](XmlRpcValue& p) { p["level"] = "auto"; p["cycle_budget_ms"] = "short"; }, "cycle_budget_ms must be a number"},
        BadParamCase{"NoThreads", [](XmlRpcValue& p) { p["threads"] = 0; }, "threads = 0 must be in [1, 64]"},
        BadParamCase{"ThreadsAsNumber", [](XmlRpcValue& p) { p["threads"] = 2.0; }, "threads must be an integer"},
        BadParamCase{"NegativeContactDistance", [](XmlRpcValue& p) { p["contact_distance_m"] = -0.1; }, "contact_distance_m"},
        BadParamCase{"GravityOfTwo", [](XmlRpcValue& p) {
          XmlRpcValue two; two[0] = 0.0; two[1] = -9.81; p["gravity_mps2"] = two; }, "gravity_mps2 must be a list of 3"},
        BadParamCase{"EmptyFrame", [](XmlRpcValue& p) { p["fixed_frame"] = ""; }, "fixed_frame is empty"},
        BadParamCase{"SlashedFrame", [](XmlRpcValue& p) { p["fixed_frame"] = "/world"; }, "fixed_frame = '/world'"},
        BadParamCase{"SlashedFollowFrame", [](XmlRpcValue& p) { p["objects"][2]["follow_frame"] = "/link"; }, "objects[2].follow_frame = '/link'"},
        BadParamCase{"NegativeTfWait", [](XmlRpcValue& p) { p["tf_wait_s"] = -0.1; }, "tf_wait_s = -0.1 must be in [0, 60]"},
        BadParamCase{"ZeroCoordinateBound", [](XmlRpcValue& p) { p["max_coordinate_m"] = 0.0; }, "max_coordinate_m = 0 must be in (0, 1e+12]"},
        BadParamCase{"NegativeCoordinateBound", [](XmlRpcValue& p) { p["max_coordinate_m"] = -1.0; }, "max_coordinate_m = -1"},
        BadParamCase{"CoordinateBoundAbove1e12", [](XmlRpcValue& p) { p["max_coordinate_m"] = 2e12; }, "max_coordinate_m = 2e+12"},
        BadParamCase{"InfiniteCoordinateBound", [](XmlRpcValue& p) { p["max_coordinate_m"] = std::numeric_limits<double>::infinity(); }, "max_coordinate_m = inf"},
        BadParamCase{"CoordinateBoundAsString", [](XmlRpcValue& p) { p["max_coordinate_m"] = "far"; }, "max_coordinate_m must be a number"},
        BadParamCase{"ZeroPointLimit", [](XmlRpcValue& p) { p["max_points_per_object"] = 0; }, "max_points_per_object"},
        BadParamCase{"MisspeltTopLevel", [](XmlRpcValue& p) { p["contact_distance"] = 0.1; }, "contact_distance is not a known"},
        BadParamCase{"NegativeForceScale", [](XmlRpcValue& p) { p["markers"]["force_scale_m_per_n"] = -1.0; }, "markers.force_scale_m_per_n = -1"},
        BadParamCase{"NegativeContactStiffness", [](XmlRpcValue& p) { p["objects"][3]["contact_stiffness_n_per_m"] = -5.0; }, "objects[3].contact_stiffness_n_per_m = -5"},
        BadParamCase{"ContactStiffnessOfDynamic", [](XmlRpcValue& p) { p["objects"][1]["contact_stiffness_n_per_m"] = 100.0; }, "objects[1].contact_stiffness_n_per_m is read only by tracked objects (on_cloud track or register), not a dynamic one"},
        BadParamCase{"SelfCollisionOfKinematic", [](XmlRpcValue& p) { p["objects"][2]["self_collision"] = true; }, "objects[2].self_collision needs a dynamic or tracked object, not a kinematic one"},
        BadParamCase{"NegativeSelfRestDistance", [](XmlRpcValue& p) { p["objects"][1]["self_rest_distance_m"] = -0.01; }, "objects[1].self_rest_distance_m = -0.01"},
        BadParamCase{"ContactStiffnessOfKinematic", [](XmlRpcValue& p) { p["objects"][2]["contact_stiffness_n_per_m"] = 100.0; }, "objects[2].contact_stiffness_n_per_m is read only by tracked objects"},
        BadParamCase{"ZeroDiagnosticsPeriod", [](XmlRpcValue& p) { p["diagnostics"]["period_s"] = 0.0; }, "diagnostics.period_s = 0 must be in (0, 3600]"},
        BadParamCase{"ErrorBelowWarning", [](XmlRpcValue& p) { p["diagnostics"]["latency_error_ms"] = 10.0; }, "diagnostics.latency_error_ms is below latency_warn_ms"},
        BadParamCase{"MisspeltDiagnostics", [](XmlRpcValue& p) { p["diagnostics"]["period"] = 1.0; }, "diagnostics.period is not a known"},
        BadParamCase{"NegativeExpectedRate", [](XmlRpcValue& p) { p["objects"][1]["expected_rate_hz"] = -1.0; }, "objects[1].expected_rate_hz = -1"},
        BadParamCase{"MisspeltMarkers", [](XmlRpcValue& p) { p["markers"]["coliding_only"] = true; }, "markers.coliding_only"},
        BadParamCase{"NoObjects", [](XmlRpcValue& p) {
          XmlRpcValue none; none.setSize(0); p["objects"] = none; }, "objects must be a non-empty list"},
        BadParamCase{"ObjectsMissing", [](XmlRpcValue& p) {
          XmlRpcValue kept; kept["rate_hz"] = p["rate_hz"]; p = kept; }, "objects is missing"},
        BadParamCase{"NameMissing", [](XmlRpcValue& p) { p["objects"][1] = XmlRpcValue(); p["objects"][1]["topic"] = "t"; }, "objects[1].name is missing"},
        BadParamCase{"NameNotAGraphName", [](XmlRpcValue& p) { p["objects"][1]["name"] = "my fruit"; }, "objects[1].name = 'my fruit'"},
        BadParamCase{"NameTwice", [](XmlRpcValue& p) { p["objects"][3]["name"] = "fruit"; }, "objects[3].name = 'fruit' is used"},
        BadParamCase{"TopicWithASpace", [](XmlRpcValue& p) { p["objects"][1]["topic"] = "fruit points"; }, "objects[1].topic = 'fruit points' is not a valid topic name"},
        BadParamCase{"TopicTwice", [](XmlRpcValue& p) { p["objects"][1]["topic"] = "/floor/points"; }, "objects[1].topic"},
        BadParamCase{"UnknownMode", [](XmlRpcValue& p) { p["objects"][1]["mode"] = "cubic"; }, "objects[1].mode = 'cubic'"},
        BadParamCase{"StiffnessAboveOne", [](XmlRpcValue& p) { p["objects"][1]["stiffness"] = 1.5; }, "objects[1].stiffness = 1.5"},
        BadParamCase{"ZeroMass", [](XmlRpcValue& p) { p["objects"][1]["mass_kg"] = 0.0; }, "objects[1].mass_kg = 0"},
        BadParamCase{"ZeroClusters", [](XmlRpcValue& p) { p["objects"][1]["clusters"] = 0; }, "objects[1].clusters = 0"},
        BadParamCase{"MassWithoutUnit", [](XmlRpcValue& p) { p["objects"][1]["mass"] = 1.0; }, "objects[1].mass is not a known"},
        BadParamCase{"UnknownOnCloud", [](XmlRpcValue& p) { p["objects"][1]["on_cloud"] = "merge"; }, "objects[1].on_cloud = 'merge'"},
        BadParamCase{"DynamicTracked", [](XmlRpcValue& p) { p["objects"][1]["on_cloud"] = "track"; }, "objects[1].on_cloud = 'track' needs dynamic: false"},
        BadParamCase{"DynamicFollowing", [](XmlRpcValue& p) { p["objects"][1]["follow_frame"] = "link"; }, "objects[1].follow_frame"},
        BadParamCase{"DeformingFollower", [](XmlRpcValue& p) { p["objects"][2]["mode"] = "linear"; }, "objects[2].mode = 'linear'"},
        BadParamCase{"DynamicAsString", [](XmlRpcValue& p) { p["objects"][1]["dynamic"] = "yes"; }, "objects[1].dynamic must be true or false"},
        BadParamCase{"DynamicRegistered", [](XmlRpcValue& p) { p["objects"][1]["on_cloud"] = "register"; }, "objects[1].on_cloud = 'register' needs dynamic: false"},
        BadParamCase{"RegisteredFollowing", [](XmlRpcValue& p) { p["objects"][2]["on_cloud"] = "register"; }, "objects[2].on_cloud = 'register' conflicts with follow_frame"},
        BadParamCase{"ModelFileWhenTracking", [](XmlRpcValue& p) { p["objects"][3]["model_file"] = "hand.ply"; }, "objects[3].model_file is read only with on_cloud: register, not 'track'"},
        BadParamCase{"ModelFileOfStatic", [](XmlRpcValue& p) { p["objects"][0]["model_file"] = "floor.pcd"; }, "objects[0].model_file is read only with on_cloud: register, not 'ignore'"},
        BadParamCase{"ModelFileAsNumber", [](XmlRpcValue& p) { p["objects"][3]["on_cloud"] = "register"; p["objects"][3]["model_file"] = 3; }, "objects[3].model_file must be a string"},
        BadParamCase{"ModelFrameWithoutFile", [](XmlRpcValue& p) { p["objects"][3]["on_cloud"] = "register"; p["objects"][3]["model_frame"] = "camera"; }, "objects[3].model_frame places model_file, which is not set"},
        BadParamCase{"SlashedModelFrame", [](XmlRpcValue& p) { p["objects"][3]["on_cloud"] = "register"; p["objects"][3]["model_file"] = "hand.ply"; p["objects"][3]["model_frame"] = "/camera"; }, "objects[3].model_frame = '/camera' starts with '/'"},
        BadParamCase{"RegisterNotADictionary", [](XmlRpcValue& p) { p["register"] = 5; }, "register must be a dictionary"},
        BadParamCase{"ZeroIterations", [](XmlRpcValue& p) { p["register"]["iterations"] = 0; }, "register.iterations = 0 must be in [1, 1000]"},
        BadParamCase{"IterationsNotInteger", [](XmlRpcValue& p) { p["register"]["iterations"] = 2.5; }, "register.iterations must be an integer"},
        BadParamCase{"ZeroCorrespondence", [](XmlRpcValue& p) { p["register"]["max_correspondence_m"] = 0.0; }, "register.max_correspondence_m = 0 must be in (0, 1000]"},
        BadParamCase{"NegativeCorrespondence", [](XmlRpcValue& p) { p["register"]["max_correspondence_m"] = -0.01; }, "register.max_correspondence_m = -0.01"},
        BadParamCase{"InfiniteCorrespondence", [](XmlRpcValue& p) { p["register"]["max_correspondence_m"] = std::numeric_limits<double>::infinity(); }, "register.max_correspondence_m = inf"},
        BadParamCase{"ZeroCloudPoints", [](XmlRpcValue& p) { p["register"]["max_cloud_points"] = 0; }, "register.max_cloud_points = 0 must be in [1, "},
        BadParamCase{"ZeroModelPoints", [](XmlRpcValue& p) { p["register"]["max_model_points"] = 0; }, "register.max_model_points = 0 must be in [1, "},
        BadParamCase{"NegativeMatchRatio", [](XmlRpcValue& p) { p["register"]["min_match_ratio"] = -0.1; }, "register.min_match_ratio = -0.1 must be in [0, 1]"},
        BadParamCase{"ExcludeNearObjectsAsNumber", [](XmlRpcValue& p) { p["register"]["exclude_near_other_objects"] = 1; }, "register.exclude_near_other_objects must be true or false, got an integer"},
        BadParamCase{"MatchRatioAboveOne", [](XmlRpcValue& p) { p["register"]["min_match_ratio"] = 1.5; }, "register.min_match_ratio = 1.5 must be in [0, 1]"},
        BadParamCase{"MisspeltRegister", [](XmlRpcValue& p) { p["register"]["iteration"] = 3; }, "register.iteration is not a known parameter"},
        BadParamCase{"UnknownCycleOn", [](XmlRpcValue& p) { p["cycle_on"] = "sometimes"; }, "cycle_on = 'sometimes' must be timer or clouds"},
        BadParamCase{"CycleOnAllWithTimer", [](XmlRpcValue& p) { p["cycle_on_all"] = true; }, "cycle_on_all is read only with cycle_on: clouds"},
        BadParamCase{"CycleOnAllAsString", [](XmlRpcValue& p) { p["cycle_on"] = "clouds"; p["cycle_on_all"] = "yes"; }, "cycle_on_all must be true or false"},
        BadParamCase{"StepFromStampsWithTimer", [](XmlRpcValue& p) { p["dt_s"] = "stamp"; }, "dt_s = 'stamp' needs cycle_on: clouds"},
        BadParamCase{"StepAsAnotherWord", [](XmlRpcValue& p) { p["cycle_on"] = "clouds"; p["dt_s"] = "fast"; }, "dt_s = 'fast' must be a number in (0, 0.1] or 'stamp'"},
        BadParamCase{"CloudsWithoutTrackedObject", [](XmlRpcValue& p) { p["cycle_on"] = "clouds"; p["objects"][3]["on_cloud"] = "ignore"; p["objects"][3]["contact_stiffness_n_per_m"] = 0.0; }, "cycle_on = 'clouds' needs an object with on_cloud: track or register"}),
    [](const auto& info) { return info.param.name; });

/// A `level` (absent: std::nullopt) and a `cycle_budget_ms` (absent: std::nullopt), and
/// what the scene's config holds after parsing them.
struct LevelCase {
  std::string name;
  std::optional<XmlRpcValue> level;
  std::optional<XmlRpcValue> budget_ms;
  int scene_level;
  std::optional<double> scene_budget_ms;
};

class LevelParamTest : public ::testing::TestWithParam<LevelCase> {};

TEST_P(LevelParamTest, LevelIsAnIntegerOrAutoWithABudget) {
  const LevelCase& c = GetParam();
  XmlRpcValue params;
  params["objects"][0] = object("ball", "ball/points");
  if (c.level) params["level"] = *c.level;
  if (c.budget_ms) params["cycle_budget_ms"] = *c.budget_ms;
  const SceneConfig scene = parseWithoutWarnings(params).scene;
  EXPECT_EQ(scene.level, c.scene_level);
  EXPECT_EQ(scene.cycle_budget_ms, c.scene_budget_ms);
}

INSTANTIATE_TEST_SUITE_P(
    NodeConfig, LevelParamTest,
    ::testing::Values(
        LevelCase{"Absent", std::nullopt, std::nullopt, -1, std::nullopt},
        LevelCase{"Finest", XmlRpcValue(-1), std::nullopt, -1, std::nullopt},
        LevelCase{"Fixed", XmlRpcValue(4), std::nullopt, 4, std::nullopt},
        LevelCase{"AutoWithABudget", XmlRpcValue("auto"), XmlRpcValue(2.5), -1, 2.5},
        LevelCase{"AutoWithAnIntegerBudget", XmlRpcValue("auto"), XmlRpcValue(8), -1, 8.0},
        LevelCase{"AutoWithTheLargestBudget", XmlRpcValue("auto"), XmlRpcValue(1e6), -1, 1e6}),
    [](const auto& info) { return info.param.name; });

TEST(NodeConfig, CyclesFollowTheTimerUnlessCloudsStartThem) {
  const NodeConfig timer = parseWithoutWarnings(validParams());
  EXPECT_EQ(timer.cycle_on, CycleOn::kTimer);
  EXPECT_FALSE(timer.cycle_on_all);
  EXPECT_FALSE(timer.dt_from_stamps);

  XmlRpcValue params = validParams();
  params["cycle_on"] = "clouds";
  params["cycle_on_all"] = true;
  params["dt_s"] = "stamp";
  const NodeConfig clouds = parseWithoutWarnings(params);
  EXPECT_EQ(clouds.cycle_on, CycleOn::kClouds);
  EXPECT_TRUE(clouds.cycle_on_all);
  EXPECT_TRUE(clouds.dt_from_stamps);
  EXPECT_DOUBLE_EQ(clouds.scene.dt_s, 1.0 / 50.0);  // the first cycle's: 1 / rate_hz

  params["rate_hz"] = 5;
  EXPECT_DOUBLE_EQ(parseWithoutWarnings(params).scene.dt_s, 0.1);  // at most 0.1 s
}

/// A copy of a dictionary without `key` (XmlRpcValue cannot erase a member).
XmlRpcValue without(const XmlRpcValue& dictionary, const std::string& key) {
  XmlRpcValue kept;
  for (auto it = dictionary.begin(); it != dictionary.end(); ++it) {
    if (it->first != key) kept[it->first] = it->second;
  }
  return kept;
}

XmlRpcValue vector3(double x, double y, double z) {
  XmlRpcValue v;
  v[0] = x;
  v[1] = y;
  v[2] = z;
  return v;
}

/// A parameter renamed to carry its unit, given by its new name, its old one or both.
struct RenamedKeyCase {
  std::string name;
  std::string key;
  std::string old_key;
  bool new_given;
  bool old_given;
  XmlRpcValue value;
  std::function<bool(const NodeConfig&)> holds_value;
  std::string warning;  ///< The one warning expected; empty: none.
  std::string error;    ///< Expected in the exception; empty: accepted.
};

class RenamedKeyTest : public ::testing::TestWithParam<RenamedKeyCase> {};

TEST_P(RenamedKeyTest, NewKeyReadsOldKeyWarnsBothAreAnError) {
  const RenamedKeyCase& c = GetParam();
  XmlRpcValue params = without(without(validParams(), c.key), c.old_key);
  if (c.new_given) params[c.key] = c.value;
  if (c.old_given) params[c.old_key] = c.value;
  std::vector<std::string> warnings;
  if (!c.error.empty()) {
    try {
      parseNodeConfig(params, warnings);
      FAIL() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.error), std::string::npos) << e.what();
    }
    return;
  }
  const NodeConfig config = parseNodeConfig(params, warnings);
  EXPECT_TRUE(c.holds_value(config));
  if (c.warning.empty()) {
    EXPECT_TRUE(warnings.empty()) << warnings.front();
  } else {
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0], c.warning);
  }
}

bool stepIs003(const NodeConfig& config) { return config.scene.dt_s == 0.03; }
bool gravityIsLunarX(const NodeConfig& config) {
  return config.scene.gravity_mps2 == Eigen::Vector3d(-1.62, 0.0, 0.0);
}

INSTANTIATE_TEST_SUITE_P(
    NodeConfig, RenamedKeyTest,
    ::testing::Values(
        RenamedKeyCase{"StepByItsName", "dt_s", "dt", true, false, 0.03, stepIs003, "", ""},
        RenamedKeyCase{"StepByItsOldName", "dt_s", "dt", false, true, 0.03, stepIs003,
                       "parameter dt is deprecated: rename it dt_s", ""},
        RenamedKeyCase{
            "StepByBothNames", "dt_s", "dt", true, true, 0.03, stepIs003, "",
            "parameter dt is the deprecated name of dt_s, which is set too: keep only dt_s"},
        RenamedKeyCase{"GravityByItsName", "gravity_mps2", "gravity", true, false,
                       vector3(-1.62, 0.0, 0.0), gravityIsLunarX, "", ""},
        RenamedKeyCase{"GravityByItsOldName", "gravity_mps2", "gravity", false, true,
                       vector3(-1.62, 0.0, 0.0), gravityIsLunarX,
                       "parameter gravity is deprecated: rename it gravity_mps2", ""},
        RenamedKeyCase{"GravityByBothNames", "gravity_mps2", "gravity", true, true,
                       vector3(-1.62, 0.0, 0.0), gravityIsLunarX, "",
                       "parameter gravity is the deprecated name of gravity_mps2, which is set "
                       "too: keep only gravity_mps2"}),
    [](const auto& info) { return info.param.name; });

TEST(NodeConfig, AnOldKeyOutOfRangeIsNamedAsGiven) {
  XmlRpcValue params = without(validParams(), "dt_s");
  params["dt"] = 0.5;
  std::vector<std::string> warnings;
  try {
    parseNodeConfig(params, warnings);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("parameter dt = 0.5 must be in (0, 0.1]"),
              std::string::npos)
        << e.what();
  }
}

TEST(NodeConfig, CoordinateBoundTakesItsRangeEndsAndAnInteger) {
  const std::vector<std::pair<XmlRpcValue, double>> accepted = {
      {XmlRpcValue(1e12), 1e12}, {XmlRpcValue(1e-3), 1e-3}, {XmlRpcValue(100), 100.0}};
  for (const auto& [value, expected] : accepted) {
    XmlRpcValue params = validParams();
    params["max_coordinate_m"] = value;
    EXPECT_EQ(parseWithoutWarnings(params).max_coordinate_m, expected);
  }
}

TEST(NodeConfig, RegisteredObjectsAreTrackedWithTheirModelAndTheRegisterBlock) {
  XmlRpcValue params = validParams();
  params["objects"][3]["on_cloud"] = "register";
  params["objects"][3]["model_file"] = "/models/hand.ply";
  params["objects"][4] = object("sponge", "/camera/points");
  params["objects"][4]["dynamic"] = false;
  params["objects"][4]["on_cloud"] = "register";
  params["objects"][4]["model_file"] = "sponge.pcd";
  params["objects"][4]["model_frame"] = "table";
  params["objects"][5] = object("cloth", "/camera/cloth");
  params["objects"][5]["dynamic"] = false;
  params["objects"][5]["on_cloud"] = "register";
  params["register"]["iterations"] = 7;
  params["register"]["max_correspondence_m"] = 0.02;
  params["register"]["max_cloud_points"] = 1500;
  params["register"]["max_model_points"] = 4000;
  params["register"]["min_match_ratio"] = 1;
  params["register"]["exclude_near_other_objects"] = false;
  const NodeConfig config = parseWithoutWarnings(params);
  ASSERT_EQ(config.objects.size(), 6u);
  for (std::size_t i = 3; i < 6; ++i) {
    EXPECT_EQ(config.objects[i].on_cloud, OnCloud::kRegister) << i;
    EXPECT_EQ(config.objects[i].object.kind, ObjectKind::kTracked) << i;
  }
  EXPECT_EQ(config.objects[3].model_file, "/models/hand.ply");
  EXPECT_EQ(config.objects[3].model_frame, "odom");  // fixed_frame when left out
  EXPECT_EQ(config.objects[4].model_file, "sponge.pcd");
  EXPECT_EQ(config.objects[4].model_frame, "table");
  EXPECT_EQ(config.objects[5].model_file, "");  // the first cloud's finite points
  EXPECT_EQ(config.objects[5].model_frame, "");
  const RegistrationConfig& registration = config.scene.registration;
  EXPECT_EQ(registration.iterations, 7);
  EXPECT_DOUBLE_EQ(registration.max_correspondence_m, 0.02);
  EXPECT_EQ(registration.max_cloud_points, 1500u);
  EXPECT_EQ(registration.max_model_points, 4000u);
  EXPECT_DOUBLE_EQ(registration.min_match_ratio, 1.0);
  EXPECT_FALSE(registration.exclude_near_other_objects);
}

TEST(NodeConfig, RegisterBlockDefaultsAreTheCores) {
  XmlRpcValue params = validParams();
  params["register"]["min_match_ratio"] = 0;
  const RegistrationConfig read = parseWithoutWarnings(params).scene.registration;
  const RegistrationConfig core;
  EXPECT_EQ(read.iterations, core.iterations);
  EXPECT_EQ(read.max_correspondence_m, core.max_correspondence_m);
  EXPECT_EQ(read.max_cloud_points, core.max_cloud_points);
  EXPECT_EQ(read.max_model_points, core.max_model_points);
  EXPECT_EQ(read.exclude_near_other_objects, core.exclude_near_other_objects);
  EXPECT_EQ(read.min_match_ratio, 0.0);
  const RegistrationConfig absent = parseWithoutWarnings(validParams()).scene.registration;
  EXPECT_EQ(absent.min_match_ratio, core.min_match_ratio);
}

TEST(NodeConfig, OnCloudNamesRoundTrip) {
  for (const auto value :
       {OnCloud::kTrack, OnCloud::kRegister, OnCloud::kReset, OnCloud::kIgnore}) {
    EXPECT_EQ(parseOnCloud(toString(value)), value);
  }
  EXPECT_FALSE(parseOnCloud("Track"));
}

/// validParams() with a robot block of `links`.
XmlRpcValue robotParams(const std::vector<std::string>& links) {
  XmlRpcValue params = validParams();
  XmlRpcValue& list = params["robot"]["links"];
  list.setSize(static_cast<int>(links.size()));
  for (std::size_t i = 0; i < links.size(); ++i) list[static_cast<int>(i)] = links[i];
  return params;
}

TEST(NodeConfig, RobotLinksAreKinematicObjectsAfterTheOthersNamedAfterTheLinks) {
  const NodeConfig config =
      parseWithoutWarnings(robotParams({"left_finger", "gripper/right-finger", "2nd"}));
  ASSERT_TRUE(config.robot);
  EXPECT_EQ(config.robot->description_param, "robot_description");
  EXPECT_DOUBLE_EQ(config.robot->point_spacing_m, 0.01) << "contact_distance_m when left out";
  ASSERT_EQ(config.objects.size(), 7u);
  const std::vector<std::string> links = {"left_finger", "gripper/right-finger", "2nd"};
  const std::vector<std::string> names = {"left_finger", "gripper_right_finger", "link_2nd"};
  for (std::size_t i = 0; i < 3; ++i) {
    const ObjectParams& link = config.objects[4 + i];
    EXPECT_EQ(link.object.name, names[i]);
    EXPECT_EQ(link.robot_link, links[i]);
    EXPECT_EQ(link.follow_frame, links[i]);
    EXPECT_EQ(link.topic, "");
    EXPECT_EQ(link.object.kind, ObjectKind::kKinematic);
    EXPECT_EQ(link.object.shape.mode, DeformationMode::kRigid);
  }
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(config.objects[i].robot_link, "") << i;
  EXPECT_FALSE(parseWithoutWarnings(validParams()).robot) << "no robot block, no robot";
}

TEST(NodeConfig, RobotBlockReadsItsParameterAndSpacing) {
  XmlRpcValue params = robotParams({"finger"});
  params["robot"]["description_param"] = "/arm/robot_description";
  params["robot"]["point_spacing_m"] = 0.004;
  const NodeConfig config = parseWithoutWarnings(params);
  EXPECT_EQ(config.robot->description_param, "/arm/robot_description");
  EXPECT_DOUBLE_EQ(config.robot->point_spacing_m, 0.004);
}

using BadRobotCase = BadParamCase;

class BadRobotTest : public ::testing::TestWithParam<BadRobotCase> {};

TEST_P(BadRobotTest, ThrowsNamingTheKey) {
  expectRefused(robotParams({"left_finger", "right_finger"}), GetParam());
}

INSTANTIATE_TEST_SUITE_P(
    NodeConfig, BadRobotTest,
    ::testing::Values(
        BadRobotCase{"NotADictionary", [](XmlRpcValue& p) { p["robot"] = "left_finger"; },
                     "parameter robot must be a dictionary"},
        BadRobotCase{"UnknownKey", [](XmlRpcValue& p) { p["robot"]["link"] = "a"; },
                     "robot.link is not a known parameter"},
        BadRobotCase{"NoLinks",
                     [](XmlRpcValue& p) {
                       p["robot"]["point_spacing_m"] = 0.004;
                       p["robot"] = without(p["robot"], "links");
                     },
                     "robot.links is missing"},
        BadRobotCase{"LinksNotAList", [](XmlRpcValue& p) { p["robot"]["links"] = "finger"; },
                     "robot.links must be a non-empty list"},
        BadRobotCase{"EmptyLinks",
                     [](XmlRpcValue& p) {
                       p["robot"]["links"] = XmlRpcValue();
                       p["robot"]["links"].setSize(0);  // setSize only grows a list
                     },
                     "robot.links must be a non-empty list"},
        BadRobotCase{"LinkNotAString", [](XmlRpcValue& p) { p["robot"]["links"][1] = 3; },
                     "robot.links[1] must be a link name"},
        BadRobotCase{"EmptyLink", [](XmlRpcValue& p) { p["robot"]["links"][0] = ""; },
                     "robot.links[0] is empty"},
        BadRobotCase{"LinkWithSlash", [](XmlRpcValue& p) { p["robot"]["links"][1] = "/finger"; },
                     "robot.links[1] = '/finger' starts with '/'"},
        BadRobotCase{"LinkTwice", [](XmlRpcValue& p) { p["robot"]["links"][2] = "left_finger"; },
                     "robot.links[2] = 'left_finger' is listed twice"},
        BadRobotCase{"NameOfAnObject", [](XmlRpcValue& p) { p["robot"]["links"][1] = "jaw"; },
                     "robot.links[1] = 'jaw' would be the object 'jaw'"},
        BadRobotCase{"MappedNamesCollide",
                     [](XmlRpcValue& p) { p["robot"]["links"][1] = "left-finger"; },
                     "robot.links[1] = 'left-finger' would be the object 'left_finger'"},
        BadRobotCase{"ZeroSpacing", [](XmlRpcValue& p) { p["robot"]["point_spacing_m"] = 0.0; },
                     "robot.point_spacing_m = 0"},
        BadRobotCase{"EmptyDescription",
                     [](XmlRpcValue& p) { p["robot"]["description_param"] = ""; },
                     "robot.description_param is empty"},
        BadRobotCase{"BadDescriptionName",
                     [](XmlRpcValue& p) { p["robot"]["description_param"] = "robot description"; },
                     "robot.description_param = 'robot description' is not a parameter name"}),
    [](const ::testing::TestParamInfo<BadRobotCase>& info) { return info.param.name; });

TEST(NodeConfig, DistancePairsNameTwoObjectsWithTheirMaximumAndLevel) {
  XmlRpcValue params = validParams();
  params["distance_pairs"][0]["object_a"] = "fruit";
  params["distance_pairs"][0]["object_b"] = "jaw";
  params["distance_pairs"][0]["max_distance_m"] = 0.2;
  params["distance_pairs"][0]["level"] = 2;
  params["distance_pairs"][1]["object_a"] = "hand";
  params["distance_pairs"][1]["object_b"] = "floor";
  const NodeConfig config = parseWithoutWarnings(params);
  ASSERT_EQ(config.distance_pairs.size(), 2u);
  EXPECT_EQ(config.distance_pairs[0].object_a, "fruit");
  EXPECT_EQ(config.distance_pairs[0].object_b, "jaw");
  EXPECT_DOUBLE_EQ(config.distance_pairs[0].max_distance_m, 0.2);
  EXPECT_EQ(config.distance_pairs[0].level, 2);
  EXPECT_DOUBLE_EQ(config.distance_pairs[1].max_distance_m, 1.0) << "the default";
  EXPECT_EQ(config.distance_pairs[1].level, -1) << "the finest by default";
  EXPECT_TRUE(parseWithoutWarnings(validParams()).distance_pairs.empty());
}

// What the reconfigure servers leave under ~reconfigure is theirs: a restarted node starts
// from the config again.
TEST(NodeConfig, TheReconfigureServersNamespaceIsLeftAlone) {
  XmlRpcValue params = validParams();
  params["reconfigure"]["friction"] = 0.9;
  params["reconfigure"]["objects"]["fruit"]["stiffness"] = 0.1;
  const NodeConfig config = parseWithoutWarnings(params);
  EXPECT_EQ(config.scene.friction, parseWithoutWarnings(validParams()).scene.friction);
  EXPECT_EQ(config.objects[1].object.shape.stiffness, 0.8);
}

TEST(NodeConfig, BadDistancePairsAreRefusedNamingTheKey) {
  const auto pair = [](const char* a, const char* b) {
    XmlRpcValue value;
    value["object_a"] = a;
    value["object_b"] = b;
    return value;
  };
  const BadParamCase cases[] = {
      {"NotAList", [](XmlRpcValue& p) { p["distance_pairs"] = "fruit"; },
       "distance_pairs must be a list"},
      {"Unknown", [&](XmlRpcValue& p) { p["distance_pairs"][0] = pair("fruit", "pear"); },
       "distance_pairs[0].object_b = 'pear' is not an object"},
      {"Missing", [&](XmlRpcValue& p) { p["distance_pairs"][0]["object_a"] = "fruit"; },
       "distance_pairs[0].object_b is missing"},
      {"Same", [&](XmlRpcValue& p) { p["distance_pairs"][0] = pair("jaw", "jaw"); },
       "distance_pairs[0].object_b = 'jaw' is object_a too"},
      {"NegativeMaximum",
       [&](XmlRpcValue& p) {
         p["distance_pairs"][0] = pair("fruit", "jaw");
         p["distance_pairs"][0]["max_distance_m"] = -0.1;
       },
       "distance_pairs[0].max_distance_m = -0.1"},
      {"LevelBelowFinest",
       [&](XmlRpcValue& p) {
         p["distance_pairs"][0] = pair("fruit", "jaw");
         p["distance_pairs"][0]["level"] = -2;
       },
       "distance_pairs[0].level = -2"},
      {"Misspelt",
       [&](XmlRpcValue& p) {
         p["distance_pairs"][0] = pair("fruit", "jaw");
         p["distance_pairs"][0]["max_distance"] = 0.1;
       },
       "distance_pairs[0].max_distance is not a known"},
  };
  for (const BadParamCase& c : cases) expectRefused(validParams(), c);
}

TEST(NodeConfig, RobotLinkObjectNamesAreValidObjectNames) {
  EXPECT_EQ(robotLinkObjectName("finger"), "finger");
  EXPECT_EQ(robotLinkObjectName("panda_leftfinger"), "panda_leftfinger");
  EXPECT_EQ(robotLinkObjectName("arm/link-7.tip"), "arm_link_7_tip");
  EXPECT_EQ(robotLinkObjectName("_base"), "link__base");
  EXPECT_EQ(robotLinkObjectName("7"), "link_7");
}

}  // namespace
}  // namespace deformable_collision
