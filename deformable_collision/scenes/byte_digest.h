#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <vector>

namespace deformable_collision {

/// FNV-1a (64 bit) over the bytes of the values fed to it, in order: two runs digest alike
/// exactly when they fed the same bits, which is what a change that claims to keep the
/// behaviour (a refactoring, a faster kernel) must show. The probes and the object-build
/// equivalence test record such digests.
class ByteDigest {
 public:
  template <typename T>
  void add(const T& value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (const unsigned char byte : bytes) hash_ = (hash_ ^ byte) * 0x100000001b3ULL;
  }
  void add(const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i) add(v[i]);
  }
  void addVectors(const std::vector<Eigen::Vector3d>& vectors) {
    for (const auto& v : vectors) add(v);
  }
  std::uint64_t value() const { return hash_; }

 private:
  std::uint64_t hash_ = 0xcbf29ce484222325ULL;
};

}  // namespace deformable_collision
