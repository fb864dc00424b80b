// A storage buffer with one owner, allocated on a Device.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>

namespace octovk::vk {

class Device;

/// A storage buffer with one owner. Device-local unless created host-visible.
class Buffer {
 public:
  Buffer() = default;
  Buffer(Device& device, std::size_t bytes, bool host_visible);
  /// With usages beyond the storage/transfer/indirect/address set every buffer has (the
  /// acceleration-structure ones: only on a device with ray queries enabled).
  Buffer(Device& device, std::size_t bytes, bool host_visible, VkBufferUsageFlags extra_usage);
  ~Buffer();
  Buffer(Buffer&& other) noexcept;
  Buffer& operator=(Buffer&& other) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer handle() const noexcept { return buffer_; }
  std::size_t size() const noexcept { return bytes_; }
  bool valid() const noexcept { return buffer_ != VK_NULL_HANDLE; }
  /// Host pointer of a host-visible buffer (persistently mapped).
  void* mapped() const noexcept { return mapped_; }
  /// Device address (bufferDeviceAddress), for the bindings the shaders reach by address.
  VkDeviceAddress address() const noexcept { return address_; }

 private:
  void release() noexcept;
  Device* device_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  std::size_t bytes_ = 0;
  void* mapped_ = nullptr;
  VkDeviceAddress address_ = 0;
};

}  // namespace octovk::vk
