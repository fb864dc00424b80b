// The library's (and its tests') way from a Context to its Vulkan device, which the public header
// does not hand out.
#pragma once

#include <memory>

#include "octovk/context.hpp"
#include "vk/device.hpp"

namespace octovk {

struct ContextAccess {
  static vk::Device& device(Context& context) noexcept { return *context.device_; }
  /// Shared with the maps, which keep it alive (Context's lifetime rule).
  static std::shared_ptr<vk::Device> shared(const Context& context) noexcept {
    return context.device_;
  }
};

}  // namespace octovk
