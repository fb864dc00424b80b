// The thin Vulkan layer: device selection, buffers, compute passes and command streams.
// Mapping code asks for "a buffer", "a pass", "a dispatch"; only this folder knows Vulkan.
// This header is the folder's front door: it brings in every class of the layer (one header
// each) and declares Device, which owns the instance, the queue and the pass cache.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "octovk/octovk.hpp"
#include "vk/binding_set.hpp"
#include "vk/buffer.hpp"
#include "vk/check.hpp"
#include "vk/command_stream.hpp"
#include "vk/pipeline_cache.hpp"

namespace octovk::vk {

class RayPipeline;
class RayPipelines;

/// Instance, physical device, logical device, queue and the shared pipeline layout.
class Device {
 public:
  /// Fails with kNoDevice / kMissingFeature for the ordinary reasons.
  static Result<std::unique_ptr<Device>> create(const ContextOptions& options);
  static std::vector<DeviceInfo> enumerate();
  ~Device();
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  const DeviceInfo& info() const noexcept { return info_; }
  VkDevice handle() const noexcept { return device_; }
  /// Whether this process is a child forked after the device was made: a Vulkan device is not
  /// usable across fork() (the driver's threads are not in the child; waits never end).
  bool forkedAway() const noexcept;
  /// Whether this process may no longer call the driver for this device: a child forked after it
  /// was made, or a process whose exit() has begun running its exit handlers (a driver may tear
  /// itself down in its own: NVIDIA's does, and an object destroyed after that, a static's, then
  /// crashed). Destructors then leave the device's objects to the end of the process.
  bool abandoned() const noexcept;
  /// Keeps what an owner leaves behind on an abandoned device (its Impl, released) reachable
  /// until the process ends, so that leak checkers see it held, not lost.
  static void keepUntilExit(void* object) noexcept;
  /// Throws kInvalidArgument, naming `what`, in such a child.
  void checkNotForked(std::string_view what) const;
  /// Submits to the device's one queue under its lock: every map of a Context records on its
  /// own command pool but shares this queue, which Vulkan requires externally synchronised.
  void submit(const VkSubmitInfo& info, VkFence fence);
  /// The queue, for interop callers, who must hold lockQueue() while they use it.
  VkQueue queue() const noexcept { return queue_; }
  std::unique_lock<std::mutex> lockQueue() { return std::unique_lock<std::mutex>(queue_mutex_); }
  std::uint32_t queueFamily() const noexcept { return queue_family_; }
  VkPipelineLayout pipelineLayout() const noexcept { return pipeline_layout_; }
  VkDescriptorSetLayout setLayout() const noexcept { return set_layout_; }
  /// Nanoseconds per timestamp tick, or 0 when the compute queue has no timestamps.
  double timestampPeriodNs() const noexcept { return timestamp_period_ns_; }
  /// minStorageBufferOffsetAlignment: offsets of bound buffer ranges must be multiples of it.
  VkDeviceSize storageOffsetAlignment() const noexcept { return storage_alignment_; }
  /// maxStorageBufferRange (or ContextOptions::max_binding_bytes if lower): the most bytes one
  /// descriptor binding may reach.
  std::uint64_t maxBindingBytes() const noexcept { return max_binding_bytes_; }
  /// maxComputeWorkGroupCount[0]: the most workgroups an indirect dispatch may ask for.
  std::uint32_t maxGroupsX() const noexcept { return max_groups_x_; }
  VkInstance instance() const noexcept { return instance_; }
  /// Ray queries against acceleration structures (VK_KHR_acceleration_structure and
  /// VK_KHR_ray_query, with their features) are enabled on this device.
  bool rayQuery() const noexcept { return ray_query_; }
  /// Ray-tracing pipelines (VK_KHR_acceleration_structure and VK_KHR_ray_tracing_pipeline, with
  /// their features) are enabled on this device: rayPipelineApi(), rayPipeline().
  bool rayTracingPipeline() const noexcept { return ray_pipeline_api_ != nullptr; }
  /// The acceleration-structure entry points and limits; only when rayQuery() or
  /// rayTracingPipeline().
  struct AccelApi {
    PFN_vkCreateAccelerationStructureKHR create = nullptr;
    PFN_vkDestroyAccelerationStructureKHR destroy = nullptr;
    PFN_vkGetAccelerationStructureBuildSizesKHR buildSizes = nullptr;
    PFN_vkCmdBuildAccelerationStructuresKHR cmdBuild = nullptr;
    PFN_vkGetAccelerationStructureDeviceAddressKHR address = nullptr;
    VkDeviceSize scratch_alignment = 1;  ///< minAccelerationStructureScratchOffsetAlignment
  };
  const AccelApi& accelApi() const noexcept { return *accel_api_; }
  /// The ray-tracing pipeline entry points and the shader binding table's layout rules; only
  /// when rayTracingPipeline().
  struct RayPipelineApi {
    PFN_vkCreateRayTracingPipelinesKHR create = nullptr;
    PFN_vkGetRayTracingShaderGroupHandlesKHR groupHandles = nullptr;
    PFN_vkCmdTraceRaysKHR cmdTrace = nullptr;
    std::uint32_t handle_size = 0;       ///< shaderGroupHandleSize
    std::uint32_t handle_alignment = 1;  ///< shaderGroupHandleAlignment: a record's stride
    std::uint32_t base_alignment = 1;    ///< shaderGroupBaseAlignment: a region's start
    std::uint32_t max_invocations = 0;   ///< maxRayDispatchInvocationCount
  };
  const RayPipelineApi& rayPipelineApi() const noexcept { return *ray_pipeline_api_; }
  /// The ray-tracing pipeline whose ray generation shader is the embedded `raygen` (e.g.
  /// "cast_ray_rt.rgen"), built once, as pass() builds compute passes; only when
  /// rayTracingPipeline().
  const RayPipeline& rayPipeline(std::string_view raygen);
  /// Whether an optional device extension (external memory / semaphore by fd) was enabled.
  bool hasExtension(std::string_view name) const noexcept {
    for (const std::string& e : extensions_)
      if (e == name) return true;
    return false;
  }
  VkPhysicalDevice physical() const noexcept { return physical_; }

  /// Loop iterations after which the driver ends an invocation's loops (llvmpipe: 65535, counted
  /// for a whole SIMD batch), as the device probe measured it; 0 when it saw no limit.
  std::uint32_t loopLimit() const noexcept { return loop_limit_; }
  void setLoopLimit(std::uint32_t limit) noexcept { loop_limit_ = limit; }

  /// The pass built from the embedded shader `name` (e.g. "ray_keys"), built once, by the
  /// first caller from any thread (the others wait for it), through the pipeline cache kept
  /// between runs (vk/pipeline_cache.hpp) unless OCTOVK_PIPELINE_CACHE=0.
  const Pass& pass(std::string_view name);
  /// Builds the passes `names` ahead of their first dispatch, on up to as many threads as the
  /// machine has cores (the calling one included), longest first as listed: a driver that
  /// compiles in vkCreateComputePipelines (llvmpipe, most GPU drivers on a first run) then
  /// compiles them side by side. A build that fails is left to pass(), which tries again and
  /// reports the error to its caller.
  void buildPasses(std::span<const std::string_view> names);

  /// What records kept between runs are written for (vk/disk_cache.hpp): this device (vendor,
  /// device, UUIDs), its driver (name, version, pipelineCacheUUID) and the SPIR-V of this build
  /// of octovk. A record written for another key is never used.
  const std::string& cacheKey() const noexcept { return cache_key_; }
  /// The file for records of `kind` ("pipelines", "probe") of this device and driver in the cache
  /// folder; empty when there is no folder (no OCTOVK_CACHE_DIR, XDG_CACHE_HOME or HOME).
  std::filesystem::path cacheFile(std::string_view kind) const;
  /// Whether the passes built so far went through a VkPipelineCache (false before the first
  /// pass, and with OCTOVK_PIPELINE_CACHE=0).
  bool usesPipelineCache() const noexcept {
    return pipeline_cache_ && pipeline_cache_->handle() != VK_NULL_HANDLE;
  }
  /// The physical device's properties (IDs, pipelineCacheUUID, limits).
  const VkPhysicalDeviceProperties& properties() const noexcept { return properties_; }

  /// Memory type index for the given requirements; throws kOutOfDeviceMemory if none.
  std::uint32_t memoryType(std::uint32_t type_bits, VkMemoryPropertyFlags wanted,
                           VkMemoryPropertyFlags fallback) const;

 private:
  Device();  // out of line: ray_pipelines_'s type is complete in device.cpp
  // The steps of create(), in order; each throws Error when it cannot go on.
  void createInstance(const ContextOptions& options);
  void pickPhysicalDevice(const ContextOptions& options);
  VkPhysicalDeviceVulkan12Features requireFeatures() const;
  void pickQueueFamily(const ContextOptions& options);
  void createLogicalDevice(const VkPhysicalDeviceVulkan12Features& supported, bool ray_query,
                           bool ray_pipeline);
  void loadAccelApi();
  void loadRayPipelineApi();
  void createLayouts();
  void describeForCache(const VkPhysicalDeviceProperties& props);

  DeviceInfo info_;
  std::function<void(const std::string&)> validation_sink_;  // before the instance that uses it
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout_ = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory_{};
  double timestamp_period_ns_ = 0.0;
  VkDeviceSize storage_alignment_ = 256;
  std::uint32_t max_groups_x_ = 65535;
  std::uint32_t loop_limit_ = 0;
  std::uint64_t max_binding_bytes_ = 1u << 27;
  long creator_pid_ = 0;           // the process that made the device
  std::mutex queue_mutex_;         // guards queue_ (vkQueueSubmit) and submissions_
  std::uint64_t submissions_ = 0;  // for OCTOVK_TRACE_STARTUP only
  struct PassSlot {
    Pass pass;
    std::once_flag built;  // set once pass.pipeline is built
  };
  VkPipeline buildPipeline(std::string_view name);
  VkPipelineCache pipelineCache();
  VkPhysicalDeviceProperties properties_{};
  std::string cache_key_;
  std::string cache_name_;  // the device-and-driver part of the key, hashed: the files' names
  std::once_flag pipeline_cache_loaded_;
  std::unique_ptr<PipelineCache> pipeline_cache_;  // after the first pass, unless turned off
  std::mutex passes_mutex_;                        // guards the deque (not the builds: see pass())
  std::deque<PassSlot> passes_;                    // deque: slots never move
  std::vector<std::string> extensions_;            // optional device extensions enabled
  bool ray_query_ = false;                         // ray queries are enabled
  std::unique_ptr<AccelApi> accel_api_;            // set when either kind of ray tracing is
  std::unique_ptr<RayPipelineApi> ray_pipeline_api_;  // set when ray-tracing pipelines are
  std::unique_ptr<RayPipelines> ray_pipelines_;       // built ones, destroyed before the device
};

}  // namespace octovk::vk
