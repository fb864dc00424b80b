// Vulkan interop (include/octovk/vulkan_interop.hpp): the one file that hands Vulkan handles
// out and takes the caller's buffers in.
#include "map/context_access.hpp"
#include "map/depth_image.hpp"
#include "map/map_impl.hpp"
#include "octovk/vulkan_interop.hpp"

namespace octovk {

class InteropAccess {
 public:
  static OccupancyMap::Impl& impl(OccupancyMap& map) { return map.self(); }
};

VulkanHandles vulkanHandles(Context& context) {
  vk::Device& d = ContextAccess::device(context);
  VulkanHandles h{d.instance(), d.physical(),    d.handle(),
                  d.queue(),    d.queueFamily(), d.storageOffsetAlignment()};
  h.external_memory_fd = d.hasExtension(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME);
  h.external_semaphore_fd = d.hasExtension(VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME);
  return h;
}

std::unique_lock<std::mutex> lockQueue(Context& context) {
  return ContextAccess::device(context).lockQueue();
}

namespace {

// The caller's range must hold `bytes` from its offset.
void checkInput(const char* call, const BufferRange& range, std::size_t bytes) {
  if (range.buffer == VK_NULL_HANDLE)
    throw Error(ErrorCode::kInvalidArgument, std::string(call) + ": the buffer is VK_NULL_HANDLE");
  if (range.size != VK_WHOLE_SIZE && range.size < bytes)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(call) + ": the range holds " + std::to_string(range.size) +
                    " bytes; the input needs " + std::to_string(bytes));
}

}  // namespace

ScanStats insertPointCloudOnDevice(OccupancyMap& map, BufferRange points_sensor,
                                   std::uint32_t count, const Eigen::Vector3f& origin_sensor,
                                   const Pose& T_world_sensor, const ScanOptions& options,
                                   WaitSemaphore wait, SignalSemaphore signal) {
  checkInput("insertPointCloudOnDevice", points_sensor, std::size_t{count} * 3 * sizeof(float));
  OccupancyMap::Impl::ScanSource source;
  source.device = points_sensor.buffer;
  source.device_offset = points_sensor.offset;
  source.device_points = count;
  source.wait = wait.semaphore;
  source.wait_value = wait.value;
  OccupancyMap::Impl& impl = InteropAccess::impl(map);
  const ScanStats stats =
      impl.insert(source, T_world_sensor.transform(origin_sensor), &T_world_sensor, options);
  impl.signal(signal.semaphore, signal.value);
  return stats;
}

ScanStats insertDepthImageOnDevice(OccupancyMap& map, BufferRange pixels, const DepthImage& image,
                                   const Pose& T_world_camera, const ScanOptions& options,
                                   const Eigen::Vector3f& origin_camera, WaitSemaphore wait,
                                   SignalSemaphore signal) {
  const DepthImage& meta = image;  // its host depths are not looked at
  if (std::string why = depthImageProblem(meta, /*host_depths=*/false); !why.empty())
    throw Error(ErrorCode::kInvalidArgument, "insertDepthImageOnDevice: " + why);
  const std::size_t bytes = std::size_t{image.width} * image.height *
                            (image.encoding == DepthImage::Encoding::kUint16 ? 2 : 4);
  checkInput("insertDepthImageOnDevice", pixels, bytes);
  OccupancyMap::Impl::ScanSource source;
  source.depth = &meta;
  source.device = pixels.buffer;
  source.device_offset = pixels.offset;
  source.wait = wait.semaphore;
  source.wait_value = wait.value;
  OccupancyMap::Impl& impl = InteropAccess::impl(map);
  const ScanStats stats =
      impl.insert(source, T_world_camera.transform(origin_camera), &T_world_camera, options);
  impl.signal(signal.semaphore, signal.value);
  return stats;
}

void searchOnDevice(OccupancyMap& map, BufferRange points, std::uint32_t count, BufferRange results,
                    SignalSemaphore signal) {
  OccupancyMap::Impl& impl = InteropAccess::impl(map);
  impl.queryOnDevice(false, points.buffer, points.offset, points.size, results.buffer,
                     results.offset, results.size, count);
  impl.signal(signal.semaphore, signal.value);
}

std::size_t castRaysResultBytes(std::uint32_t count) {
  // The results, then from the first RayState past them one per ray (recordCastRays).
  return passes::queryOutputBytes(count, 0);
}

void castRaysOnDevice(OccupancyMap& map, BufferRange rays, std::uint32_t count, BufferRange results,
                      SignalSemaphore signal) {
  if (results.size != VK_WHOLE_SIZE && results.size < castRaysResultBytes(count))
    throw Error(ErrorCode::kInvalidArgument,
                "castRaysOnDevice: the results range holds " + std::to_string(results.size) +
                    " bytes; castRaysResultBytes(" + std::to_string(count) +
                    ") = " + std::to_string(castRaysResultBytes(count)) + " are needed");
  OccupancyMap::Impl& impl = InteropAccess::impl(map);
  impl.queryOnDevice(true, rays.buffer, rays.offset, rays.size, results.buffer, results.offset,
                     results.size, count);
  impl.signal(signal.semaphore, signal.value);
}

std::size_t changedKeysBytes(std::size_t count) {
  return sizeof(gpu::ChangedKeysHeader) + count * sizeof(gpu::ChangedKey);
}

void changedKeysOnDevice(OccupancyMap& map, BufferRange out, SignalSemaphore signal) {
  OccupancyMap::Impl& impl = InteropAccess::impl(map);
  impl.changedKeysOnDevice(out.buffer, out.offset, out.size);
  impl.signal(signal.semaphore, signal.value);
}

}  // namespace octovk
