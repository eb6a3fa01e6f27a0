// The scene's detection: the broad phase gives the candidate object pairs, the hierarchy
// query finds each pair's contacts, and pairs that did not change keep theirs.
#include <algorithm>

#include "deformable_collision/core/scene/scene.h"

#include "deformable_collision/core/scene/detail/pair_query_lanes.h"
#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {
namespace {

/// Writes a query's contacts straight into the scene's list, tagged with their objects.
class PairContacts final : public ContactSink {
 public:
  PairContacts(std::vector<SceneContact>& contacts, std::uint32_t object_a, std::uint32_t object_b)
      : contacts_(contacts), object_a_(object_a), object_b_(object_b) {}
  void add(const SphereContact& contact) override {
    contacts_.push_back(SceneContact{object_a_, object_b_, contact});
  }

 private:
  std::vector<SceneContact>& contacts_;
  std::uint32_t object_a_;
  std::uint32_t object_b_;
};

bool movesOnlyRigidly(ObjectKind kind) {
  return kind == ObjectKind::kStatic || kind == ObjectKind::kKinematic;
}

/// The level the query of objects a and b runs to at the scene's `level`. An object that
/// moves only rigidly meets one that ends at or above `level` at its own leaves: its tree
/// costs nothing to keep, its slabs prune the descent there, and a leaf contact costs the
/// response a point pair, where its coarse nodes at `level` would reach far more of the
/// other's leaves than its points do (a floor's level 7 against a pile object's leaves).
int queryLevel(int level, const SphereTree& a, ObjectKind kind_a, const SphereTree& b,
               ObjectKind kind_b) {
  const bool rigid_a = movesOnlyRigidly(kind_a);
  if (rigid_a == movesOnlyRigidly(kind_b)) return level;
  const SphereTree& deforming = rigid_a ? b : a;
  return level >= deforming.maxLevel() ? std::max(a.maxLevel(), b.maxLevel()) : level;
}

}  // namespace

// Each root sphere is computed from its own object alone, and the same whichever thread
// computes it.
void Scene::computeRootsOnPool() {
  if (pool_.threads() == 1 || objects_.size() < kRootsWorthSharing) return;
  pool_.forEach(objects_.size(), [this](std::size_t index) {
    Object& o = *objects_[index];
    if (o.config.kind != ObjectKind::kStatic) o.tree.sphere(0);
  });
}

const std::vector<BroadPhase::Pair>& Scene::sweepAndPrune() {
  const double margin = 0.5 * config_.contact_distance_m;
  return broad_phase_.sweep(objects_.size(), [&](std::uint32_t index) {
    Object& o = *objects_[index];
    const bool is_static = o.config.kind == ObjectKind::kStatic;
    // Static objects keep their points' box, set when they were made; the margin is the
    // contact distance in force.
    if (is_static) {
      o.sweep_box = o.points_box;
      o.sweep_box.min().array() -= margin;
      o.sweep_box.max().array() += margin;
    } else {
      const Sphere& root = o.tree.sphere(0);
      const Eigen::Vector3d reach = Eigen::Vector3d::Constant(root.radius + margin);
      o.sweep_box = Eigen::AlignedBox3d(root.center - reach, root.center + reach);
    }
    return BroadPhase::Box{o.sweep_box, is_static};
  });
}

void Scene::detect(int level, std::optional<std::size_t> only_a, std::optional<std::size_t> only_b,
                   std::vector<SceneContact>& contacts, std::vector<ContactRun>* runs) {
  const auto& candidate_pairs = sweepAndPrune();
  const auto matches = [&](std::size_t a, std::size_t b) {
    const bool a_ok = !only_a || *only_a == a;
    const bool b_ok = !only_b || *only_b == b;
    return a_ok && b_ok;
  };
  for (const auto& [a, b] : candidate_pairs) {
    // A pair matches the filter in either order; contacts keep the order asked for.
    const bool forward = matches(a, b);
    const bool backward = !forward && matches(b, a);
    if (!forward && !backward) continue;
    ++stats_.object_pairs_tested;
    const std::uint32_t first = forward ? a : b;
    const std::uint32_t second = forward ? b : a;
    const std::size_t begin = contacts.size();
    queryPair(level, first, second, query_, query_counters_, contacts);
    if (runs && contacts.size() > begin) runs->push_back({first, second, begin, contacts.size()});
  }
  appendSelfContacts(level, only_a, only_b, contacts);
}

void Scene::appendSelfContacts(int level, std::optional<std::size_t> only_a,
                               std::optional<std::size_t> only_b,
                               std::vector<SceneContact>& contacts) {
  for (std::uint32_t index = 0; index < objects_.size(); ++index) {
    Object& o = *objects_[index];
    if (!o.rest_spheres || (only_a && *only_a != index) || (only_b && *only_b != index)) continue;
    const double rest_distance_m =
        std::max(o.config.self_rest_distance_m > 0.0
                     ? o.config.self_rest_distance_m
                     : kSelfRestContactDistances * config_.contact_distance_m,
                 config_.contact_distance_m);
    PairContacts self_contacts(contacts, index, index);
    self_query_.collide(o.tree, *o.rest_spheres, level, config_.contact_distance_m, rest_distance_m,
                        self_contacts, query_counters_);
  }
}

void Scene::queryPair(int level, std::uint32_t first, std::uint32_t second, HierarchyQuery& query,
                      QueryCounters& counters, std::vector<SceneContact>& contacts) {
  PairContacts pair_contacts(contacts, first, second);
  Object& a = *objects_[first];
  Object& b = *objects_[second];
  const PairSlabs slabs{a.slabs.empty() ? nullptr : &a.slabs, b.slabs.empty() ? nullptr : &b.slabs};
  query.collide(a.tree, b.tree, queryLevel(level, a.tree, a.config.kind, b.tree, b.config.kind),
                config_.contact_distance_m, pair_contacts, counters, slabs);
}

// Two objects whose points did not change since the last detection have the same contacts
// at the same level: the same candidate pair (their boxes come from the same spheres) and the
// same query on the same spheres. Only tracked, kinematic and static objects keep their
// points between detections: a tracked pile between its clouds, a camera's object on the
// floor, and what a detection ahead of the cycle saw. Every dynamic object moves in each
// cycle's step, so a detection ahead leaves its pairs to the cycle.
void Scene::detectCycleContacts(int level, bool ahead) {
  contacts_.swap(previous_contacts_);
  contact_runs_.swap(previous_runs_);
  contacts_.clear();
  contact_runs_.clear();
  const bool reusable = previous_level_ == level;
  // Unset until this detection is complete: one that throws leaves nothing to reuse.
  previous_level_.reset();
  computeRootsOnPool();
  const auto& candidate_pairs = sweepAndPrune();
  // A scene of a few pairs stays on this thread: handing them out costs more than it saves.
  const bool shared = pool_.threads() > 1 && candidate_pairs.size() >= kPairsWorthSharing;
  if (shared) queryPairsOnPool(level, candidate_pairs, ahead, reusable);
  std::size_t cursor = 0;
  std::size_t pooled = 0;
  for (const auto& [a, b] : candidate_pairs) {
    if (leftToCycle(a, b, ahead)) continue;
    if (!ahead) ++stats_.object_pairs_tested;
    if (keepsContacts(a, b, reusable)) {
      if (!ahead) ++stats_.object_pairs_reused;
      reusePreviousContacts(a, b, cursor);
      continue;
    }
    const std::size_t begin = contacts_.size();
    if (shared) {
      contacts_.insert(contacts_.end(), pair_lanes_->contactsBegin(pooled),
                       pair_lanes_->contactsEnd(pooled));
      ++pooled;
    } else {
      queryPair(level, a, b, query_, query_counters_, contacts_);
    }
    if (contacts_.size() > begin) contact_runs_.push_back({a, b, begin, contacts_.size()});
  }
  // Self-contacts are queried every cycle, after every pair's: the response of pairs reads
  // only their runs.
  self_contacts_begin_ = contacts_.size();
  if (!ahead) appendSelfContacts(level, std::nullopt, std::nullopt, contacts_);
  revisions_detected_ = revisions_;
  previous_level_ = level;
}

bool Scene::leftToCycle(std::uint32_t a, std::uint32_t b, bool ahead) const {
  return ahead && (objects_[a]->dynamic() || objects_[b]->dynamic());
}

bool Scene::keepsContacts(std::uint32_t a, std::uint32_t b, bool reusable) const {
  return reusable && objects_[a]->revision <= revisions_detected_ &&
         objects_[b]->revision <= revisions_detected_;
}

void Scene::queryPairsOnPool(int level, const std::vector<BroadPhase::Pair>& candidate_pairs,
                             bool ahead, bool reusable) {
  pair_lanes_->clear(objects_.size());
  for (const auto& [a, b] : candidate_pairs) {
    if (!leftToCycle(a, b, ahead) && !keepsContacts(a, b, reusable)) pair_lanes_->add(a, b);
  }
  pair_lanes_->run(pool_, [&](std::uint32_t a, std::uint32_t b, HierarchyQuery& query,
                              QueryCounters& counters, std::vector<SceneContact>& contacts) {
    queryPair(level, a, b, query, counters, contacts);
  });
  pair_lanes_->addCounters(query_counters_);
}

void Scene::reusePreviousContacts(std::uint32_t first, std::uint32_t second, std::size_t& cursor) {
  const auto before_pair = [&](const ContactRun& run) {
    return run.object_a < first || (run.object_a == first && run.object_b < second);
  };
  while (cursor < previous_runs_.size() && before_pair(previous_runs_[cursor])) ++cursor;
  if (cursor == previous_runs_.size()) return;
  const ContactRun& previous = previous_runs_[cursor];
  // No run: the pair had no contacts.
  if (previous.object_a != first || previous.object_b != second) return;
  const std::size_t begin = contacts_.size();
  contacts_.insert(contacts_.end(), previous_contacts_.begin() + previous.begin,
                   previous_contacts_.begin() + previous.end);
  contact_runs_.push_back({first, second, begin, contacts_.size()});
}

}  // namespace deformable_collision
