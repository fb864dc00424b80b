// Vulkan interop: the one public header with Vulkan types. For callers that keep their own data
// in Vulkan buffers on octovk's device and want queries answered there, with nothing copied
// through the host.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <mutex>

#include "octovk/device_types.h"
#include "octovk/octovk.hpp"

namespace octovk {

/// The Vulkan objects of a Context. Buffers shared with octovk must be created on `device`
/// with VK_BUFFER_USAGE_STORAGE_BUFFER_BIT; octovk submits its work to `queue` and waits for it.
/// Vulkan requires a queue externally synchronised, and every map of the Context submits to
/// `queue` from whichever thread uses it: hold lockQueue(context) around any vkQueueSubmit,
/// vkQueueWaitIdle or other call of yours on `queue`.
struct VulkanHandles {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  /// Offsets of BufferRanges must be multiples of this (minStorageBufferOffsetAlignment).
  VkDeviceSize offset_alignment = 1;
  /// VK_KHR_external_memory_fd / VK_KHR_external_semaphore_fd are enabled (where the device has
  /// them): memory and semaphores can be exported to CUDA or another API by file descriptor.
  bool external_memory_fd = false;
  bool external_semaphore_fd = false;
};

VulkanHandles vulkanHandles(Context& context);

/// The lock octovk holds while it submits to the Context's queue; hold it while you use
/// VulkanHandles::queue (briefly: every map of the Context waits for it to submit).
std::unique_lock<std::mutex> lockQueue(Context& context);

/// A range of a caller's buffer.
struct BufferRange {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize offset = 0;
  VkDeviceSize size = VK_WHOLE_SIZE;
};

/// A semaphore the caller signals when its buffer is ready (VK_NULL_HANDLE: ready now). A
/// timeline semaphore (needs the device's timelineSemaphore feature, which octovk enables where
/// the device has it) is waited for `value`; a binary one is waited for and unsignalled.
/// The calls return after their own work is complete, so the semaphore may then be destroyed;
/// on Mesa drivers first hold lockQueue and call vkQueueWaitIdle (a Mesa race, seen on lavapipe
/// 22.3: docs/architecture.md, "Change detection").
struct WaitSemaphore {
  VkSemaphore semaphore = VK_NULL_HANDLE;
  std::uint64_t value = 0;
};

/// A semaphore octovk signals once a call's results are in the caller's buffer (and the map is
/// updated), so that the caller's own device work can wait for them without the host in between
/// (VK_NULL_HANDLE: none). A timeline semaphore is signalled to `value` (the caller's next value;
/// the timelineSemaphore feature, enabled where the device has it); a binary one is signalled.
/// The signal is on the Context's queue, after every command octovk submitted for the call.
struct SignalSemaphore {
  VkSemaphore semaphore = VK_NULL_HANDLE;
  std::uint64_t value = 0;
};

/// OccupancyMap::insertPointCloud (sensor-frame overload) on points already in a device buffer:
/// `points_sensor` holds count x, y, z floats (12 B each) and needs TRANSFER_SRC usage. octovk's
/// first submission waits for `wait`, then copies the points on the device (nothing passes
/// through the host). The caller must not change the range until the call returns; the call
/// returns when the scan is in the map, with the same result as the host overload.
ScanStats insertPointCloudOnDevice(OccupancyMap& map, BufferRange points_sensor,
                                   std::uint32_t count, const Eigen::Vector3f& origin_sensor,
                                   const Pose& T_world_sensor,
                                   const ScanOptions& options = {}, WaitSemaphore wait = {},
                                   SignalSemaphore signal = {});

/// OccupancyMap::insertDepthImage on pixels already in a device buffer: `pixels` holds
/// image.width * image.height depths in image.encoding (image.depths is not read), row by row,
/// and needs TRANSFER_SRC usage. Waits and returns as insertPointCloudOnDevice.
ScanStats insertDepthImageOnDevice(OccupancyMap& map, BufferRange pixels, const DepthImage& image,
                                   const Pose& T_world_camera,
                                   const ScanOptions& options = {},
                                   const Eigen::Vector3f& origin_camera = Eigen::Vector3f::Zero(),
                                   WaitSemaphore wait = {}, SignalSemaphore signal = {});

/// OccupancyMap::search on points already in a device buffer: `points` holds count x, y, z
/// floats (12 B each); `results` receives count gpu::LookupResult (16 B each). The caller must
/// not use either range while the call runs; the call returns when the results are written.
void searchOnDevice(OccupancyMap& map, BufferRange points, std::uint32_t count,
                    BufferRange results, SignalSemaphore signal = {});

/// Bytes castRaysOnDevice needs in `results`: the results, then the walks' scratch space.
std::size_t castRaysResultBytes(std::uint32_t count);

/// OccupancyMap::castRays on rays already in a device buffer: `rays` holds count gpu::RayQuery
/// (40 B each); `results` (castRaysResultBytes(count) bytes) receives count gpu::RayResult
/// (16 B each) at its start. A ray the device could not finish (a driver that limits loops and a
/// pathological ray; OccupancyMap::castRays throws for it) has hit = gpu::kRayUnfinished.
void castRaysOnDevice(OccupancyMap& map, BufferRange rays, std::uint32_t count,
                      BufferRange results, SignalSemaphore signal = {});

/// Bytes changedKeysOnDevice needs for `count` changed keys (map.numChangesDetected()).
std::size_t changedKeysBytes(std::size_t count);

/// The map's change set (OccupancyMap::changedKeys) into a device buffer: a gpu::ChangedKeysHeader
/// (its count), then that many gpu::ChangedKey {key x, y, z, created} (octovk/device_types.h), in
/// no particular order; `out` must hold changedKeysBytes(map.numChangesDetected()) (else
/// kInvalidArgument, nothing written). Waits for the scans submitted before it.
void changedKeysOnDevice(OccupancyMap& map, BufferRange out, SignalSemaphore signal = {});

/// DistanceField::clearances on spheres already in a device buffer: `spheres` holds count
/// centre x, y, z and radius floats (16 B each; radius 0 for DistanceField::distances' answer);
/// `results` receives count gpu::DistanceResult (32 B each). Offsets must be multiples of
/// VulkanHandles::offset_alignment and each range within one storage binding's reach. octovk's
/// submission waits for `wait`; the call returns when the results are written, and `signal` is
/// signalled once they are (also for count 0), for the caller's device work to wait on.
void distancesOnDevice(DistanceField& field, BufferRange spheres, std::uint32_t count,
                       BufferRange results, WaitSemaphore wait = {}, SignalSemaphore signal = {});

}  // namespace octovk
