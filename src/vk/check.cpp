#include "vk/check.hpp"

#include <sys/resource.h>

#include <cstdio>
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

namespace {

// Where the process's address space is limited (`ulimit -v`): the limit and its remedy, since a
// GPU driver reserves far more address space than it uses (NVIDIA's fails to start under 4 GiB);
// empty where there is no limit.
std::string addressSpaceNote() {
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return {};
  char text[160];
  std::snprintf(text, sizeof text,
                " (this process's address space is limited to %.1f GiB by `ulimit -v`, and GPU "
                "drivers reserve more: raise or remove the limit)",
                static_cast<double>(limit.rlim_cur) / (1024.0 * 1024.0 * 1024.0));
  return text;
}

}  // namespace

std::string resultWords(VkResult r) {
  switch (r) {
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "the Vulkan device is out of memory";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "the Vulkan driver is out of host memory" + addressSpaceNote();
    case VK_ERROR_DEVICE_LOST:
      return "the Vulkan device was lost (a driver reset, a GPU fault or a time-out)";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "the Vulkan driver failed to initialise" + addressSpaceNote();
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
