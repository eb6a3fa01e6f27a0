// The peers of S1: what a user would pick instead of our sphere trees to find the point
// pairs of two deforming point clouds closer than the contact distance.
#include <BulletCollision/BroadphaseCollision/btDbvt.h>
#include <fcl/fcl.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <array>
#include <stdexcept>
#include <string>

#include "bench/s1_methods.h"

namespace deformable_collision::bench {

namespace {

using Points = std::vector<Eigen::Vector3d>;

/// Whether two FCL bounding volumes may hold points closer than `distance`, by FCL's own
/// tests: AABB::distance for boxes; for OBBRSS the OBB overlap test that FCL's collide()
/// uses, on boxes grown by half the distance (OBBRSS::distance, the RSS distance, made
/// the query over a hundred times slower here).
bool mayBeCloser(const fcl::AABBd& a, const fcl::AABBd& b, double distance) {
  return a.distance(b) < distance;
}

bool mayBeCloser(const fcl::OBBRSSd& a, const fcl::OBBRSSd& b, double distance) {
  fcl::OBBd grown_a = a.obb, grown_b = b.obb;
  grown_a.extent.array() += 0.5 * distance;
  grown_b.extent.array() += 0.5 * distance;
  return grown_a.overlap(grown_b);
}

/// FCL's BVHModel over each cloud, brought up to the new points through beginUpdateModel /
/// updateSubModel / endUpdateModel: a bottom-up refit for AABB; for OBBRSS a top-down one
/// (each node fitted to its points, O(n log n)), because FCL 0.7.0's bottom-up OBBRSS
/// refit leaves boxes that do not enclose their points (OBB merge_smalldist records a
/// vertex as the minimum only when it is not a new maximum), which missed pairs here.
/// FCL's collide() and distance() accept only triangle models (they return nothing for
/// BVH_MODEL_POINTCLOUD, and distance() gives one closest pair, not all pairs within a
/// distance), so the query is a descent over FCL's nodes that follows FCL's own traversal:
/// FCL's BV test (mayBeCloser), the larger node split first (BV::size), a point per leaf.
template <class BV>
class FclMethod : public S1Method {
 public:
  FclMethod(const char* name, bool bottom_up, const Points& a, const Points& b,
            double contact_distance_m)
      : name_(name),
        bottom_up_(bottom_up),
        points_{&a, &b},
        contact_distance_m_(contact_distance_m) {
    for (int k = 0; k < 2; ++k) {
      if (models_[k].beginModel() != fcl::BVH_OK ||
          models_[k].addSubModel(*points_[k]) != fcl::BVH_OK ||
          models_[k].endModel() != fcl::BVH_OK) {
        throw std::runtime_error(std::string("FCL could not build the ") + name + " model");
      }
    }
  }

  const char* name() const override { return name_; }

  std::size_t step() override {
    for (int k = 0; k < 2; ++k) {
      if (models_[k].beginUpdateModel() != fcl::BVH_OK ||
          models_[k].updateSubModel(*points_[k]) != fcl::BVH_OK ||
          models_[k].endUpdateModel(true, bottom_up_) != fcl::BVH_OK) {
        throw std::runtime_error(std::string("FCL could not refit the ") + name_ + " model");
      }
    }
    pairs_.clear();
    stack_.assign(1, {0, 0});
    while (!stack_.empty()) {
      const auto [i, j] = stack_.back();
      stack_.pop_back();
      const fcl::BVNode<BV>& na = models_[0].getBV(i);
      const fcl::BVNode<BV>& nb = models_[1].getBV(j);
      if (!mayBeCloser(na.bv, nb.bv, contact_distance_m_)) continue;
      if (na.isLeaf() && nb.isLeaf()) {
        const auto pa = static_cast<std::uint32_t>(na.primitiveId());
        const auto pb = static_cast<std::uint32_t>(nb.primitiveId());
        if (closerThan((*points_[0])[pa], (*points_[1])[pb], contact_distance_m_))
          pairs_.emplace_back(pa, pb);
      } else if (nb.isLeaf() || (!na.isLeaf() && na.bv.size() > nb.bv.size())) {
        stack_.push_back({na.leftChild(), j});
        stack_.push_back({na.rightChild(), j});
      } else {
        stack_.push_back({i, nb.leftChild()});
        stack_.push_back({i, nb.rightChild()});
      }
    }
    return static_cast<std::size_t>(models_[0].getNumBVs() + models_[1].getNumBVs());
  }

  std::vector<PointPair> pointPairs() const override { return sortedUnique(pairs_); }

 private:
  const char* name_;
  bool bottom_up_;
  std::array<const Points*, 2> points_;
  double contact_distance_m_;
  std::array<fcl::BVHModel<BV>, 2> models_;
  std::vector<std::pair<int, int>> stack_;
  std::vector<PointPair> pairs_;
};

/// A btDbvt per cloud (Bullet's dynamic AABB tree, built in double precision), one leaf
/// per point holding the point's box grown by half the contact distance. Each step every
/// leaf is updated the way Bullet's own btDbvtBroadphase does it: reinserted only when its
/// (fattened) box no longer contains the new one, then one incremental optimisation pass.
/// collideTT reports the leaf pairs whose boxes overlap; the exact distance decides.
class BulletDbvtMethod : public S1Method {
 public:
  BulletDbvtMethod(const Points& a, const Points& b, double contact_distance_m)
      : points_{&a, &b}, contact_distance_m_(contact_distance_m), collector_(*this) {
    for (int k = 0; k < 2; ++k) {
      leaves_[k].reserve(points_[k]->size());
      for (std::size_t p = 0; p < points_[k]->size(); ++p) {
        btDbvtNode* leaf = trees_[k].insert(pointBox((*points_[k])[p]), nullptr);
        leaf->dataAsInt = static_cast<int>(p);
        leaves_[k].push_back(leaf);
      }
    }
  }

  const char* name() const override { return "bullet_dbvt"; }

  std::size_t step() override {
    std::size_t reinserted = 0;
    for (int k = 0; k < 2; ++k) {
      for (std::size_t p = 0; p < leaves_[k].size(); ++p) {
        btDbvtVolume box = pointBox((*points_[k])[p]);
        reinserted +=
            trees_[k].update(leaves_[k][p], box, btScalar(kFatteningFactor * contact_distance_m_));
      }
      trees_[k].optimizeIncremental(1);
    }
    pairs_.clear();
    trees_[0].collideTT(trees_[0].m_root, trees_[1].m_root, collector_);
    return reinserted;
  }

  std::vector<PointPair> pointPairs() const override { return sortedUnique(pairs_); }

 private:
  /// The margin a reinserted leaf is fattened by, in contact distances: Bullet's
  /// broadphase fattens by a fixed margin, which has to be small next to the point spacing
  /// here, or every leaf overlaps its neighbours'.
  static constexpr double kFatteningFactor = 0.5;

  struct PairCollector : btDbvt::ICollide {
    explicit PairCollector(BulletDbvtMethod& method) : method(method) {}
    using btDbvt::ICollide::Process;
    void Process(const btDbvtNode* na, const btDbvtNode* nb) override {
      const auto pa = static_cast<std::uint32_t>(na->dataAsInt);
      const auto pb = static_cast<std::uint32_t>(nb->dataAsInt);
      if (closerThan((*method.points_[0])[pa], (*method.points_[1])[pb],
                     method.contact_distance_m_)) {
        method.pairs_.emplace_back(pa, pb);
      }
    }
    BulletDbvtMethod& method;
  };

  btDbvtVolume pointBox(const Eigen::Vector3d& p) const {
    return btDbvtVolume::FromCR(btVector3(p.x(), p.y(), p.z()),
                                btScalar(0.5 * contact_distance_m_));
  }

  std::array<const Points*, 2> points_;
  double contact_distance_m_;
  std::array<btDbvt, 2> trees_;
  std::array<std::vector<btDbvtNode*>, 2> leaves_;
  PairCollector collector_;
  std::vector<PointPair> pairs_;
};

/// PCL's KdTreeFLANN over cloud b, rebuilt each step on b's new points (unsorted results,
/// the faster setting), and a radius search around each point of a that lies in b's
/// bounding box grown by the contact distance (the others cannot have a partner). The
/// search runs in float with a radius grown by a micrometre, so rounding drops no pair;
/// the exact distance decides.
class PclKdTreeMethod : public S1Method {
 public:
  PclKdTreeMethod(const Points& a, const Points& b, double contact_distance_m)
      : a_(a),
        b_(b),
        contact_distance_m_(contact_distance_m),
        cloud_b_(new pcl::PointCloud<pcl::PointXYZ>) {
    cloud_b_->resize(b_.size());
    tree_.setSortedResults(false);
  }

  const char* name() const override { return "pcl_kdtree"; }

  std::size_t step() override {
    Eigen::AlignedBox3d box_b;
    for (std::size_t p = 0; p < b_.size(); ++p) {
      (*cloud_b_)[p].getVector3fMap() = b_[p].cast<float>();
      box_b.extend(b_[p]);
    }
    tree_.setInputCloud(cloud_b_);
    const Eigen::Vector3d grow = Eigen::Vector3d::Constant(contact_distance_m_);
    const Eigen::AlignedBox3d reach(box_b.min() - grow, box_b.max() + grow);
    pairs_.clear();
    pcl::PointXYZ query;
    for (std::size_t p = 0; p < a_.size(); ++p) {
      if (!reach.contains(a_[p])) continue;
      query.getVector3fMap() = a_[p].cast<float>();
      tree_.radiusSearch(query, contact_distance_m_ + 1e-6, found_, squared_distances_);
      for (const int q : found_) {
        if (closerThan(a_[p], b_[q], contact_distance_m_)) {
          pairs_.emplace_back(static_cast<std::uint32_t>(p), static_cast<std::uint32_t>(q));
        }
      }
    }
    return b_.size();
  }

  std::vector<PointPair> pointPairs() const override { return sortedUnique(pairs_); }

 private:
  const Points& a_;
  const Points& b_;
  double contact_distance_m_;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud_b_;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree_;
  std::vector<int> found_;
  std::vector<float> squared_distances_;
  std::vector<PointPair> pairs_;
};

}  // namespace

std::vector<std::unique_ptr<S1Method>> makePeers(const Points& a, const Points& b,
                                                 double contact_distance_m) {
  std::vector<std::unique_ptr<S1Method>> peers;
  peers.push_back(
      std::make_unique<FclMethod<fcl::AABBd>>("fcl_aabb", true, a, b, contact_distance_m));
  peers.push_back(
      std::make_unique<FclMethod<fcl::OBBRSSd>>("fcl_obbrss", false, a, b, contact_distance_m));
  peers.push_back(std::make_unique<BulletDbvtMethod>(a, b, contact_distance_m));
  peers.push_back(std::make_unique<PclKdTreeMethod>(a, b, contact_distance_m));
  return peers;
}

}  // namespace deformable_collision::bench
