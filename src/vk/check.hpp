// Vulkan results as octovk errors: the one check every Vulkan call of this folder goes through.
#pragma once

#include <vulkan/vulkan.h>

namespace octovk::vk {

/// Throws octovk::Error(kVulkan) naming the call, the VkResult and the place when r fails.
void check(VkResult r, const char* call, const char* file, int line);
#define OCTOVK_VK(call) ::octovk::vk::check((call), #call, __FILE__, __LINE__)

const char* resultName(VkResult r);

}  // namespace octovk::vk
