// Inside src/vk only: the Vulkan instance (with the validation layer and its messenger when
// asked for) and what each physical device offers, for Device::create and Device::enumerate.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk::vk::detail {

inline constexpr const char* kNoDeviceHint =
    "no Vulkan device found: install Mesa's CPU driver with `apt-get install "
    "mesa-vulkan-drivers` (lavapipe) or a GPU driver, and check `vulkaninfo --summary`";

/// An instance destroyed with its scope (Device::enumerate's).
struct InstanceHandle {
  VkInstance instance = VK_NULL_HANDLE;
  ~InstanceHandle() {
    if (instance) vkDestroyInstance(instance, nullptr);
  }
};

/// The order of preference of device types when no selector names one: lower is better.
int typeRank(VkPhysicalDeviceType t);

/// The validation messenger's settings: warnings and errors, counted (validationMessageCount)
/// and given to `sink` (a std::function<void(const std::string&)>*), or to stderr without one.
VkDebugUtilsMessengerCreateInfoEXT messengerInfo(const void* sink);

/// ContextOptions::enable_validation, or OCTOVK_VALIDATION set and not "0".
bool validationRequested(const ContextOptions& options);

/// With `sink`, the instance runs the validation layer (core and synchronization validation) and
/// reports to it, also while the instance itself is created and destroyed.
VkResult makeInstance(const std::function<void(const std::string&)>* sink, VkInstance* out);

std::vector<VkPhysicalDevice> physicalDevices(VkInstance instance);
std::vector<VkExtensionProperties> deviceExtensions(VkPhysicalDevice pd);
bool hasDeviceExtension(const std::vector<VkExtensionProperties>& available, const char* name);

/// Name, type, driver, device-local memory and ray-tracing support of device `index`.
DeviceInfo describe(VkPhysicalDevice pd, std::uint32_t index);

}  // namespace octovk::vk::detail
