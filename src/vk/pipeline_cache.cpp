#include "vk/pipeline_cache.hpp"

#include <cstdlib>
#include <cstring>
#include <optional>
#include <utility>
#include <vector>

#include "vk/disk_cache.hpp"

namespace octovk::vk {

namespace {

constexpr const char* kKind = "pipeline";

// Data the driver gave for this very device: the header Vulkan defines
// (VkPipelineCacheHeaderVersionOne) names it. Checked before the driver sees the data, so that a
// file from another GPU or driver never reaches a driver that might trust it.
bool ownData(const std::vector<std::byte>& data, const VkPhysicalDeviceProperties& props) {
  VkPipelineCacheHeaderVersionOne h;
  if (data.size() < sizeof h) return false;
  std::memcpy(&h, data.data(), sizeof h);
  return h.headerSize >= sizeof h && h.headerSize <= data.size() &&
         h.headerVersion == VK_PIPELINE_CACHE_HEADER_VERSION_ONE && h.vendorID == props.vendorID &&
         h.deviceID == props.deviceID &&
         std::memcmp(h.pipelineCacheUUID, props.pipelineCacheUUID, VK_UUID_SIZE) == 0;
}

}  // namespace

bool pipelineCacheEnabled() {
  const char* env = std::getenv("OCTOVK_PIPELINE_CACHE");
  return !(env && std::strcmp(env, "0") == 0);
}

PipelineCache::PipelineCache(VkDevice device, const VkPhysicalDeviceProperties& props,
                             std::filesystem::path file, std::string key)
    : device_(device), props_(props), file_(std::move(file)), key_(std::move(key)) {
  std::optional<std::vector<std::byte>> data;
  try {
    data = disk::readRecord(file_, kKind, key_);
  } catch (...) {  // e.g. no memory for the file: start empty
    data.reset();
  }
  if (data && !ownData(*data, props_)) data.reset();
  VkPipelineCacheCreateInfo info{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  if (data) {
    info.initialDataSize = data->size();
    info.pInitialData = data->data();
  }
  if (vkCreatePipelineCache(device_, &info, nullptr, &cache_) == VK_SUCCESS) {
    if (data) loaded_bytes_ = data->size();
    return;
  }
  cache_ = VK_NULL_HANDLE;
  if (!data) return;
  // The driver refused the data: start empty.
  info.initialDataSize = 0;
  info.pInitialData = nullptr;
  if (vkCreatePipelineCache(device_, &info, nullptr, &cache_) != VK_SUCCESS)
    cache_ = VK_NULL_HANDLE;
}

PipelineCache::~PipelineCache() {
  if (cache_) vkDestroyPipelineCache(device_, cache_, nullptr);
}

std::size_t PipelineCache::save() noexcept {
  if (!cache_ || file_.empty()) return 0;
  try {
    std::size_t size = 0;
    if (vkGetPipelineCacheData(device_, cache_, &size, nullptr) != VK_SUCCESS) return 0;
    if (size == loaded_bytes_ || size <= sizeof(VkPipelineCacheHeaderVersionOne)) return 0;
    std::vector<std::byte> data(size);
    // VK_INCOMPLETE (the cache grew between the calls) leaves a shorter but valid prefix; only
    // whole data is kept.
    if (vkGetPipelineCacheData(device_, cache_, &size, data.data()) != VK_SUCCESS) return 0;
    data.resize(size);
    if (!ownData(data, props_)) return 0;
    return disk::writeRecord(file_, kKind, key_, data) ? size : 0;
  } catch (...) {
    return 0;
  }
}

}  // namespace octovk::vk
