// Vulkan results as octovk errors: the one check every Vulkan call of this folder goes through.
#pragma once

#include <vulkan/vulkan.h>

#include <string>

namespace octovk::vk {

/// Throws octovk::Error when r fails: kOutOfDeviceMemory for the out-of-memory results, else
/// kVulkan; what() says it in words (resultWords), detail() names the call, the VkResult and the
/// source place.
void check(VkResult r, const char* call, const char* file, int line);
#define OCTOVK_VK(call) ::octovk::vk::check((call), #call, __FILE__, __LINE__)

const char* resultName(VkResult r);
/// What a failed VkResult means, in words for the user (no Vulkan names but an unknown result's).
std::string resultWords(VkResult r);

}  // namespace octovk::vk
