#include "deformable_collision/core/response/detail/contact_memory.h"

#include <algorithm>

namespace deformable_collision {
namespace detail {

ContactMemory::ContactSide* ContactMemory::find(std::uint32_t partner) {
  for (ContactSide& side : sides) {
    if (side.partner == partner) return &side;
  }
  return nullptr;
}

void ContactMemory::remember(std::uint32_t partner, const Eigen::Vector3d& normal,
                             std::uint64_t cycle) {
  if (ContactSide* side = find(partner)) {
    side->normal = normal;
    side->cycle = cycle;
  } else {
    sides.push_back({partner, normal, cycle});
  }
}

void ContactMemory::forgetBefore(std::uint64_t cycle) {
  sides.erase(std::remove_if(sides.begin(), sides.end(),
                             [&](const ContactSide& side) { return side.cycle + 1 < cycle; }),
              sides.end());
}

}  // namespace detail

}  // namespace deformable_collision
