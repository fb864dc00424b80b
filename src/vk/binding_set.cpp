#include "vk/binding_set.hpp"

#include <cstring>
#include <string>
#include <utility>

#include "gpu/gpu_types.h"
#include "vk/check.hpp"
#include "vk/device.hpp"

namespace octovk::vk {

BindingSet::BindingSet(Device& device)
    : device_(&device),
      addresses_(device, gpu::kBindingCount * sizeof(std::uint64_t), /*host_visible=*/true) {
  std::memset(addresses_.mapped(), 0, addresses_.size());
  VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, gpu::kBindingCount + 1};
  VkDescriptorPoolCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  info.maxSets = 1;
  info.poolSizeCount = 1;
  info.pPoolSizes = &size;
  OCTOVK_VK(vkCreateDescriptorPool(device.handle(), &info, nullptr, &pool_));
  VkDescriptorSetLayout layout = device.setLayout();
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = pool_;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &layout;
  try {
    OCTOVK_VK(vkAllocateDescriptorSets(device.handle(), &alloc, &set_));
    write(gpu::kBindAddresses, addresses_.handle(), 0, VK_WHOLE_SIZE);
  } catch (...) {
    release();
    throw;
  }
}

BindingSet::~BindingSet() { release(); }

BindingSet::BindingSet(BindingSet&& other) noexcept { *this = std::move(other); }

BindingSet& BindingSet::operator=(BindingSet&& other) noexcept {
  if (this != &other) {
    release();
    device_ = other.device_;
    pool_ = std::exchange(other.pool_, VK_NULL_HANDLE);
    set_ = std::exchange(other.set_, VK_NULL_HANDLE);
    addresses_ = std::move(other.addresses_);
  }
  return *this;
}

void BindingSet::release() noexcept {
  if (device_ && pool_) vkDestroyDescriptorPool(device_->handle(), pool_, nullptr);
  pool_ = VK_NULL_HANDLE;
  set_ = VK_NULL_HANDLE;
}

void BindingSet::update(std::span<const Buffer* const> buffers) {
  auto* table = static_cast<std::uint64_t*>(addresses_.mapped());
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    const auto binding = static_cast<std::uint32_t>(i);
    if (gpu::kAddressedBindings & (1u << binding))
      table[binding] = buffers[i]->address();
    else
      write(binding, buffers[i]->handle(), 0, buffers[i]->size());
  }
}

void BindingSet::updateRange(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset,
                             VkDeviceSize size) {
  write(binding, buffer, offset, size);
}

void BindingSet::write(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset,
                       VkDeviceSize size) {
  // A storage buffer descriptor may not reach further than maxStorageBufferRange: what could
  // (the map's arrays) goes by device address, and what is bound here must fit.
  if (size != VK_WHOLE_SIZE && size > device_->maxBindingBytes())
    throw Error(ErrorCode::kInvalidArgument,
                "a buffer range of " + std::to_string(size) + " bytes at binding " +
                    std::to_string(binding) +
                    " exceeds what one binding may hold on this device (" +
                    std::to_string(device_->maxBindingBytes()) +
                    " bytes, maxStorageBufferRange); split the batch");
  VkDescriptorBufferInfo info{buffer, offset, size};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  write.pBufferInfo = &info;
  vkUpdateDescriptorSets(device_->handle(), 1, &write, 0, nullptr);
}

}  // namespace octovk::vk
