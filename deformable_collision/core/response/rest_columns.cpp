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
    // Centre and half sizes round outwards by an ulp or so: the margins of offsetBounds.
    node.box_center = box.center();
    node.box_half = 0.5 * box.sizes();
  }
}

double RestColumns::reach(std::uint32_t within, const RestColumn& column, double start, double sign,
                          double gap_m, double enough) {
  // A stretch at a time, from a few gaps long, doubling: a walk that ends soon reads little
  // beyond where it ends, and one through a thick part descends the tree a few times only.
  // A column of a few gaps more is read at once: every descent passes the tree's top again.
  const auto [middle, half] = offsetBounds(nodes_[within], column, sign);
  const double end = middle + half;
  double stretch = end - start <= 16.0 * gap_m ? end - start : 4.0 * gap_m;
  double reach = start;
  for (double low = start; low < end; stretch *= 2.0) {
    double high = low + stretch;
    if (!(high > low)) high = std::numeric_limits<double>::infinity();
    gather(within, column, sign, low, high);
    for (const double offset : offsets_) {
      if (offset <= reach) continue;
      if (offset - reach > gap_m) return reach;
      reach = offset;
      if (reach > enough) return reach;
    }
    // Rounding is monotone: every offset beyond `high` is then more than a gap beyond too.
    if (high - reach > gap_m) return reach;
    low = high;
  }
  return reach;
}

void RestColumns::gather(std::uint32_t within, const RestColumn& column, double sign, double low,
                         double high) {
  offsets_.clear();
  pending_.assign(1, within);
  while (!pending_.empty()) {
    const Node& node = nodes_[pending_.back()];
    pending_.pop_back();
    if (missesStretch(node, column, sign, low, high)) continue;
    if (node.child_count == 0) {
      gatherPoints(node, column, sign, low, high);
      continue;
    }
    for (std::uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
      pending_.push_back(c);
    }
  }
  std::sort(offsets_.begin(), offsets_.end());
}

bool RestColumns::missesStretch(const Node& node, const RestColumn& column, double sign, double low,
                                double high) const {
  const auto [middle, half] = offsetBounds(node, column, sign);
  if (middle + half <= low || middle - half > high) return true;
  const Eigen::Vector3d away = node.center - column.center;
  const double along = away.dot(column.normal);
  const double wide = column.radius + node.reach + 1e-9 * column.center.cwiseAbs().sum();
  return (away - along * column.normal).squaredNorm() > wide * wide;
}

void RestColumns::gatherPoints(const Node& node, const RestColumn& column, double sign, double low,
                               double high) {
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    // As a walk over the whole column computes them, so that the offsets are the same bits.
    const Eigen::Vector3d d = slot_points_[s] - column.center;
    const double offset = d.dot(column.normal);
    const double signed_offset = sign * offset;
    if (!(signed_offset > low && signed_offset <= high)) continue;
    if ((d - offset * column.normal).norm() <= column.radius) offsets_.push_back(signed_offset);
  }
}

std::pair<double, double> RestColumns::offsetBounds(const Node& node, const RestColumn& column,
                                                    double sign) const {
  const double middle = sign * (node.box_center - column.center).dot(column.normal);
  // The points' offsets round by a few ulps of their and the centre's magnitudes.
  const double margin = 1e-9 * (node.box_center.cwiseAbs().sum() + node.box_half.sum() +
                                column.center.cwiseAbs().sum()) +
                        std::numeric_limits<double>::min();
  return {middle, node.box_half.dot(column.normal.cwiseAbs()) + margin};
}

}  // namespace detail
}  // namespace deformable_collision
