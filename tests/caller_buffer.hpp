// A caller's buffer for the interop tests: a host-visible, host-coherent storage buffer made with
// the Vulkan API alone on the context's device, as an application would make one.
#pragma once

#include <gtest/gtest.h>
#include <vulkan/vulkan.h>

#include "octovk/vulkan_interop.hpp"

namespace octovk::test {

class CallerBuffer {
 public:
  CallerBuffer(const VulkanHandles& vk, VkDeviceSize bytes) : device_(vk.device) {
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = bytes;
    // TRANSFER_DST too: a test's own consumer copies results into one (a caller's submission).
    info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                 VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    EXPECT_EQ(vkCreateBuffer(device_, &info, nullptr, &buffer_), VK_SUCCESS);
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, buffer_, &req);
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(vk.physical_device, &props);
    const VkMemoryPropertyFlags want =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    std::uint32_t type = 0;
    while (type < props.memoryTypeCount &&
           !((req.memoryTypeBits & (1u << type)) &&
             (props.memoryTypes[type].propertyFlags & want) == want))
      ++type;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = type;
    EXPECT_EQ(vkAllocateMemory(device_, &alloc, nullptr, &memory_), VK_SUCCESS);
    vkBindBufferMemory(device_, buffer_, memory_, 0);
    vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_);
  }
  ~CallerBuffer() {
    vkDestroyBuffer(device_, buffer_, nullptr);
    vkFreeMemory(device_, memory_, nullptr);
  }
  CallerBuffer(const CallerBuffer&) = delete;
  CallerBuffer& operator=(const CallerBuffer&) = delete;
  BufferRange range() const { return {buffer_, 0, VK_WHOLE_SIZE}; }
  void* data() const { return mapped_; }

 private:
  VkDevice device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
};

}  // namespace octovk::test
