// Acceleration structures over axis-aligned boxes (VK_KHR_acceleration_structure), built on the
// device from box arrays that passes wrote, for ray queries in compute shaders (VK_KHR_ray_query)
// or ray-tracing pipelines (VK_KHR_ray_tracing_pipeline, vk/ray_pipeline.hpp). Only on a device
// with vk::Device::rayQuery() or rayTracingPipeline().
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "vk/device.hpp"

namespace octovk::vk {

/// A global memory barrier (the builds' and the traces' stages, which CommandStream::barrier
/// does not cover).
void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                   VkPipelineStageFlags dst_stage, VkAccessFlags dst_access);

/// One acceleration structure and the buffer that holds it; one owner.
class AccelerationStructure {
 public:
  AccelerationStructure() = default;
  AccelerationStructure(Device& device, VkAccelerationStructureTypeKHR type, VkDeviceSize bytes);
  ~AccelerationStructure();
  AccelerationStructure(AccelerationStructure&& other) noexcept;
  AccelerationStructure& operator=(AccelerationStructure&& other) noexcept;
  AccelerationStructure(const AccelerationStructure&) = delete;
  AccelerationStructure& operator=(const AccelerationStructure&) = delete;

  VkAccelerationStructureKHR handle() const noexcept { return handle_; }
  VkDeviceAddress address() const noexcept { return address_; }
  VkDeviceSize size() const noexcept { return storage_.size(); }

 private:
  void release() noexcept;
  Device* device_ = nullptr;
  Buffer storage_;
  VkAccelerationStructureKHR handle_ = VK_NULL_HANDLE;
  VkDeviceAddress address_ = 0;
};

/// Boxes for one bottom-level structure: `count` VkAabbPositionsKHR (24 B each, stride 24) at
/// device address `data` (8-byte aligned), the instance's `mask` for ray queries' cull masks.
/// A box whose min x is NaN is inactive. `count` may be 0 (the build then gets one inactive box,
/// written by the caller at `data`, see recordBuild).
struct BoxGeometry {
  VkDeviceAddress data = 0;
  std::uint32_t count = 0;
  std::uint32_t mask = 0xFF;
};

/// One bottom-level structure per box array and a top-level one with one instance of each
/// (identity transform, instance custom index = the array's index), built on the device. Owns
/// the structures, the instance buffer and the build scratch; grows them as needed.
class BoxScene {
 public:
  explicit BoxScene(Device& device) : device_(&device) {}

  /// Records the builds into `stream` (after a barrier that makes earlier shader and transfer
  /// writes of the boxes visible to the build) and a barrier that makes the structures visible
  /// to later compute shaders' ray queries (a pipeline's trace has its own,
  /// RayPipeline::recordTrace). Allocates before recording, so call it while the
  /// device does not use the scene. A geometry with count 0 is built from one box at its `data`,
  /// which must then hold an inactive box.
  void recordBuild(CommandStream& stream, std::span<const BoxGeometry> geometries);
  /// Device bytes the scene would hold after recordBuild(geometries): the structures and buffers
  /// it keeps (large enough) and the ones it would make (with their headroom); for a memory cap
  /// checked before the build. Allocates nothing.
  std::size_t bytesAfterBuild(std::span<const BoxGeometry> geometries) const;
  /// Device address of the top-level structure (0 before the first build).
  VkDeviceAddress tlasAddress() const noexcept { return tlas_.address(); }
  /// Device bytes held: structures, instances, scratch.
  std::size_t deviceBytes() const noexcept;
  /// Frees everything (the next build allocates again).
  void release() noexcept;

 private:
  /// What a build over some geometries needs: each bottom-level structure, the top-level one,
  /// the scratch (the bottom-level builds' regions side by side, aligned) and the instances.
  struct Sizes {
    std::vector<VkDeviceSize> blas;
    std::vector<VkDeviceSize> scratch_offset;
    VkDeviceSize tlas = 0, scratch = 0, instances = 0;
  };
  Sizes sizes(std::span<const BoxGeometry> geometries) const;

  Device* device_;
  std::vector<AccelerationStructure> blas_;
  AccelerationStructure tlas_;
  Buffer instances_;
  Buffer scratch_;
};

}  // namespace octovk::vk
