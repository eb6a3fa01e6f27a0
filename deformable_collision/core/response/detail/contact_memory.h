// Internal to the core: the sides a dynamic object's partners touched it from.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace deformable_collision {
namespace detail {

/// The side each partner touched this object from, kept while the contact lasts: an object
/// pushed past the middle of a thin wall must still be pushed back, not through.
struct ContactMemory {
  struct ContactSide {
    std::uint32_t partner = 0;
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Away from the partner.
    std::uint64_t cycle = 0;                            ///< Last cycle in contact.
  };

  /// The side last seen for `partner`, or nullptr.
  ContactSide* find(std::uint32_t partner);
  void remember(std::uint32_t partner, const Eigen::Vector3d& normal, std::uint64_t cycle);
  /// Forgets the partners not in contact in the cycle before `cycle`.
  void forgetBefore(std::uint64_t cycle);

  std::vector<ContactSide> sides;
};

}  // namespace detail
}  // namespace deformable_collision
