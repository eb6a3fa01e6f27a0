#include "deformable_collision/core/scene/detail/registration_errors.h"

#include <algorithm>

#include "deformable_collision/core/scene/detail/scene_object.h"

namespace deformable_collision {
namespace detail {
namespace {

// hidden_m >= seen_m: an object whose hidden_m is 0 has no error on either side.
bool registered(const std::unique_ptr<SceneObject>& object) {
  return object->registration_error.hidden_m > 0.0;
}

// A pair's contacts share one side of each camera, told at their mean place along their
// depth-weighted mean normal (from b to a: each object's surface there faces the other): the
// normals of single point pairs scatter across a flat face, and may lie along it.
void assignPair(const SurfaceError& a, const SurfaceError& b, std::vector<SceneContact>& contacts,
                std::size_t begin, std::size_t end) {
  Eigen::Vector3d position = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
  for (std::size_t k = begin; k < end; ++k) {
    position += contacts[k].contact.position;
    normal += contacts[k].contact.depth_m * contacts[k].contact.normal;
  }
  position /= static_cast<double>(end - begin);
  const double error = std::max(a.at(position, -normal), b.at(position, normal));
  for (std::size_t k = begin; k < end; ++k) contacts[k].registration_error_m = error;
}

}  // namespace

void assignRegistrationErrors(const std::vector<std::unique_ptr<SceneObject>>& objects,
                              std::vector<SceneContact>& contacts) {
  if (std::none_of(objects.begin(), objects.end(), registered)) return;
  for (std::size_t begin = 0; begin < contacts.size();) {
    const std::size_t end = pairRunEnd(contacts, begin);
    const SceneContact& first = contacts[begin];
    if (registered(objects[first.object_a]) || registered(objects[first.object_b])) {
      assignPair(objects[first.object_a]->registration_error,
                 objects[first.object_b]->registration_error, contacts, begin, end);
    }
    begin = end;
  }
}

}  // namespace detail
}  // namespace deformable_collision
