#pragma once

#include <ros/serialization.h>

#include "deformable_collision/ContactArray.h"

// `~contacts` is serialised for subscribers in other processes into buffers the publishing
// thread reuses (MessageBufferPool) instead of one roscpp allocates at every publication:
// ros::Publisher::publish() serialises through this function template and offers no other
// hook. Every translation unit that publishes a ContactArray must include this header before
// it does, so that none instantiates the primary template instead.
namespace ros::serialization {

template <>
SerializedMessage serializeMessage<deformable_collision::ContactArray>(
    const deformable_collision::ContactArray& message);

}  // namespace ros::serialization
