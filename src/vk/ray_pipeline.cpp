#include "vk/ray_pipeline.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"
#include "vk/accel.hpp"
#include "vk/device.hpp"
#include "vk/shader_registry.hpp"

namespace octovk::vk {

static_assert(RayPipeline::kConstantsOffset == sizeof(gpu::PassConstants),
              "the pipelines' push constants follow the compute passes'");

namespace {

VkDeviceSize alignUp(VkDeviceSize v, VkDeviceSize a) { return (v + a - 1) / a * a; }

// The stages after the ray generation shader, the same in every pipeline.
constexpr std::array<std::pair<const char*, VkShaderStageFlagBits>, 3> kHitStages{{
    {"accel_box.rmiss", VK_SHADER_STAGE_MISS_BIT_KHR},
    {"accel_box.rint", VK_SHADER_STAGE_INTERSECTION_BIT_KHR},
    {"accel_box.rahit", VK_SHADER_STAGE_ANY_HIT_BIT_KHR},
}};

VkShaderModule shaderModule(VkDevice device, std::string_view name) {
  const std::span<const std::uint32_t> code = findShader(name);
  if (code.empty())
    throw Error(ErrorCode::kInternal, "no embedded shader named '" + std::string(name) + "'");
  VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  info.codeSize = code.size() * sizeof(std::uint32_t);
  info.pCode = code.data();
  VkShaderModule module = VK_NULL_HANDLE;
  OCTOVK_VK(vkCreateShaderModule(device, &info, nullptr, &module));
  return module;
}

}  // namespace

RayPipeline::RayPipeline(Device& device, std::string_view raygen, VkPipelineCache cache)
    : device_(device) {
  const Device::RayPipelineApi& api = device.rayPipelineApi();
  const VkDevice dev = device.handle();
  // Stage 0 the ray generation shader, then the miss, intersection and any-hit shaders; the
  // groups: ray generation, miss, and the boxes' procedural hit group (no closest hit: the
  // any-hit shader keeps the nearest box in the payload).
  std::array<VkPipelineShaderStageCreateInfo, 4> stages{};
  for (std::size_t i = 0; i < stages.size(); ++i) {
    stages[i] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    stages[i].pName = "main";
  }
  stages[0].stage = VK_SHADER_STAGE_RAYGEN_BIT_KHR;
  for (std::size_t i = 0; i < kHitStages.size(); ++i) stages[i + 1].stage = kHitStages[i].second;
  try {
    stages[0].module = shaderModule(dev, raygen);
    for (std::size_t i = 0; i < kHitStages.size(); ++i)
      stages[i + 1].module = shaderModule(dev, kHitStages[i].first);
  } catch (...) {
    for (const auto& s : stages)
      if (s.module) vkDestroyShaderModule(dev, s.module, nullptr);
    throw;
  }
  std::array<VkRayTracingShaderGroupCreateInfoKHR, 3> groups{};
  for (auto& g : groups) {
    g = {VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
    g.generalShader = g.closestHitShader = g.anyHitShader = g.intersectionShader =
        VK_SHADER_UNUSED_KHR;
  }
  groups[0].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[0].generalShader = 0;
  groups[1].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[1].generalShader = 1;
  groups[2].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_PROCEDURAL_HIT_GROUP_KHR;
  groups[2].intersectionShader = 2;
  groups[2].anyHitShader = 3;
  VkRayTracingPipelineCreateInfoKHR info{VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};
  info.stageCount = static_cast<std::uint32_t>(stages.size());
  info.pStages = stages.data();
  info.groupCount = static_cast<std::uint32_t>(groups.size());
  info.pGroups = groups.data();
  info.maxPipelineRayRecursionDepth = 1;  // the ray generation shader traces; nothing else does
  info.layout = device.pipelineLayout();
  const VkResult r = api.create(dev, VK_NULL_HANDLE, cache, 1, &info, nullptr, &pipeline_);
  for (const auto& s : stages) vkDestroyShaderModule(dev, s.module, nullptr);
  check(r, "vkCreateRayTracingPipelinesKHR", __FILE__, __LINE__);

  // The table: one record per group, each region starting at a multiple of
  // shaderGroupBaseAlignment, records shaderGroupHandleAlignment apart (a ray generation
  // region's size must equal its stride).
  const std::uint32_t handle = api.handle_size;
  std::vector<std::uint8_t> handles(groups.size() * handle);
  try {
    OCTOVK_VK(api.groupHandles(dev, pipeline_, 0, static_cast<std::uint32_t>(groups.size()),
                               handles.size(), handles.data()));
    const VkDeviceSize stride = alignUp(handle, api.handle_alignment);
    const VkDeviceSize region = alignUp(stride, api.base_alignment);
    // Room for aligning the buffer's device address too.
    table_ = Buffer(device, static_cast<std::size_t>(groups.size() * region + api.base_alignment),
                    /*host_visible=*/true, VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR);
    const VkDeviceAddress base = alignUp(table_.address(), api.base_alignment);
    auto* bytes = static_cast<std::uint8_t*>(table_.mapped());
    VkStridedDeviceAddressRegionKHR* regions[] = {&raygen_, &miss_, &hit_};
    for (std::size_t g = 0; g < groups.size(); ++g) {
      const VkDeviceAddress at = base + g * region;
      std::memcpy(bytes + (at - table_.address()), handles.data() + g * handle, handle);
      *regions[g] = {at, stride, stride};
    }
  } catch (...) {
    vkDestroyPipeline(dev, pipeline_, nullptr);
    throw;
  }
}

RayPipeline::~RayPipeline() {
  if (pipeline_) vkDestroyPipeline(device_.handle(), pipeline_, nullptr);
}

void RayPipeline::recordTrace(CommandStream& stream, VkDescriptorSet set, std::uint32_t items,
                              const void* constants, std::uint32_t constants_bytes) const {
  if (items == 0) return;
  const Device::RayPipelineApi& api = device_.rayPipelineApi();
  if (items > api.max_invocations)
    throw Error(ErrorCode::kInvalidArgument,
                "a trace of " + std::to_string(items) + " rays is more than device '" +
                    device_.info().name + "' launches at once (maxRayDispatchInvocationCount " +
                    std::to_string(api.max_invocations) + "); use the ray-query or walk backend");
  const VkCommandBuffer cmd = stream.commandBuffer();
  // The structures just built, the boxes and the inputs the compute passes and transfers wrote.
  memoryBarrier(cmd,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                    VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT |
                    VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                    VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipeline_);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, device_.pipelineLayout(), 0,
                          1, &set, 0, nullptr);
  vkCmdPushConstants(cmd, device_.pipelineLayout(), kStages, kConstantsOffset, constants_bytes,
                     constants);
  // Rows of 2^16 invocations: far inside every device's launch limits.
  const std::uint32_t width = std::min<std::uint32_t>(items, 1u << 16);
  const std::uint32_t height = (items + width - 1) / width;
  api.cmdTrace(cmd, &raygen_, &miss_, &hit_, &callable_, width, height, 1);
  // Its writes (results, marked cells), read by later passes, transfers and indirect dispatches.
  memoryBarrier(cmd, VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_SHADER_WRITE_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                    VK_PIPELINE_STAGE_DRAW_INDIRECT_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                    VK_ACCESS_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                    VK_ACCESS_TRANSFER_WRITE_BIT);
}

const RayPipeline& RayPipelines::get(std::string_view raygen, VkPipelineCache cache) {
  // Built under the lock: two or three pipelines per device, each built once.
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [name, pipeline] : built_)
    if (name == raygen) return *pipeline;
  auto pipeline = std::make_unique<RayPipeline>(device_, raygen, cache);
  return *built_.emplace_back(std::string(raygen), std::move(pipeline)).second;
}

}  // namespace octovk::vk
