// The Vulkan pipeline cache kept between runs: filled from the cache folder (vk/disk_cache.hpp)
// before the device's first pipeline is built, written back by the device's destructor when the
// driver added to it. A GPU driver compiles each compute shader in vkCreateComputePipelines, and
// this lets a second run skip that. OCTOVK_PIPELINE_CACHE=0 turns it off.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <filesystem>
#include <string>

namespace octovk::vk {

/// Whether a pipeline cache is read and written: OCTOVK_PIPELINE_CACHE unset or not "0".
bool pipelineCacheEnabled();

/// One VkPipelineCache, owned. Its handle may be used by several threads at once for
/// vkCreateComputePipelines (it is created without EXTERNALLY_SYNCHRONIZED, so the driver
/// synchronises it); save() and the destructor must not run beside them.
class PipelineCache {
 public:
  /// The cache for `device`, filled from the record at `file` when that holds data of this very
  /// driver (the header Vulkan defines: vendor, device and pipelineCacheUUID) written for `key`;
  /// empty otherwise. handle() is VK_NULL_HANDLE if even an empty cache could not be created:
  /// pipelines are then built without one.
  PipelineCache(VkDevice device, const VkPhysicalDeviceProperties& props,
                std::filesystem::path file, std::string key);
  ~PipelineCache();
  PipelineCache(const PipelineCache&) = delete;
  PipelineCache& operator=(const PipelineCache&) = delete;

  VkPipelineCache handle() const noexcept { return cache_; }
  /// Bytes of driver data it started from (0: it started empty).
  std::size_t loadedBytes() const noexcept { return loaded_bytes_; }
  /// Writes the driver's data to the file when it differs in size from what was loaded (the
  /// driver added pipelines) and holds more than the header; any failure is ignored. Returns
  /// the bytes written, 0 when nothing was.
  std::size_t save() noexcept;

 private:
  VkDevice device_;
  VkPhysicalDeviceProperties props_;
  std::filesystem::path file_;
  std::string key_;
  VkPipelineCache cache_ = VK_NULL_HANDLE;
  std::size_t loaded_bytes_ = 0;
};

}  // namespace octovk::vk
