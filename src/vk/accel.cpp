#include "vk/accel.hpp"

#include <algorithm>
#include <cstring>
#include <utility>
#include <vector>

namespace octovk::vk {

// ---------------------------------------------------------------------------------------------
// AccelerationStructure

AccelerationStructure::AccelerationStructure(Device& device, VkAccelerationStructureTypeKHR type,
                                             VkDeviceSize bytes)
    : device_(&device),
      storage_(device, bytes, /*host_visible=*/false,
               VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR) {
  VkAccelerationStructureCreateInfoKHR info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};
  info.buffer = storage_.handle();
  info.offset = 0;  // offsets must be multiples of 256: each structure has its own buffer
  info.size = bytes;
  info.type = type;
  OCTOVK_VK(device.accelApi().create(device.handle(), &info, nullptr, &handle_));
  VkAccelerationStructureDeviceAddressInfoKHR address{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
  address.accelerationStructure = handle_;
  address_ = device.accelApi().address(device.handle(), &address);
}

AccelerationStructure::~AccelerationStructure() { release(); }

AccelerationStructure::AccelerationStructure(AccelerationStructure&& other) noexcept {
  *this = std::move(other);
}

AccelerationStructure& AccelerationStructure::operator=(AccelerationStructure&& other) noexcept {
  if (this != &other) {
    release();
    device_ = other.device_;
    storage_ = std::move(other.storage_);
    handle_ = std::exchange(other.handle_, VK_NULL_HANDLE);
    address_ = std::exchange(other.address_, 0);
  }
  return *this;
}

void AccelerationStructure::release() noexcept {
  if (device_ && handle_) device_->accelApi().destroy(device_->handle(), handle_, nullptr);
  handle_ = VK_NULL_HANDLE;
  address_ = 0;
  storage_ = Buffer();
}

void memoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                   VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 1, &b, 0, nullptr, 0, nullptr);
}

// ---------------------------------------------------------------------------------------------
// BoxScene

namespace {

VkDeviceSize alignUp(VkDeviceSize v, VkDeviceSize a) { return (v + a - 1) / a * a; }

// Whether a structure of `bytes` is kept: one exists and is large enough.
bool keeps(const AccelerationStructure& as, VkDeviceSize bytes) {
  return as.handle() != VK_NULL_HANDLE && as.size() >= bytes;
}
// What a structure made for `bytes` gets: a quarter more, for the next builds.
VkDeviceSize withHeadroom(VkDeviceSize bytes) { return bytes + bytes / 4; }

// A structure of at least `bytes`, kept while it is large enough.
void ensureStructure(Device& device, AccelerationStructure& as, VkAccelerationStructureTypeKHR type,
                     VkDeviceSize bytes) {
  if (keeps(as, bytes)) return;
  as = AccelerationStructure();
  as = AccelerationStructure(device, type, withHeadroom(bytes));
}

// The geometry and build info of a bottom-level structure over `g` (pGeometries left unset:
// the caller points it at its own copy of `geo`).
void bottomLevel(const BoxGeometry& g, VkAccelerationStructureGeometryKHR& geo,
                 VkAccelerationStructureBuildGeometryInfoKHR& build) {
  geo = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  geo.geometryType = VK_GEOMETRY_TYPE_AABBS_KHR;
  geo.geometry.aabbs = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_AABBS_DATA_KHR};
  geo.geometry.aabbs.data.deviceAddress = g.data;
  geo.geometry.aabbs.stride = sizeof(VkAabbPositionsKHR);
  geo.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
  build = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  build.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
  build.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  build.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  build.geometryCount = 1;
}

// The same for the top-level structure over the instances.
void topLevel(VkAccelerationStructureGeometryKHR& geo,
              VkAccelerationStructureBuildGeometryInfoKHR& build) {
  geo = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  geo.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  geo.geometry.instances = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR};
  geo.geometry.instances.arrayOfPointers = VK_FALSE;
  geo.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
  build = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  build.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  build.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  build.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  build.geometryCount = 1;
}

// A geometry of count 0 is built from one (inactive) box.
std::uint32_t boxCount(const BoxGeometry& g) { return std::max<std::uint32_t>(g.count, 1); }

}  // namespace

BoxScene::Sizes BoxScene::sizes(std::span<const BoxGeometry> geometries) const {
  const Device::AccelApi& api = device_->accelApi();
  const VkDevice dev = device_->handle();
  const VkDeviceSize align = api.scratch_alignment;
  Sizes out;
  // One bottom-level structure per array, each with its own scratch region (so the builds need
  // no barrier between them), then the top-level one (reusing the scratch after a barrier).
  for (const BoxGeometry& g : geometries) {
    VkAccelerationStructureGeometryKHR geo;
    VkAccelerationStructureBuildGeometryInfoKHR build;
    bottomLevel(g, geo, build);
    build.pGeometries = &geo;
    const std::uint32_t count = boxCount(g);
    VkAccelerationStructureBuildSizesInfoKHR sizes{
        VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
    api.buildSizes(dev, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &build, &count, &sizes);
    out.blas.push_back(sizes.accelerationStructureSize);
    out.scratch_offset.push_back(out.scratch);
    out.scratch = alignUp(out.scratch + sizes.buildScratchSize, align);
  }
  VkAccelerationStructureGeometryKHR tgeo;
  VkAccelerationStructureBuildGeometryInfoKHR tbuild;
  topLevel(tgeo, tbuild);
  tbuild.pGeometries = &tgeo;
  const auto instance_count = static_cast<std::uint32_t>(geometries.size());
  VkAccelerationStructureBuildSizesInfoKHR tsizes{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  api.buildSizes(dev, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &tbuild, &instance_count,
                 &tsizes);
  out.tlas = tsizes.accelerationStructureSize;
  out.scratch = std::max(out.scratch, alignUp(tsizes.buildScratchSize, align));
  out.instances = geometries.size() * sizeof(VkAccelerationStructureInstanceKHR);
  return out;
}

std::size_t BoxScene::bytesAfterBuild(std::span<const BoxGeometry> geometries) const {
  const Sizes need = sizes(geometries);
  const VkDeviceSize align = device_->accelApi().scratch_alignment;
  std::size_t bytes = 0;
  for (std::size_t i = 0; i < need.blas.size(); ++i)
    bytes += i < blas_.size() && keeps(blas_[i], need.blas[i]) ? blas_[i].size()
                                                               : withHeadroom(need.blas[i]);
  bytes += keeps(tlas_, need.tlas) ? tlas_.size() : withHeadroom(need.tlas);
  bytes += scratch_.valid() && scratch_.size() >= need.scratch + align
               ? scratch_.size()
               : need.scratch + need.scratch / 4 + align;
  bytes += instances_.valid() && instances_.size() >= need.instances ? instances_.size()
                                                                     : need.instances;
  return bytes;
}

void BoxScene::recordBuild(CommandStream& stream, std::span<const BoxGeometry> geometries) {
  const Device::AccelApi& api = device_->accelApi();
  const std::size_t n = geometries.size();
  const VkDeviceSize align = api.scratch_alignment;
  const Sizes need = sizes(geometries);

  std::vector<VkAccelerationStructureGeometryKHR> geo(n);
  std::vector<VkAccelerationStructureBuildGeometryInfoKHR> build(n);
  std::vector<VkAccelerationStructureBuildRangeInfoKHR> range(n);
  blas_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    bottomLevel(geometries[i], geo[i], build[i]);
    build[i].pGeometries = &geo[i];
    range[i] = {boxCount(geometries[i]), 0, 0, 0};
    ensureStructure(*device_, blas_[i], VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR,
                    need.blas[i]);
  }
  VkAccelerationStructureGeometryKHR tgeo;
  VkAccelerationStructureBuildGeometryInfoKHR tbuild;
  topLevel(tgeo, tbuild);
  tbuild.pGeometries = &tgeo;
  const auto instance_count = static_cast<std::uint32_t>(n);
  ensureStructure(*device_, tlas_, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR, need.tlas);

  // Room for aligning the scratch's device address too.
  const VkDeviceSize scratch_bytes = need.scratch;
  if (!scratch_.valid() || scratch_.size() < scratch_bytes + align) {
    scratch_ = Buffer();
    scratch_ = Buffer(*device_, scratch_bytes + scratch_bytes / 4 + align, false);
  }
  const VkDeviceAddress scratch = alignUp(scratch_.address(), align);
  const std::size_t instance_bytes = need.instances;
  if (!instances_.valid() || instances_.size() < instance_bytes)
    instances_ = Buffer(*device_, instance_bytes, false,
                        VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR);

  std::vector<VkAccelerationStructureInstanceKHR> inst(n);
  for (std::size_t i = 0; i < n; ++i) {
    inst[i] = {};
    inst[i].transform.matrix[0][0] = inst[i].transform.matrix[1][1] =
        inst[i].transform.matrix[2][2] = 1.0f;
    inst[i].instanceCustomIndex = static_cast<std::uint32_t>(i) & 0xFFFFFFu;
    inst[i].mask = geometries[i].mask & 0xFFu;
    inst[i].flags = VK_GEOMETRY_INSTANCE_FORCE_OPAQUE_BIT_KHR;
    inst[i].accelerationStructureReference = blas_[i].address();
  }

  const VkCommandBuffer cmd = stream.commandBuffer();
  stream.update(instances_, inst.data(), instance_bytes);
  // The boxes (written by a compute pass or a transfer) and the instances, read by the build;
  // the scratch and the structures, which earlier work may have used, written by it.
  memoryBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR |
                    VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR);
  std::vector<const VkAccelerationStructureBuildRangeInfoKHR*> ranges(n);
  for (std::size_t i = 0; i < n; ++i) {
    build[i].dstAccelerationStructure = blas_[i].handle();
    build[i].scratchData.deviceAddress = scratch + need.scratch_offset[i];
    ranges[i] = &range[i];
  }
  if (n) api.cmdBuild(cmd, static_cast<std::uint32_t>(n), build.data(), ranges.data());
  // The bottom-level structures, read by the top-level build, whose scratch overlaps theirs.
  memoryBarrier(cmd, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR |
                    VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR);
  tgeo.geometry.instances.data.deviceAddress = instances_.address();
  tbuild.dstAccelerationStructure = tlas_.handle();
  tbuild.scratchData.deviceAddress = scratch;
  const VkAccelerationStructureBuildRangeInfoKHR trange{instance_count, 0, 0, 0};
  const VkAccelerationStructureBuildRangeInfoKHR* tranges = &trange;
  api.cmdBuild(cmd, 1, &tbuild, &tranges);
  // The structures, read by ray queries in later compute passes.
  memoryBarrier(cmd, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);
}

std::size_t BoxScene::deviceBytes() const noexcept {
  std::size_t bytes = tlas_.size() + instances_.size() + scratch_.size();
  for (const AccelerationStructure& b : blas_) bytes += b.size();
  return bytes;
}

void BoxScene::release() noexcept {
  blas_.clear();
  tlas_ = AccelerationStructure();
  instances_ = Buffer();
  scratch_ = Buffer();
}

}  // namespace octovk::vk
