#include "vk/buffer.hpp"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "octovk/errors.hpp"
#include "vk/check.hpp"
#include "vk/device.hpp"
#include "vk/fault_injection.hpp"

namespace octovk::vk {

Buffer::Buffer(Device& device, std::size_t bytes, bool host_visible)
    : Buffer(device, bytes, host_visible, 0) {}

namespace {

// An allocation the driver refused, in the user's words: how much was asked for, and from which
// memory. The callers that know what the buffer was for say so and name the remedy.
Error refused(const Error& e, std::size_t bytes, bool host_visible) {
  if (e.code() != ErrorCode::kOutOfDeviceMemory) return e;
  char text[160];
  const char* memory = host_visible ? "host-visible" : "device";
  if (bytes < (std::size_t{1} << 20))
    std::snprintf(text, sizeof(text), "could not allocate %zu bytes of %s memory", bytes, memory);
  else
    std::snprintf(text, sizeof(text), "could not allocate %zu bytes (%.1f MiB) of %s memory", bytes,
                  static_cast<double>(bytes) / (1024.0 * 1024.0), memory);
  return Error(e.code(), e.message() + ": " + text, e.scan(), e.detail());
}

}  // namespace

Buffer::Buffer(Device& device, std::size_t bytes, bool host_visible,
               VkBufferUsageFlags extra_usage) try
    : device_(&device) {
  bytes_ = std::max<std::size_t>(bytes, 16);
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = bytes_;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
               VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT |
               VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | extra_usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  OCTOVK_VK(vkCreateBuffer(device.handle(), &info, nullptr, &buffer_));
  try {
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device.handle(), buffer_, &req);
    VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
    flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.pNext = &flags;
    alloc.allocationSize = req.size;
    if (host_visible) {
      alloc.memoryTypeIndex = device.memoryType(
          req.memoryTypeBits,
          VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT |
              VK_MEMORY_PROPERTY_HOST_CACHED_BIT,
          VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    } else {
      alloc.memoryTypeIndex =
          device.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
    }
    OCTOVK_VK(fault::deviceAllocationFails()
                  ? VK_ERROR_OUT_OF_DEVICE_MEMORY
                  : vkAllocateMemory(device.handle(), &alloc, nullptr, &memory_));
    OCTOVK_VK(vkBindBufferMemory(device.handle(), buffer_, memory_, 0));
    if (host_visible)
      OCTOVK_VK(vkMapMemory(device.handle(), memory_, 0, VK_WHOLE_SIZE, 0, &mapped_));
    VkBufferDeviceAddressInfo address{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    address.buffer = buffer_;
    address_ = vkGetBufferDeviceAddress(device.handle(), &address);
  } catch (...) {
    release();
    throw;
  }
} catch (const Error& e) {
  throw refused(e, std::max<std::size_t>(bytes, 16), host_visible);
}

Buffer::~Buffer() { release(); }

Buffer::Buffer(Buffer&& other) noexcept { *this = std::move(other); }

Buffer& Buffer::operator=(Buffer&& other) noexcept {
  if (this != &other) {
    release();
    device_ = other.device_;
    buffer_ = std::exchange(other.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(other.memory_, VK_NULL_HANDLE);
    bytes_ = std::exchange(other.bytes_, 0);
    mapped_ = std::exchange(other.mapped_, nullptr);
    address_ = std::exchange(other.address_, 0);
  }
  return *this;
}

void Buffer::release() noexcept {
  if (!device_) return;
  if (buffer_) vkDestroyBuffer(device_->handle(), buffer_, nullptr);
  if (memory_) vkFreeMemory(device_->handle(), memory_, nullptr);
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  bytes_ = 0;
  address_ = 0;
}

}  // namespace octovk::vk
