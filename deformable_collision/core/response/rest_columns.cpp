#include "deformable_collision/core/response/detail/rest_columns.h"

#include <Eigen/Geometry>
#include <algorithm>

namespace deformable_collision {
namespace detail {

RestColumns::RestColumns(const ShapeMatchingBody& body, const SphereTree& tree)
    : nodes_(tree.nodeCount()) {
  for (std::uint32_t n = 0; n < tree.nodeCount(); ++n) {
    const SphereNode& from = tree.node(n);
    Node& node = nodes_[n];
    node.center =
        from.cluster < 0
            ? from.rest_center
            : Eigen::Vector3d(from.rest_center + body.cluster(from.cluster).rest_center_of_mass);
    // The points and the centre differ from the centred coordinates the sphere was fitted
    // to by a few ulps of their magnitude; the margin only makes the walk read more points.
    node.reach = from.rest_radius_m + 1e-9 * (from.rest_radius_m + node.center.cwiseAbs().sum()) +
                 std::numeric_limits<double>::min();
    node.first_child = from.first_child;
    node.child_count = from.child_count;
    node.first_point = from.first_point;
    node.point_count = from.point_count;
  }
  slot_points_.reserve(tree.pointIndices().size());
  for (const std::uint32_t index : tree.pointIndices()) {
    slot_points_.push_back(body.restPositions()[index]);
  }
  boundBoxes();
  // Walks run in the response's cycle: no column holds more points, nor a descent more
  // pending nodes, than the tree has.
  pending_.reserve(nodes_.size());
  offsets_.reserve(slot_points_.size());
}

void RestColumns::boundBoxes() {
  for (std::size_t n = nodes_.size(); n-- > 0;) {
    Node& node = nodes_[n];
    Eigen::AlignedBox3d box;
    if (node.child_count == 0) {
      for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
        box.extend(slot_points_[s]);
      }
    }
    for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
      box.extend(Eigen::AlignedBox3d(nodes_[c].box_center - nodes_[c].box_half,
                                     nodes_[c].box_center + nodes_[c].box_half));
    }
    node.box_center = box.center();
    node.box_half = 0.5 * box.sizes();
    // Centre and half sizes round by an ulp or so, the points' offsets by a few ulps of
    // their magnitudes.
    node.box_margin = 1e-9 * (node.box_center.cwiseAbs().sum() + node.box_half.sum()) +
                      std::numeric_limits<double>::min();
  }
}

namespace {

/// The walk over a column's sorted offsets, times `sign`, from `reach` outwards: true once
/// it ends, at a gap wider than `gap_m` (the surface of a layered or solid slab, not what
/// lies beyond a gap) or past `enough`.
template <typename Iterator>
bool walk(Iterator first, Iterator last, double sign, double gap_m, double enough, double& reach) {
  for (; first != last; ++first) {
    const double offset = sign * *first;
    if (offset <= reach) continue;
    if (offset - reach > gap_m) return true;
    reach = offset;
    if (reach > enough) return true;
  }
  return false;
}

constexpr double kInfinity = std::numeric_limits<double>::infinity();

}  // namespace

double RestColumns::reach(std::uint32_t within, const RestColumn& column, double start, double sign,
                          double gap_m, double enough) {
  // A stretch at a time, from a few gaps long, doubling: a walk that ends soon reads little
  // beyond where it ends, and one through a thick part descends the tree a few times only.
  // A column of a few gaps more is read at once: every descent passes the tree's top again.
  const auto [middle, half] = offsetBounds(nodes_[within], stretchOf(column, sign, 0.0, 0.0));
  const double end = middle + half;
  double length = end - start <= 16.0 * gap_m ? end - start : 4.0 * gap_m;
  double reach = start;
  for (double low = start; low < end; length *= 2.0) {
    double high = low + length;
    if (!(high > low)) high = kInfinity;
    gather(within, stretchOf(column, sign, low, high));
    if (walk(offsets_.begin(), offsets_.end(), 1.0, gap_m, enough, reach)) return reach;
    // Rounding is monotone: every offset beyond `high` is then more than a gap beyond too.
    if (high - reach > gap_m) return reach;
    low = high;
  }
  return reach;
}

std::pair<double, double> RestColumns::reachBothWays(std::uint32_t within, const RestColumn& column,
                                                     double along_start, double against_start,
                                                     double gap_m) {
  const auto [middle, half] = offsetBounds(nodes_[within], stretchOf(column, 1.0, 0.0, 0.0));
  if (middle + half - along_start > 16.0 * gap_m || half - middle - against_start > 16.0 * gap_m) {
    return {reach(within, column, along_start, 1.0, gap_m),
            reach(within, column, against_start, -1.0, gap_m)};
  }
  // A short column is read once for both walks. Points between the two starts are passed
  // over by both (so is a node's own part of the column), so they are not read at all.
  Stretch both = stretchOf(column, 1.0, -kInfinity, kInfinity);
  both.skip_low = -against_start;
  both.skip_high = along_start;
  gather(within, both);
  double along = along_start;
  double against = against_start;
  walk(offsets_.begin(), offsets_.end(), 1.0, gap_m, kInfinity, along);
  walk(offsets_.rbegin(), offsets_.rend(), -1.0, gap_m, kInfinity, against);
  return {along, against};
}

RestColumns::Stretch RestColumns::stretchOf(const RestColumn& column, double sign, double low,
                                            double high) const {
  Stretch stretch{column, sign, low, high};
  stretch.abs_normal = column.normal.cwiseAbs();
  stretch.margin = 1e-9 * column.center.cwiseAbs().sum();
  return stretch;
}

void RestColumns::gather(std::uint32_t within, const Stretch& stretch) {
  offsets_.clear();
  pending_.assign(1, within);
  while (!pending_.empty()) {
    const Node& node = nodes_[pending_.back()];
    pending_.pop_back();
    if (misses(node, stretch)) continue;
    if (node.child_count == 0) {
      gatherPoints(node, stretch);
      continue;
    }
    for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
      pending_.push_back(c);
    }
  }
  std::sort(offsets_.begin(), offsets_.end());
}

bool RestColumns::misses(const Node& node, const Stretch& stretch) const {
  const auto [middle, half] = offsetBounds(node, stretch);
  if (middle + half <= stretch.low || middle - half > stretch.high) return true;
  if (middle - half >= stretch.skip_low && middle + half <= stretch.skip_high) return true;
  const RestColumn& column = stretch.column;
  const Eigen::Vector3d away = node.center - column.center;
  const double along = away.dot(column.normal);
  const double wide = column.radius + node.reach + stretch.margin;
  return (away - along * column.normal).squaredNorm() > wide * wide;
}

void RestColumns::gatherPoints(const Node& node, const Stretch& stretch) {
  const RestColumn& column = stretch.column;
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    // As a walk over the whole column computes them, so that the offsets are the same bits.
    const Eigen::Vector3d d = slot_points_[s] - column.center;
    const double offset = d.dot(column.normal);
    const double signed_offset = stretch.sign * offset;
    if (!(signed_offset > stretch.low && signed_offset <= stretch.high)) continue;
    if (signed_offset >= stretch.skip_low && signed_offset <= stretch.skip_high) continue;
    if ((d - offset * column.normal).norm() <= column.radius) offsets_.push_back(signed_offset);
  }
}

std::pair<double, double> RestColumns::offsetBounds(const Node& node,
                                                    const Stretch& stretch) const {
  const RestColumn& column = stretch.column;
  const double middle = stretch.sign * (node.box_center - column.center).dot(column.normal);
  return {middle, node.box_half.dot(stretch.abs_normal) + node.box_margin + stretch.margin};
}

}  // namespace detail
}  // namespace deformable_collision
