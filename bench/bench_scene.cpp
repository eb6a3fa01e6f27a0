// The built-in scenes of the paper's section 7, one scene per process (scripts/run_benchmarks
// runs each, so peak memory is per scene); rows are appended to CSV files in results_dir.
//   s2 results_dir [settle=150] [cycles=100]
//     The pile (300 soft objects, 131k points) settled at the finest level, then `cycles` cycles at
//     each level from 1 to the finest, each from the same settled state (rebuilt with the same
//     seeds and checked equal), the levels taking turns of a tenth of their cycles: contacts,
//     detection, response, and the error against the finest level: (i) coverage, the largest
//     distance from a finest-level contact of the settled state to the nearest contact of the same
//     object pair at this level; (ii) the RMS deviation of the soft objects' points from the
//     finest-level run after the cycles, over their mean diameter; the whole cycle's time (shape
//     matching included), and the state each level leaves: mean point speed, and how far point
//     pairs of two soft objects lie inside half the contact distance (largest and mean, over the
//     finest level's contacts). Then `level: auto` (Scene::setCycleBudget) for 300 cycles from
//     the same settled state, with a budget of half the finest level's detection + response in this
//     run: the share of cycles within it (of all, and of those after the first 20, in which the
//     level climbs from 0), the levels picked and the mean cost. Last, rest: the pile dropped and
//     run at each level from 0 to the finest for 300 cycles from the start, the mean point speed
//     over its last 50 cycles (mean, largest, and after the last) and its end state's depths. ->
//     s2.csv, s2_state.csv, s2_auto.csv, s2_rest.csv, baselines.csv
//   s3 results_dir [settle=150] [cycles=100]
//     Three objects (19k points) at the finest level, stage by stage, with the conversion
//     of every object's points to a PointCloud2 as the node publishes them. -> s3.csv,
//     baselines.csv
//   forces results_dir [cycles=300]
//     The cost of contact forces: the pile (S2, finest level, settled 150 cycles) and the
//     gripper (driven as the demo drives it) run `cycles` cycles with contact_forces on, with
//     the pair summaries and every kinematic object's wrench, and the same cycles with it off,
//     each from a fresh build of the scene, in turns of a tenth of the cycles: the mean whole
//     cycle of each and their ratio. -> forces.csv
//   memory scene results_dir [cycles=150]
//     Peak resident memory of a built-in scene (two_objects at 160k points, as S1's
//     largest, or pile, three_objects at their default count) -> memory.csv
// The baseline of a scene's times: a full bottom-up refit of its soft objects' hierarchies
// on the same state, in the same process.
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/response/contact_totals.h"
#include "deformable_collision/ros/point_cloud_conversion.h"
#include "deformable_collision/scenes/demo_scenes.h"

namespace dc = deformable_collision;
namespace db = deformable_collision::bench;

namespace {

struct Means {
  double contacts = 0, shape_matching_ms = 0, detection_ms = 0, response_ms = 0;
};

/// Runs `cycles` cycles and adds their stats to the means `m` of `total_cycles` cycles.
void addCycles(dc::Scene& scene, int cycles, int total_cycles, Means& m) {
  for (int c = 0; c < cycles; ++c) {
    scene.cycle();
    const dc::CycleStats& s = scene.stats();
    m.contacts += double(s.contacts) / total_cycles;
    m.shape_matching_ms += s.shape_matching_ms / total_cycles;
    m.detection_ms += s.detection_ms / total_cycles;
    m.response_ms += s.response_ms / total_cycles;
  }
}

std::vector<std::size_t> softObjects(const dc::Scene& scene) {
  std::vector<std::size_t> soft;
  for (std::size_t i = 0; i < scene.objectCount(); ++i) {
    if (scene.objectConfig(i).kind == dc::ObjectKind::kDynamic) soft.push_back(i);
  }
  return soft;
}

std::vector<Eigen::Vector3d> softPoints(const dc::Scene& scene) {
  std::vector<Eigen::Vector3d> points;
  for (const std::size_t i : softObjects(scene)) {
    const auto& p = scene.body(i).positions();
    points.insert(points.end(), p.begin(), p.end());
  }
  return points;
}

/// Mean time of a full bottom-up refit of every soft object's hierarchy on the current
/// state, with trees of the scene's configuration.
double fullRefitMs(const dc::Scene& scene) {
  std::vector<dc::SphereTree> trees;
  for (const std::size_t i : softObjects(scene))
    trees.emplace_back(scene.body(i), scene.config().tree);
  constexpr int kRepeats = 20;
  const auto start = db::Clock::now();
  for (int r = 0; r < kRepeats; ++r) {
    for (dc::SphereTree& tree : trees) tree.beginCycle(dc::SphereUpdate::kBottomUpRefit);
  }
  return db::millisecondsSince(start) / kRepeats;
}

void appendBaseline(const std::string& results_dir, const char* scene, double ms) {
  db::CsvAppender csv(results_dir + "/baselines.csv", "scene,baseline,ms");
  std::fprintf(csv.file(), "%s,full_bottom_up_refit,%.5f\n", scene, ms);
}

std::unique_ptr<dc::Scene> settled(dc::DemoScene kind, int settle) {
  auto scene = dc::makeDemoScene(kind);
  for (int c = 0; c < settle; ++c) scene->cycle();
  return scene;
}

/// The largest distance from a contact at `fine` to the nearest contact of the same object
/// pair at `coarse`; infinite if a pair has none there.
double coverageError(const std::vector<dc::SceneContact>& fine,
                     const std::vector<dc::SceneContact>& coarse) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Eigen::Vector3d>> by_pair;
  for (const dc::SceneContact& c : coarse) {
    by_pair[std::minmax(c.object_a, c.object_b)].push_back(c.contact.position);
  }
  double worst = 0.0;
  for (const dc::SceneContact& c : fine) {
    const auto found = by_pair.find(std::minmax(c.object_a, c.object_b));
    if (found == by_pair.end()) return std::numeric_limits<double>::infinity();
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : found->second) {
      nearest = std::min(nearest, (p - c.contact.position).squaredNorm());
    }
    worst = std::max(worst, std::sqrt(nearest));
  }
  return worst;
}

/// The settled pile's soft objects: their mean diameter (what errors are relative to) and
/// how fast their points still move (what the deviations grow from).
struct PileState {
  double diameter_m = 0.0;
  double speed_mps = 0.0;
};

PileState describePile(const dc::Scene& pile) {
  PileState state;
  const std::vector<std::size_t> soft = softObjects(pile);
  for (const std::size_t i : soft) {
    state.diameter_m += 2.0 * dc::smallestEnclosingSphere(pile.body(i).restPositions()).radius;
  }
  state.diameter_m /= double(soft.size());
  state.speed_mps = dc::meanDynamicPointSpeed(pile);
  return state;
}

/// Per level below the finest, how far the finest contacts are from the level's (coverage).
std::vector<double> coverageByLevel(dc::Scene& scene) {
  const int finest = scene.maxLevel();
  std::vector<dc::SceneContact> fine, coarse;
  scene.contactsAt(finest, std::nullopt, std::nullopt, fine);
  std::vector<double> coverage(finest + 1, 0.0);
  for (int level = 1; level < finest; ++level) {
    scene.contactsAt(level, std::nullopt, std::nullopt, coarse);
    coverage[level] = coverageError(fine, coarse);
  }
  return coverage;
}

/// The state a level's run leaves: how fast the soft points still move, and how far point
/// pairs of two soft objects lie inside half the contact distance (where the response puts
/// touching objects), from the finest level's contacts on that state.
struct LevelEnd {
  double speed_mps = 0.0;
  double deepest_m = 0.0;
  double mean_depth_m = 0.0;
};

LevelEnd describeEnd(dc::Scene& scene) {
  LevelEnd end;
  end.speed_mps = dc::meanDynamicPointSpeed(scene);
  std::vector<dc::SceneContact> contacts;
  scene.contactsAt(scene.maxLevel(), std::nullopt, std::nullopt, contacts);
  const double half = 0.5 * scene.config().contact_distance_m;
  std::size_t pairs = 0;
  for (const dc::SceneContact& c : contacts) {
    if (scene.objectConfig(c.object_a).kind != dc::ObjectKind::kDynamic ||
        scene.objectConfig(c.object_b).kind != dc::ObjectKind::kDynamic) {
      continue;
    }
    // At the leaves depth_m is the contact distance less the closest pair's distance.
    const double inside = std::max(0.0, c.contact.depth_m - half);
    end.deepest_m = std::max(end.deepest_m, inside);
    end.mean_depth_m += inside;
    ++pairs;
  }
  if (pairs > 0) end.mean_depth_m /= double(pairs);
  return end;
}

/// Every level from the same settled pile (`finest_scene` is it at the finest level): its
/// means, its end state and its points' RMS distance from the finest run's, relative to the
/// diameter. The levels run in turns of a tenth of their cycles each, so that a slow spell of
/// the host (a shared virtual machine's can last seconds and cost half again) falls on every
/// level alike rather than on the one running then. False if the settled piles differ,
/// which would make the comparison meaningless.
bool runLevels(std::unique_ptr<dc::Scene> finest_scene, int settle, int cycles,
               const std::vector<Eigen::Vector3d>& settled_points, double diameter_m,
               std::vector<Means>& means, std::vector<LevelEnd>& ends,
               std::vector<double>& rms_rel) {
  const int finest = static_cast<int>(means.size()) - 1;
  std::vector<std::unique_ptr<dc::Scene>> at_level(finest + 1);
  at_level[finest] = std::move(finest_scene);
  for (int level = 1; level < finest; ++level) {
    at_level[level] = settled(dc::DemoScene::kPile, settle);
    if (softPoints(*at_level[level]) != settled_points) {
      std::fprintf(stderr, "bench_scene s2: the settled pile differs between runs\n");
      return false;
    }
    at_level[level]->setLevel(level);
  }
  constexpr int kTurns = 10;
  for (int turn = 0; turn < kTurns; ++turn) {
    const int turn_cycles = cycles * (turn + 1) / kTurns - cycles * turn / kTurns;
    for (int level = 1; level <= finest; ++level) {
      addCycles(*at_level[level], turn_cycles, cycles, means[level]);
    }
  }
  const std::vector<Eigen::Vector3d> reference_points = softPoints(*at_level[finest]);
  for (int level = 1; level <= finest; ++level) {
    ends[level] = describeEnd(*at_level[level]);
    const std::vector<Eigen::Vector3d> points = softPoints(*at_level[level]);
    double squared = 0.0;
    for (std::size_t p = 0; p < points.size(); ++p)
      squared += (points[p] - reference_points[p]).squaredNorm();
    rms_rel[level] = std::sqrt(squared / double(points.size())) / diameter_m;
  }
  return true;
}

/// The pile dropped and run at one level for kCycles: whether it comes to rest there.
struct RestRun {
  static constexpr int kCycles = 300;
  static constexpr int kLateCycles = 50;  ///< Over which the speed is taken.
  double late_mean_speed_mps = 0.0;
  double late_largest_speed_mps = 0.0;
  LevelEnd end;
};

RestRun runRest(int level) {
  auto scene = dc::makeDemoScene(dc::DemoScene::kPile);
  scene->setLevel(level);
  RestRun run;
  for (int c = 0; c < RestRun::kCycles; ++c) {
    scene->cycle();
    if (c < RestRun::kCycles - RestRun::kLateCycles) continue;
    const double speed = dc::meanDynamicPointSpeed(*scene);
    run.late_mean_speed_mps += speed / RestRun::kLateCycles;
    run.late_largest_speed_mps = std::max(run.late_largest_speed_mps, speed);
  }
  run.end = describeEnd(*scene);
  return run;
}

void reportRest(const std::string& results_dir, int finest) {
  std::printf(
      "\nrest: the pile dropped and run at each level for %d cycles; mean point speed over the "
      "last %d\n\n| level | mean speed m/s | largest m/s | after the last m/s | deepest m | "
      "mean depth m |\n|---|---|---|---|---|---|\n",
      RestRun::kCycles, RestRun::kLateCycles);
  db::CsvAppender csv(results_dir + "/s2_rest.csv",
                      "level,cycles,late_cycles,late_mean_speed_mps,late_largest_speed_mps,"
                      "end_speed_mps,deepest_m,mean_depth_m");
  for (int level = 0; level <= finest; ++level) {
    const RestRun run = runRest(level);
    std::printf("| %d | %.4f | %.4f | %.4f | %.4f | %.5f |\n", level, run.late_mean_speed_mps,
                run.late_largest_speed_mps, run.end.speed_mps, run.end.deepest_m,
                run.end.mean_depth_m);
    std::fprintf(csv.file(), "%d,%d,%d,%.6f,%.6f,%.6f,%.6f,%.6f\n", level, RestRun::kCycles,
                 RestRun::kLateCycles, run.late_mean_speed_mps, run.late_largest_speed_mps,
                 run.end.speed_mps, run.end.deepest_m, run.end.mean_depth_m);
  }
}

/// Cycles in budget mode from the settled pile: what they cost and which levels they ran at.
/// kCycles, so that the climb from level 0 and the tries of finer levels (every 50 to 200
/// cycles) weigh in as they do in a long run.
struct AutoRun {
  static constexpr int kCycles = 300;
  static constexpr int kClimbCycles = 20;
  int cycles_within_budget = 0;
  int climbed_cycles_within_budget = 0;  ///< Of the cycles after the first kClimbCycles.
  double mean_total_ms = 0.0;
  std::vector<int> cycles_at_level;
};

std::optional<AutoRun> runAuto(int settle, const std::vector<Eigen::Vector3d>& settled_points,
                               double budget_ms) {
  constexpr int cycles = AutoRun::kCycles;
  auto scene = settled(dc::DemoScene::kPile, settle);
  if (softPoints(*scene) != settled_points) {
    std::fprintf(stderr, "bench_scene s2: the settled pile differs between runs\n");
    return std::nullopt;
  }
  scene->setCycleBudget(budget_ms);
  AutoRun run;
  run.cycles_at_level.assign(scene->maxLevel() + 1, 0);
  for (int c = 0; c < cycles; ++c) {
    scene->cycle();
    const dc::CycleStats& s = scene->stats();
    const double total = s.detection_ms + s.response_ms;
    run.cycles_within_budget += total <= budget_ms;
    if (c >= AutoRun::kClimbCycles) run.climbed_cycles_within_budget += total <= budget_ms;
    run.mean_total_ms += total / cycles;
    ++run.cycles_at_level[s.level];
  }
  return run;
}

/// The auto run's line and s2_auto.csv: levels as "level:cycles" pairs joined by ';'.
void reportAuto(const std::string& results_dir, const AutoRun& run, double budget_ms,
                double finest_total_ms) {
  constexpr int cycles = AutoRun::kCycles;
  int lowest = -1, highest = 0;
  double mean_level = 0.0;
  std::string levels;
  for (int level = 0; level < int(run.cycles_at_level.size()); ++level) {
    const int at = run.cycles_at_level[level];
    if (at == 0) continue;
    if (lowest < 0) lowest = level;
    highest = level;
    mean_level += double(level) * at / cycles;
    levels += (levels.empty() ? "" : ";") + std::to_string(level) + ":" + std::to_string(at);
  }
  const double within = double(run.cycles_within_budget) / cycles;
  const int climbed = std::max(cycles - AutoRun::kClimbCycles, 1);
  const double within_climbed = double(run.climbed_cycles_within_budget) / climbed;
  std::printf(
      "\nlevel auto: budget %.3f ms (half the finest level's %.3f ms), %d cycles: %.1f%% within "
      "budget (%.1f%% after the first %d), levels %d / %.2f / %d (min / mean / max), cycles per "
      "level %s, mean detection + response %.3f ms\n",
      budget_ms, finest_total_ms, cycles, 100.0 * within, 100.0 * within_climbed,
      AutoRun::kClimbCycles, lowest, mean_level, highest, levels.c_str(), run.mean_total_ms);
  db::CsvAppender csv(results_dir + "/s2_auto.csv",
                      "budget_ms,finest_total_ms,cycles,within_budget_share,"
                      "within_budget_share_after_climb,climb_cycles,level_min,level_mean,"
                      "level_max,cycles_per_level,mean_total_ms");
  std::fprintf(csv.file(), "%.5f,%.5f,%d,%.4f,%.4f,%d,%d,%.3f,%d,%s,%.5f\n", budget_ms,
               finest_total_ms, cycles, within, within_climbed, AutoRun::kClimbCycles, lowest,
               mean_level, highest, levels.c_str(), run.mean_total_ms);
}

int runS2(const std::string& results_dir, int settle, int cycles) {
  auto reference = settled(dc::DemoScene::kPile, settle);
  const int finest = reference->maxLevel();
  const std::vector<Eigen::Vector3d> settled_points = softPoints(*reference);
  const PileState pile = describePile(*reference);
  const double baseline_ms = fullRefitMs(*reference);
  appendBaseline(results_dir, "s2", baseline_ms);
  {
    db::CsvAppender state(
        results_dir + "/s2_state.csv",
        "soft_points,settle_cycles,cycles_per_level,mean_diameter_m,mean_point_speed_mps");
    std::fprintf(state.file(), "%zu,%d,%d,%.5f,%.5f\n", settled_points.size(), settle, cycles,
                 pile.diameter_m, pile.speed_mps);
  }
  const std::vector<double> coverage = coverageByLevel(*reference);
  std::vector<Means> means(finest + 1);
  std::vector<LevelEnd> ends(finest + 1);
  std::vector<double> rms_rel(finest + 1, 0.0);
  if (!runLevels(std::move(reference), settle, cycles, settled_points, pile.diameter_m, means, ends,
                 rms_rel)) {
    return 1;
  }

  std::printf(
      "S2 pile: %zu soft points, settled for %d cycles, then %d cycles per level; "
      "mean object diameter %.4f m, mean point speed when settled %.3f m/s; full refit "
      "baseline %.3f ms\n\n",
      settled_points.size(), settle, cycles, pile.diameter_m, pile.speed_mps, baseline_ms);
  std::printf(
      "| level | contacts | detection ms | response ms | total ms | / baseline | whole cycle ms | "
      "coverage m | rms rel | speed after m/s | deepest m | mean depth m |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  db::CsvAppender csv(results_dir + "/s2.csv",
                      "level,contacts,detection_ms,response_ms,total_ms,shape_matching_ms,"
                      "whole_cycle_ms,coverage_error_m,rms_error_rel,speed_after_mps,"
                      "deepest_m,mean_depth_m");
  for (int level = 1; level <= finest; ++level) {
    const Means& m = means[level];
    const LevelEnd& e = ends[level];
    const double total = m.detection_ms + m.response_ms;
    const double whole = total + m.shape_matching_ms;
    std::printf(
        "| %d | %.0f | %.3f | %.3f | %.3f | %.3f | %.3f | %.4f | %.5f | %.4f | %.4f | %.5f |\n",
        level, m.contacts, m.detection_ms, m.response_ms, total, total / baseline_ms, whole,
        coverage[level], rms_rel[level], e.speed_mps, e.deepest_m, e.mean_depth_m);
    std::fprintf(csv.file(), "%d,%.1f,%.5f,%.5f,%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.6f\n", level,
                 m.contacts, m.detection_ms, m.response_ms, total, m.shape_matching_ms, whole,
                 coverage[level], rms_rel[level], e.speed_mps, e.deepest_m, e.mean_depth_m);
  }
  const double finest_total_ms = means[finest].detection_ms + means[finest].response_ms;
  const double budget_ms = 0.5 * finest_total_ms;
  const std::optional<AutoRun> run = runAuto(settle, settled_points, budget_ms);
  if (!run) return 1;
  reportAuto(results_dir, *run, budget_ms, finest_total_ms);
  reportRest(results_dir, finest);
  return 0;
}

int runS3(const std::string& results_dir, int settle, int cycles) {
  auto scene = settled(dc::DemoScene::kThreeObjects, settle);
  const double baseline_ms = fullRefitMs(*scene);
  appendBaseline(results_dir, "s3", baseline_ms);
  double conversion_ms = 0.0, whole_ms = 0.0;
  Means m;
  for (int c = 0; c < cycles; ++c) {
    const auto start = db::Clock::now();
    scene->cycle();
    // As the node publishes: a new message per object and cycle.
    const auto converting = db::Clock::now();
    for (std::size_t i = 0; i < scene->objectCount(); ++i) {
      sensor_msgs::PointCloud2 cloud;
      dc::writeCloudPoints(scene->body(i).positions(), cloud);
    }
    conversion_ms += db::millisecondsSince(converting) / cycles;
    whole_ms += db::millisecondsSince(start) / cycles;
    const dc::CycleStats& s = scene->stats();
    m.shape_matching_ms += s.shape_matching_ms / cycles;
    m.detection_ms += s.detection_ms / cycles;
    m.response_ms += s.response_ms / cycles;
    m.contacts += double(s.contacts) / cycles;
  }
  std::size_t points = 0;
  for (std::size_t i = 0; i < scene->objectCount(); ++i) points += scene->body(i).pointCount();
  std::printf(
      "S3 three objects: %zu points, settled for %d cycles, mean of %d, %.0f contacts; "
      "full refit baseline %.3f ms\n\n| stage | ms | / baseline |\n|---|---|---|\n",
      points, settle, cycles, m.contacts, baseline_ms);
  db::CsvAppender csv(results_dir + "/s3.csv", "stage,ms");
  const std::pair<const char*, double> stages[] = {{"deformation", m.shape_matching_ms},
                                                   {"detection", m.detection_ms},
                                                   {"response", m.response_ms},
                                                   {"conversion_to_pointcloud2", conversion_ms},
                                                   {"whole_cycle", whole_ms}};
  for (const auto& [stage, ms] : stages) {
    std::printf("| %s | %.4f | %.3f |\n", stage, ms, ms / baseline_ms);
    std::fprintf(csv.file(), "%s,%.5f\n", stage, ms);
  }
  return 0;
}

/// One of the forces benchmark's two runs of a scene: its state, time and cycle count.
struct ForcesRun {
  std::unique_ptr<dc::Scene> scene;
  bool forces = true;
  int cycles = 0;
  double ms = 0.0;
  std::vector<dc::PairSummary> summaries;
};

ForcesRun startForcesRun(dc::DemoScene kind, bool forces, int settle) {
  dc::SceneConfig config;
  config.contact_forces = forces;
  ForcesRun run;
  run.scene = dc::makeDemoScene(kind, 0, config);
  run.forces = forces;
  for (int c = 0; c < settle; ++c) {
    dc::driveDemoScene(kind, *run.scene, c * run.scene->config().dt_s);
    run.scene->cycle();
  }
  return run;
}

/// `cycles` more cycles of the run: with forces, what a node makes of them too.
void continueForcesRun(dc::DemoScene kind, ForcesRun& run, int settle, int cycles) {
  dc::Scene& scene = *run.scene;
  for (int c = 0; c < cycles; ++c, ++run.cycles) {
    dc::driveDemoScene(kind, scene, (settle + run.cycles) * scene.config().dt_s);
    const auto start = db::Clock::now();
    scene.cycle();
    if (run.forces) {
      dc::summarizePairs(scene.contacts(), run.summaries);
      for (std::uint32_t o = 0; o < scene.objectCount(); ++o) {
        if (scene.objectConfig(o).kind != dc::ObjectKind::kKinematic) continue;
        const dc::Wrench wrench = dc::wrenchOn(scene.contacts(), o, Eigen::Isometry3d::Identity());
        if (!wrench.force_n.allFinite()) std::abort();
      }
    }
    run.ms += db::millisecondsSince(start);
  }
}

int runForces(const std::string& results_dir, int cycles) {
  db::CsvAppender csv(results_dir + "/forces.csv",
                      "scene,level,cycles,with_forces_ms,without_forces_ms,ratio");
  constexpr int kSettle = 150;
  for (const dc::DemoScene kind : {dc::DemoScene::kPile, dc::DemoScene::kGripper}) {
    std::array<ForcesRun, 2> runs{startForcesRun(kind, true, kSettle),
                                  startForcesRun(kind, false, kSettle)};
    const int turn = std::max(1, cycles / 10);
    for (int done = 0; done < cycles; done += turn) {
      for (ForcesRun& run : runs) continueForcesRun(kind, run, kSettle, turn);
    }
    const double with_ms = runs[0].ms / runs[0].cycles;
    const double without_ms = runs[1].ms / runs[1].cycles;
    const int level = runs[0].scene->level();
    std::printf("forces %s level %d: %.4f ms a cycle with forces, %.4f without: %.3fx\n",
                dc::toString(kind), level, with_ms, without_ms, with_ms / without_ms);
    std::fprintf(csv.file(), "%s,%d,%d,%.5f,%.5f,%.4f\n", dc::toString(kind), level, runs[0].cycles,
                 with_ms, without_ms, with_ms / without_ms);
  }
  return 0;
}

int runMemory(const std::string& name, const std::string& results_dir, int cycles) {
  const auto kind = dc::parseDemoScene(name);
  if (!kind) {
    std::fprintf(stderr, "bench_scene memory: unknown scene '%s'\n", name.c_str());
    return 2;
  }
  const long before = db::peakResidentBytes();
  const std::size_t requested = *kind == dc::DemoScene::kTwoObjects ? 160000 : 0;
  auto scene = dc::makeDemoScene(*kind, requested);
  for (int c = 0; c < cycles; ++c) scene->cycle();
  const long peak = db::peakResidentBytes();
  std::size_t points = 0;
  for (std::size_t i = 0; i < scene->objectCount(); ++i) points += scene->body(i).pointCount();
  const double per_point = double(peak - before) / double(points);
  std::printf(
      "%s: %zu points, peak resident %.1f MB (%.1f MB before the scene), %.0f bytes per point\n",
      name.c_str(), points, peak / 1e6, before / 1e6, per_point);
  db::CsvAppender csv(results_dir + "/memory.csv",
                      "scene,points,rss_before_bytes,peak_rss_bytes,bytes_per_point");
  std::fprintf(csv.file(), "%s,%zu,%ld,%ld,%.0f\n", name.c_str(), points, before, peak, per_point);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  const auto intArg = [&](int index, int fallback) {
    return argc > index ? std::atoi(argv[index]) : fallback;
  };
  if (mode == "s2" && argc > 2) return runS2(argv[2], intArg(3, 150), intArg(4, 100));
  if (mode == "s3" && argc > 2) return runS3(argv[2], intArg(3, 150), intArg(4, 100));
  if (mode == "memory" && argc > 3) return runMemory(argv[2], argv[3], intArg(4, 150));
  if (mode == "forces" && argc > 2) return runForces(argv[2], intArg(3, 300));
  std::fprintf(stderr,
               "usage: bench_scene s2 results_dir [settle=150] [cycles=100]\n"
               "       bench_scene s3 results_dir [settle=150] [cycles=100]\n"
               "       bench_scene memory two_objects|pile|three_objects results_dir [cycles=150]\n"
               "       bench_scene forces results_dir [cycles=300]\n");
  return 2;
}
