#include "vk/check.hpp"

#include <sstream>

#include "octovk/octovk.hpp"

namespace octovk::vk {

const char* resultName(VkResult r) {
  switch (r) {
    case VK_SUCCESS:
      return "VK_SUCCESS";
    case VK_NOT_READY:
      return "VK_NOT_READY";
    case VK_TIMEOUT:
      return "VK_TIMEOUT";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST:
      return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED:
      return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT:
      return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
      return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT:
      return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS:
      return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_OUT_OF_POOL_MEMORY:
      return "VK_ERROR_OUT_OF_POOL_MEMORY";
    default:
      return "VkResult(other)";
  }
}

std::string resultWords(VkResult r) {
  switch (r) {
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "the Vulkan device is out of memory";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "the Vulkan driver is out of host memory";
    case VK_ERROR_DEVICE_LOST:
      return "the Vulkan device was lost (a driver reset, a GPU fault or a time-out)";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "the Vulkan driver failed to initialise";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "the Vulkan driver is incompatible";
    case VK_ERROR_TOO_MANY_OBJECTS:
      return "the Vulkan driver has too many objects";
    default:
      return std::string("the Vulkan driver failed unexpectedly (") + resultName(r) + ")";
  }
}

void check(VkResult r, const char* call, const char* file, int line) {
  if (r == VK_SUCCESS) return;
  // The user reads words and the remedy (set OCTOVK_DEBUG for the rest); the call, the result
  // and the source place are the developer's, in Error::detail().
  std::ostringstream detail;
  detail << call << " failed with " << resultName(r) << " (" << int(r) << ") at " << file << ":"
         << line;
  const bool oom = r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY;
  throw Error(oom ? ErrorCode::kOutOfDeviceMemory : ErrorCode::kVulkan, resultWords(r), 0,
              detail.str());
}

}  // namespace octovk::vk
