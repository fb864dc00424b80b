// Vulkan interop: the one public header with Vulkan types. For callers that keep their own data
// in Vulkan buffers on octovk's device and want queries answered there, with nothing copied
// through the host.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>

#include "octovk/gpu_types.h"
#include "octovk/octovk.hpp"

namespace octovk {

/// The Vulkan objects of a Context. Buffers shared with octovk must be created on `device`
/// with VK_BUFFER_USAGE_STORAGE_BUFFER_BIT; octovk submits its work to `queue` and waits for it.
struct VulkanHandles {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  /// Offsets of BufferRanges must be multiples of this (minStorageBufferOffsetAlignment).
  VkDeviceSize offset_alignment = 1;
};

VulkanHandles vulkanHandles(Context& context);

/// A range of a caller's buffer.
struct BufferRange {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize offset = 0;
  VkDeviceSize size = VK_WHOLE_SIZE;
};

/// OccupancyMap::search on points already in a device buffer: `points` holds count x, y, z
/// floats (12 B each); `results` receives count gpu::LookupResult (16 B each). The caller must
/// not use either range while the call runs; the call returns when the results are written.
void searchOnDevice(OccupancyMap& map, BufferRange points, std::uint32_t count,
                    BufferRange results);

/// Bytes castRaysOnDevice needs in `results`: the results, then the walks' scratch space.
std::size_t castRaysResultBytes(std::uint32_t count);

/// OccupancyMap::castRays on rays already in a device buffer: `rays` holds count gpu::RayQuery
/// (40 B each); `results` (castRaysResultBytes(count) bytes) receives count gpu::RayResult
/// (16 B each) at its start.
void castRaysOnDevice(OccupancyMap& map, BufferRange rays, std::uint32_t count,
                      BufferRange results);

}  // namespace octovk
