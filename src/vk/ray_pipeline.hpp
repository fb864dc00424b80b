// Ray-tracing pipelines (VK_KHR_ray_tracing_pipeline): the traced passes (castRay's and the scans')
// on devices that trace rays through pipelines rather than ray queries. Each pipeline is a ray
// generation shader (the pass), the hit group of the box geometry (accel_box.rint: the slab test;
// accel_box.rahit: keeps the nearest box) and a miss shader, on the device's one pipeline layout,
// with its shader binding table laid out as the device's properties require.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "vk/buffer.hpp"
#include "vk/command_stream.hpp"

namespace octovk::vk {

class Device;

/// One ray-tracing pipeline and its shader binding table; built by Device::rayPipeline.
class RayPipeline {
 public:
  /// The stages of every pipeline: the descriptor set layout's bindings and the pipeline
  /// layout's second push-constant range include them (Device::createLayouts).
  static constexpr VkShaderStageFlags kStages =
      VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_MISS_BIT_KHR |
      VK_SHADER_STAGE_INTERSECTION_BIT_KHR | VK_SHADER_STAGE_ANY_HIT_BIT_KHR;
  /// Where their push constants start: after the compute passes' (gpu::PassConstants), since
  /// ranges of different stages may not overlap (shaders/ray_stage.glsl's OCTOVK_RAY_CONSTANTS).
  static constexpr std::uint32_t kConstantsOffset = 16;

  /// Builds the pipeline whose ray generation shader is the embedded `raygen`, through `cache`
  /// (may be VK_NULL_HANDLE), and writes its shader binding table.
  RayPipeline(Device& device, std::string_view raygen, VkPipelineCache cache);
  ~RayPipeline();
  RayPipeline(const RayPipeline&) = delete;
  RayPipeline& operator=(const RayPipeline&) = delete;

  /// Records a trace of `items` ray generation invocations (a 1-D workload folded into x and y,
  /// as shaders/ray_stage.glsl's invocationIndex counts them) with `constants` (at most
  /// gpu::PassConstants' 16 B), between barriers that order it after the earlier compute,
  /// transfer and acceleration-structure build work and before the later compute and transfer
  /// work. Binds the descriptor set `set` for it.
  void recordTrace(CommandStream& stream, VkDescriptorSet set, std::uint32_t items,
                   const void* constants, std::uint32_t constants_bytes) const;

 private:
  Device& device_;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  Buffer table_;  // the shader binding table: raygen, miss and hit regions
  VkStridedDeviceAddressRegionKHR raygen_{}, miss_{}, hit_{}, callable_{};
};

/// The ray-tracing pipelines a device has built, by ray generation shader; thread-safe.
class RayPipelines {
 public:
  explicit RayPipelines(Device& device) : device_(device) {}
  /// The pipeline of `raygen`, built by the first caller (a build that throws is tried again).
  const RayPipeline& get(std::string_view raygen, VkPipelineCache cache);

 private:
  Device& device_;
  std::mutex mutex_;
  std::deque<std::pair<std::string, std::unique_ptr<RayPipeline>>> built_;
};

}  // namespace octovk::vk
