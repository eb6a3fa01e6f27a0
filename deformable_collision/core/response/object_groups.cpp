#include "deformable_collision/core/response/detail/object_groups.h"

#include <algorithm>

namespace deformable_collision {
namespace detail {

void ObjectGroups::group() {
  // (object, item) pairs are unique: any sort keeps each object's items in their order.
  std::sort(items_.begin(), items_.end());
  starts_.clear();
  for (std::size_t i = 0; i < items_.size(); ++i) {
    if (i == 0 || items_[i].first != items_[i - 1].first) starts_.push_back(i);
  }
  starts_.push_back(items_.size());
}

}  // namespace detail
}  // namespace deformable_collision
