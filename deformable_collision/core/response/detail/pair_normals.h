// Internal to the core: the normals of a response's pairs between dynamic objects. Not
// installed.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "deformable_collision/core/common/worker_pool.h"
#include "deformable_collision/core/response/contact_response.h"

namespace deformable_collision {
namespace detail {

/// The normal of each contact run between two dynamic objects, and how far each of its
/// contact nodes reaches along it towards the partner. They read the objects' spheres and
/// leaf columns as the query left them, which resolving pairs does not change, so all are
/// measured before the first pair is resolved: on a pool's threads when there are many,
/// each run writing only its own slots, the same bits on any count. Nothing is allocated
/// once the slots have grown to a scene's needs.
class PairNormals {
 public:
  using Objects = ContactResponse::Objects;

  /// Below this many runs the normals are measured on the calling thread.
  static constexpr std::size_t kRunsWorthSharing = 32;

  /// Forgets the last response's runs; `runs` and `contacts` are the counts of this one's.
  void clear(std::size_t runs, std::size_t contacts);
  /// One more run to measure, between two dynamic objects; `side_of_a` is the direction a
  /// lies in seen from b, not unit, which the normal is turned to agree with.
  void add(std::uint32_t run, const Eigen::Vector3d& side_of_a);
  /// Measures every run added since clear(), on `pool` if they are many.
  void measure(WorkerPool& pool, Objects& objects, const std::vector<SceneContact>& contacts,
               const std::vector<ContactRun>& runs, double contact_distance_m);

  /// A measured run's side of a, as add() was given it.
  const Eigen::Vector3d& sideOfA(std::uint32_t run) const { return measured_[run].side_of_a; }
  /// A measured run's unit normal, from b to a.
  const Eigen::Vector3d& normal(std::uint32_t run) const { return measured_[run].normal; }
  /// Of a measured run's contact `contact` whose query ended at the leaves: how far the
  /// points of its node in a reach against the normal, and those of its node in b along it.
  double reachOfA(std::size_t contact) const { return reach_a_[contact]; }
  double reachOfB(std::size_t contact) const { return reach_b_[contact]; }

 private:
  /// One side's contact nodes in the run being measured: each node once, with its number of
  /// the run's contacts (0 outside them) and its reach. Sized to the largest tree met.
  struct Side {
    void fit(std::size_t node_count);

    std::vector<std::uint32_t> nodes;
    std::vector<std::uint32_t> contacts_of_node;
    std::vector<double> reach_of_node;
  };
  struct Lane {
    Side a;
    Side b;
  };
  struct Measured {
    Eigen::Vector3d side_of_a = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  };

  /// Computes, on this thread, the spheres that measuring the added runs reads: the first
  /// contact node's of a (the origin of its moments), and above the leaves every contact
  /// node's.
  void computeSpheresRead(Objects& objects, const std::vector<SceneContact>& contacts,
                          const std::vector<ContactRun>& runs);
  /// Measures added run `index` with `lane`'s scratch.
  void measureRun(std::size_t index, Lane& lane, Objects& objects,
                  const std::vector<SceneContact>& contacts, const std::vector<ContactRun>& runs,
                  double contact_distance_m);

  std::vector<std::uint32_t> added_;  ///< The runs to measure, in the order added.
  std::vector<Measured> measured_;    ///< By run.
  std::vector<double> reach_a_;       ///< By contact.
  std::vector<double> reach_b_;
  std::vector<Lane> lanes_;
};

}  // namespace detail
}  // namespace deformable_collision
