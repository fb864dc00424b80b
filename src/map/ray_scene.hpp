// What castRay's ray-tracing backend keeps per map: the boxes buffer (an AccelHeader, then the
// boxes accel_boxes.comp writes), the acceleration structure built over them, and which state
// of the tree they describe.
#pragma once

#include <cstdint>

#include "gpu/gpu_types.h"
#include "octovk/octovk.hpp"
#include "vk/accel.hpp"
#include "vk/device.hpp"

namespace octovk {

struct RayScene {
  explicit RayScene(vk::Device& device)
      : accel(device), readback(device, sizeof(gpu::AccelHeader), /*host_visible=*/true) {}

  vk::Buffer boxes;     ///< AccelHeader, then the occupied boxes, then the unknown ones
  vk::BoxScene accel;   ///< built over `boxes`
  vk::Buffer readback;  ///< the header after accel_boxes: the box counts
  /// OccupancyMap::Impl::tree_version_ the structure was built from; none yet: ~0.
  std::uint64_t version = ~std::uint64_t{0};
  OccupancyMap::CastRayInfo info;

  std::size_t deviceBytes() const { return boxes.size() + accel.deviceBytes() + readback.size(); }
};

}  // namespace octovk
