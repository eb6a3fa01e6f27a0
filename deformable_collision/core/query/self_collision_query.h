#pragma once

#include <cstdint>
#include <vector>

#include "deformable_collision/core/common/wide_vectors.h"
#include "deformable_collision/core/hierarchy/bounding_sphere.h"
#include "deformable_collision/core/hierarchy/sphere_tree.h"
#include "deformable_collision/core/query/collision_query.h"

namespace deformable_collision {

/// What a self-collision query reads of an object's rest shape: each node's rest sphere in
/// the object's frame (SphereNode keeps it in its cluster's centred coordinates), so that a
/// node pair's rest distances are bounded without reading its points, and the points' rest
/// positions in the tree's slot order, so that a leaf's are contiguous.
class RestSpheres {
 public:
  /// The rest spheres of `tree`'s nodes.
  explicit RestSpheres(const SphereTree& tree);

  const Sphere& operator[](std::uint32_t node) const { return spheres_[node]; }
  /// The rest positions of the points by slot of the tree's pointIndices(), one row per
  /// coordinate, as the tree's leafPositions() holds their current positions.
  const SlotPositions& slotPoints() const { return slot_points_; }
  /// How far a cluster's node's rest points reach from its cluster's rest centre of mass.
  double clusterExtent(std::uint32_t node) const { return cluster_extents_[node]; }

 private:
  std::vector<Sphere> spheres_;
  std::vector<double> cluster_extents_;
  SlotPositions slot_points_;
};

/// Descends one sphere tree against itself for the pairs of its points that came within the
/// contact distance although they lie more than `rest_distance_m` apart in the rest shape:
/// an object folded or pressed onto itself. Points nearer in the rest shape are neighbours
/// in the material, never a self-contact (docs/design.md, "Self-collision"). Holds its
/// traversal stack, so that repeated queries allocate nothing.
class SelfCollisionQuery {
 public:
  /// A query whose leaf tests use vectors of at most `width` (every width finds the same
  /// contacts, bit for bit).
  explicit SelfCollisionQuery(VectorWidth width = widestVectors()) : width_(width) {}

  /// Adds to `contacts` the self-contacts of `tree` at `level` (-1 or >= maxLevel(): the
  /// leaves), the node pairs a != b whose spheres come closer than `contact_distance_m` and
  /// whose points all lie more than `rest_distance_m` apart at rest (from `rest`, which must
  /// be `tree`'s). A pair at `level` whose rest spheres do not prove that is descended
  /// further, down to its leaves, whose points are then tested pair by pair: every point
  /// pair closer than the contact distance and farther than `rest_distance_m` at rest lies
  /// under a contact's two nodes, at any level; at the leaves, a leaf pair (or a leaf with
  /// itself) is a contact, at its closest such pair, exactly when it holds one. A pair whose
  /// rest spheres lie within `rest_distance_m` of each other is never descended, nor one of
  /// a cluster whose fit stretches no rest distance beyond that down to the contact
  /// distance (a cluster at rest, moved rigidly or mildly deformed). The
  /// depth of a contact above the leaves is its own spheres' overlap (grown by half the
  /// contact distance each).
  void collide(SphereTree& tree, const RestSpheres& rest, int level, double contact_distance_m,
               double rest_distance_m, ContactSink& contacts, QueryCounters& counters);

 private:
  /// How a cluster's fit f can bring two points closer than at rest: for rest points whose
  /// offsets from its rest centre of mass stay within e in each coordinate, |f(u) - f(v)| >=
  /// (least_stretch - 2 e quadratic_norms) |u - v|; each of its points lies within
  /// deviation_m of its fit. `linear` is the fit's A, for how far two clusters' fits part.
  struct ClusterStretch {
    double least_stretch = 0.0;
    double quadratic_norms = 0.0;
    double deviation_m = 0.0;
    Eigen::Vector3d rest_center_m = Eigen::Vector3d::Zero();
    Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();
    /// Whether the stretch can keep any pair apart at all: a fold inside the cluster
    /// (least_stretch near 0) never does, whatever the nodes.
    bool may_keep_apart = false;
  };
  struct PendingPair {
    std::uint32_t node_a = 0;
    std::uint32_t node_b = 0;
    bool all_distant = false;  ///< Every point of a farther than the rest distance from b's.
  };
  void measureStretches(const ShapeMatchingBody& body, double contact_distance_m,
                        double rest_distance_m);
  /// One query's state and steps (self_collision_query.cpp).
  struct Descent;

  std::vector<PendingPair> stack_;
  std::vector<ClusterStretch> stretches_;  ///< Of the tree queried, per cluster.
  /// The sphere a query uses for a node (SelfCollisionQuery::Descent::sphere), chosen in
  /// query `query`.
  struct QuerySphere {
    Sphere sphere;
    std::uint64_t query = 0;
  };
  std::vector<QuerySphere> query_spheres_;
  /// The box around a node's current points, measured in query `query`.
  struct NodeBox {
    double low[3];
    double high[3];
    std::uint64_t query = 0;
  };
  std::vector<NodeBox> node_boxes_;
  std::uint64_t query_serial_ = 0;
  VectorWidth width_;
};

}  // namespace deformable_collision
