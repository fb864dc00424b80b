// The buffers bound to the one descriptor set layout every pass shares.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <span>

#include "vk/buffer.hpp"

namespace octovk::vk {

class Device;

/// The buffers bound to the shared descriptor set layout, binding i = buffers[i]: by descriptor,
/// or for the bindings in gpu::kAddressedBindings by device address, through the address table
/// this set owns (bound at gpu::kBindAddresses).
class BindingSet {
 public:
  BindingSet() = default;
  explicit BindingSet(Device& device);
  ~BindingSet();
  BindingSet(BindingSet&& other) noexcept;
  BindingSet& operator=(BindingSet&& other) noexcept;
  BindingSet(const BindingSet&) = delete;
  BindingSet& operator=(const BindingSet&) = delete;

  /// Points every binding at its buffer; call after any buffer is replaced, while idle. Throws
  /// kInvalidArgument when a descriptor-bound buffer exceeds the device's binding range.
  void update(std::span<const Buffer* const> buffers);
  /// Points one descriptor binding at a range of a buffer the caller owns (interop); the same
  /// range check.
  void updateRange(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize size);
  VkDescriptorSet handle() const noexcept { return set_; }

 private:
  void release() noexcept;
  void write(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize size);
  Device* device_ = nullptr;
  Buffer addresses_;  // uint64_t[kBindingCount]: the device address of each addressed binding
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
};

}  // namespace octovk::vk
