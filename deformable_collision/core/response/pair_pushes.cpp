// The pushes of one pair: how deep each contact node lies, against a fixed object's planes
// or between two dynamic objects, and the whole objects' moves they add up to.
#include <algorithm>
#include <limits>
#include <optional>

#include "deformable_collision/core/response/detail/pair_normals.h"
#include "deformable_collision/core/response/detail/resolving_pair.h"

namespace deformable_collision {

void ContactResponse::collectPushes(const ResolvingPair& pair) {
  for (std::size_t k = pair.run_begin; k < pair.run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    ContactPush push;
    push.node_a = c.node_a;
    push.node_b = c.node_b;
    push.points_a = pair.a.tree.node(c.node_a).point_count;
    push.points_b = pair.b.tree.node(c.node_b).point_count;
    const bool pushed =
        pair.one_side_fixed ? pushFromFixedPlane(pair, c, push) : pushBetweenDynamic(pair, k, push);
    if (pushed) pair.scratch->pushes.push_back(push);
  }
}

ContactResponse::FixedSurface ContactResponse::fixedSurface(const ResolvingPair& pair,
                                                            std::uint32_t node) {
  const bool a_fixed = !pair.a.dynamic();
  Object& fixed = a_fixed ? pair.a : pair.b;
  const int cluster = std::max(0, fixed.tree.node(node).cluster);
  const detail::FixedPlanes::Plane& plane = fixed.planes->plane(node);
  FixedSurface surface{fixed.body.deformation(cluster).rotation * plane.normal,
                       fixed.tree.sphere(node).center, plane.extent_along};
  if (surface.away.dot(a_fixed ? Eigen::Vector3d(-pair.side_of_a) : pair.side_of_a) < 0.0) {
    surface.away = -surface.away;
    surface.reach = plane.extent_against;
  }
  return surface;
}

// Against a fixed object: its node's plane, oriented towards the dynamic object, and the
// deepest point's signed distance. Unlike the distance to the nearest point, that depth
// does not shrink or flip when points have passed a thin layer such as a floor.
bool ContactResponse::pushFromFixedPlane(const ResolvingPair& pair, const SphereContact& c,
                                         ContactPush& push) {
  const bool a_fixed = !pair.a.dynamic();
  Object& moving = a_fixed ? pair.b : pair.a;
  const FixedSurface surface = fixedSurface(pair, a_fixed ? c.node_a : c.node_b);
  const std::uint32_t moving_node = a_fixed ? c.node_b : c.node_a;
  const SphereNode& node = moving.tree.node(moving_node);
  // The object has not moved in this response yet: the pairs with fixed objects come first,
  // and their moves wait for moveByFixedPartners. The node's sphere bounds its points along
  // the plane's normal: where even its lowest point leaves no depth, no point does, and the
  // points are not read (a coarse node holds hundreds, and many of a pile's coarse contacts
  // with a floor or a wall are such). The margin is far above the rounding of these sums, so
  // the outcome is the points' own.
  const Sphere& bound = moving.tree.sphere(moving_node);
  const Eigen::Vector3d from_plane = bound.center - surface.plane_point;
  const double margin = 1e-12 * (from_plane.norm() + bound.radius + std::abs(surface.reach) +
                                 config_.contact_distance_m);
  if (surface.reach + 0.5 * config_.contact_distance_m -
          (from_plane.dot(surface.away) - bound.radius - margin) <=
      0.0) {
    return false;
  }
  double deepest = std::numeric_limits<double>::infinity();
  const auto& positions = moving.body.positions();
  for (std::uint32_t s = node.first_point; s < node.first_point + node.point_count; ++s) {
    deepest = std::min(
        deepest,
        (positions[moving.tree.pointIndices()[s]] - surface.plane_point).dot(surface.away));
  }
  const double depth = surface.reach + 0.5 * config_.contact_distance_m - deepest;
  if (depth <= 0.0) return false;
  push.normal = a_fixed ? Eigen::Vector3d(-surface.away) : surface.away;
  push.depth_a = a_fixed ? 0.0 : depth;
  push.depth_b = a_fixed ? depth : 0.0;
  push.surface_m =
      surface.plane_point.dot(surface.away) + surface.reach + 0.5 * config_.contact_distance_m;
  return true;
}

ContactResponse::TouchedSurface ContactResponse::touchedSurface(const ResolvingPair& pair,
                                                                const Eigen::Vector3d& away) {
  const bool a_fixed = !pair.a.dynamic();
  Object& fixed = a_fixed ? pair.a : pair.b;
  TouchedSurface touched{away, away.unitOrthogonal(), Eigen::Vector3d::Zero(), {}};
  touched.across_v = away.cross(touched.across_u);
  for (std::size_t k = pair.run_begin; k < pair.run_end; ++k) {
    const SphereContact& c = contacts_[k].contact;
    const std::uint32_t node = a_fixed ? c.node_a : c.node_b;
    const FixedSurface surface = fixedSurface(pair, node);
    touched.level = std::max(touched.level, surface.plane_point.dot(away) + surface.reach);
    const Sphere& sphere = fixed.tree.sphere(node);
    const Eigen::Vector2d across(sphere.center.dot(touched.across_u),
                                 sphere.center.dot(touched.across_v));
    touched.in_line.extend(across - Eigen::Vector2d::Constant(sphere.radius));
    touched.in_line.extend(across + Eigen::Vector2d::Constant(sphere.radius));
  }
  return touched;
}

// A long step carries points of a dynamic object past a thin fixed layer, beyond the
// contact distance of any of its points, where no contact sees them; the contacts' pushes
// then undo only about the layer's thickness of a step that took more. So the deepest of
// the object's points in line with the touched nodes (within their spheres across the
// pair's normal), measured against the highest of their surfaces, is brought back by moving
// the whole object when the pair's move leaves it deeper than that: nothing dents it.
void ContactResponse::clearPassedPoints(ResolvingPair& pair) {
  const bool a_fixed = !pair.a.dynamic();
  Object& moving = a_fixed ? pair.b : pair.a;
  const TouchedSurface touched =
      touchedSurface(pair, (a_fixed ? -1.0 : 1.0) * pair.normal_sum.normalized());
  const Eigen::Vector3d& away = touched.away;
  const double lowest = lowestInLine(moving, touched, pair.scratch->descent);
  // As in pushFromFixedPlane, the object has not moved in this response yet.
  const double depth = touched.level + 0.5 * config_.contact_distance_m - lowest;
  double deepest_push = 0.0;
  for (const ContactPush& push : pair.scratch->pushes)
    deepest_push = std::max(deepest_push, push.depth_a + push.depth_b);
  // Points past the contacts' reach are cleared; those within it only brought back within
  // the contact distance, where the next cycle's contacts see them. Even within it the
  // contacts only dent their own nodes' points, and a soft object moves by less than its
  // deepest push: the points in line outside those nodes would stay where the step put them.
  const double needed = depth > deepest_push + config_.contact_distance_m
                            ? depth
                            : depth - config_.contact_distance_m;
  Eigen::Vector3d& move = a_fixed ? pair.move_b : pair.move_a;
  const double moved = move.dot(away);
  if (moved < needed) move += (needed - moved) * away;
}

// Down the object's tree rather than over all its points: a gripper's fruit held between two
// jaws on a floor read its 10,000 points three times a cycle, 6% of the demo scene's cycle.
// A node is opened only if its sphere lies in line with the touched nodes and reaches below
// the lowest point found so far, the lowest reaching first, so that the bound tightens
// early. The margin keeps rounding from pruning a point the scan would have taken, so the
// result is the scan's to the bit.
double ContactResponse::lowestInLine(Object& moving, const TouchedSurface& touched,
                                     std::vector<ReachingNode>& descent) {
  const Eigen::Vector3d& away = touched.away;
  const auto& positions = moving.body.positions();
  const auto& indices = moving.tree.pointIndices();
  double lowest = std::numeric_limits<double>::infinity();
  // The least `away` component the sphere allows its points, or nothing if none of them can
  // be in line.
  const auto reach_in_line = [&](const Sphere& sphere) -> std::optional<double> {
    const double margin = 1e-12 * (sphere.center.norm() + sphere.radius);
    const Eigen::Vector2d across(sphere.center.dot(touched.across_u),
                                 sphere.center.dot(touched.across_v));
    const Eigen::AlignedBox2d box(across.array() - (sphere.radius + margin),
                                  across.array() + (sphere.radius + margin));
    if (!box.intersects(touched.in_line)) return std::nullopt;
    return sphere.center.dot(away) - sphere.radius - margin;
  };
  descent.clear();
  if (const auto root = reach_in_line(moving.tree.sphere(0))) descent.push_back({0, *root});
  while (!descent.empty()) {
    const ReachingNode reaching = descent.back();
    descent.pop_back();
    if (reaching.lowest_m >= lowest) continue;
    const NodeState& state = moving.tree.current(reaching.node);
    if (state.isLeaf()) {
      for (std::uint32_t k = 0; k < state.point_count; ++k) {
        const Eigen::Vector3d& point = positions[indices[state.first_point + k]];
        if (touched.inLine(point)) lowest = std::min(lowest, point.dot(away));
      }
      continue;
    }
    const std::size_t first_child = descent.size();
    for (std::uint32_t child = state.first_child; child < state.first_child + state.child_count;
         ++child) {
      if (const auto reach = reach_in_line(moving.tree.sphere(child))) {
        if (*reach < lowest) descent.push_back({child, *reach});
      }
    }
    // The lowest reaching child last on the stack: visited next.
    std::sort(descent.begin() + first_child, descent.end(),
              [](const ReachingNode& x, const ReachingNode& y) { return x.lowest_m > y.lowest_m; });
  }
  return lowest;
}

// Two dynamic nodes, along the pair's normal, the depth shared by inverse mass. At the
// leaves the depth is how far b's points reach past a's along the normal: the nearest
// pair's distance says nothing of how deep two clouds have passed into each other (it stays
// below the point spacing however deep), and piles would sink into themselves. Above the
// leaves, spheres stand for their points (the query's depth).
bool ContactResponse::pushBetweenDynamic(const ResolvingPair& pair, std::size_t contact,
                                         ContactPush& push) const {
  const SphereContact& c = contacts_[contact].contact;
  const Object& a = pair.a;
  const Object& b = pair.b;
  push.normal = pair.dynamic_normal;
  const double overlap = pair.leaves
                             ? pair_normals_->reachOfB(contact) + pair_normals_->reachOfA(contact) +
                                   config_.contact_distance_m
                             : c.depth_m;
  const double depth =
      overlap - 0.5 * config_.contact_distance_m - (a.translation - b.translation).dot(push.normal);
  if (depth <= 0.0) return false;
  // Shared by inverse node mass: a's share is b's node mass over both; the object nearer
  // to a support does not move (shock propagation), nor one that the push would drive into
  // a fixed object (a wall) which has pushed it off in this response.
  const double mass_a = a.body.pointMassKg() * push.points_a;
  const double mass_b = b.body.pointMassKg() * push.points_b;
  const bool a_holds = a.support_depth < b.support_depth || pair.a_against_fixed;
  const bool b_holds = b.support_depth < a.support_depth || pair.b_against_fixed;
  const double share_of_a = a_holds && !b_holds   ? 0.0
                            : b_holds && !a_holds ? 1.0
                                                  : mass_b / (mass_a + mass_b);
  push.depth_a = depth * share_of_a;
  push.depth_b = depth - push.depth_a;
  return true;
}

// Each object moves by the mean push of its contact nodes, weighted by their points. A
// stiff object cannot dent, so it moves to clear more of its deepest node: the mean push
// for a soft one (the rest is dented), all of the deepest for a rigid one.
void ContactResponse::moveByMeanPush(ResolvingPair& pair) {
  Eigen::Vector3d mean_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_b = Eigen::Vector3d::Zero();
  double weight_a = 0.0;
  double weight_b = 0.0;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (const ContactPush& push : pair.scratch->pushes) {
    mean_a += push.points_a * push.depth_a * push.normal;
    mean_b -= push.points_b * push.depth_b * push.normal;
    weight_a += push.points_a;
    weight_b += push.points_b;
    normal_sum += (push.depth_a + push.depth_b) * push.normal;
  }
  mean_a /= weight_a;
  mean_b /= weight_b;
  double deepest_a = 0.0;
  double deepest_b = 0.0;
  for (const ContactPush& push : pair.scratch->pushes) {
    deepest_a = std::max(deepest_a, push.depth_a - mean_a.dot(push.normal));
    deepest_b = std::max(deepest_b, push.depth_b + mean_b.dot(push.normal));
  }
  const Eigen::Vector3d pair_direction = normal_sum.normalized();
  // Between two dynamic objects above the leaves nothing dents: the depths are those of the
  // nodes' spheres (they stand for their points), and a dent would push a node's points by
  // how deep the spheres overlap, not the points. Each object clears its deepest node whole.
  const bool dents = pair.leaves || pair.one_side_fixed;
  const double stiffness_a = dents ? pair.a.config.shape.stiffness : 1.0;
  const double stiffness_b = dents ? pair.b.config.shape.stiffness : 1.0;
  if (pair.a.dynamic()) mean_a += stiffness_a * deepest_a * pair_direction;
  if (pair.b.dynamic()) mean_b -= stiffness_b * deepest_b * pair_direction;
  if (pair.held) undoStepApproach(pair, pair_direction, mean_a, mean_b);
  pair.move_a = mean_a;
  pair.move_b = mean_b;
  pair.normal_sum = normal_sum;
}

// Two objects that touched in the last cycle rested on each other: what this cycle's step
// (and the pairs before) brought them together along the pair's normal is undone by moving
// them whole, whatever their stiffness, up to their deepest push; only overlap beyond that
// dents. Otherwise a soft object moves back only by its mean push, and every point above its
// contact ends each cycle lower by the difference: a soft box under another one compacts into
// itself, and with no stiffness at all it never stops.
void ContactResponse::undoStepApproach(const ResolvingPair& pair, const Eigen::Vector3d& normal,
                                       Eigen::Vector3d& move_a, Eigen::Vector3d& move_b) const {
  const Object& a = pair.a;
  const Object& b = pair.b;
  const Eigen::Vector3d step_a = stepOf(a);
  const Eigen::Vector3d step_b = stepOf(b);
  const double approach =
      -((step_a + pair.translation_before_a) - (step_b + pair.translation_before_b)).dot(normal);
  if (approach <= 0.0) return;
  double depth_a = 0.0;
  double depth_b = 0.0;
  double deepest_a = 0.0;
  double deepest_b = 0.0;
  for (const ContactPush& push : pair.scratch->pushes) {
    depth_a += push.depth_a;
    depth_b += push.depth_b;
    deepest_a = std::max(deepest_a, push.depth_a);
    deepest_b = std::max(deepest_b, push.depth_b);
  }
  const double share_a = depth_a / (depth_a + depth_b);
  const double need_a = std::min(share_a * approach, deepest_a);
  const double need_b = std::min((1.0 - share_a) * approach, deepest_b);
  if (a.dynamic() && move_a.dot(normal) < need_a) move_a += (need_a - move_a.dot(normal)) * normal;
  if (b.dynamic() && -move_b.dot(normal) < need_b) move_b -= (need_b + move_b.dot(normal)) * normal;
}

}  // namespace deformable_collision
