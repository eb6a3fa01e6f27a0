#include "deformable_collision/ros/contact_array_serialization.h"

#include "deformable_collision/ros/message_buffer_pool.h"

namespace ros::serialization {
namespace {

// Messages in flight at once, most, in the load test (16k contacts at 100 Hz to one
// subscriber on loopback): 2 in an instrumented 60 s run; in another a new peak came at 45 s.
// Beyond the kept buffers (4 of 2 MB there) a message's buffer is mapped for it alone.
constexpr std::size_t kKeptContactBuffers = 4;

}  // namespace

template <>
SerializedMessage serializeMessage<deformable_collision::ContactArray>(
    const deformable_collision::ContactArray& message) {
  // One pool per publishing thread (a node's cycle thread): nodes in one manager do not share
  // buffers or a lock; a buffer still in flight when its thread ends is unmapped on return.
  thread_local deformable_collision::MessageBufferPool pool(kKeptContactBuffers);
  SerializedMessage serialized;
  const std::uint32_t length = serializationLength(message);
  serialized.num_bytes = length + 4;
  serialized.buf = pool.acquire(serialized.num_bytes);
  OStream stream(serialized.buf.get(), static_cast<std::uint32_t>(serialized.num_bytes));
  serialize(stream, length);
  serialized.message_start = stream.getData();
  serialize(stream, message);
  return serialized;
}

}  // namespace ros::serialization
