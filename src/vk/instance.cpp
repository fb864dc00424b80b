#include "vk/instance.hpp"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <string_view>

namespace octovk::vk {

namespace {

const char* typeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "CPU";
    default:
      return "other";
  }
}

std::atomic<std::size_t> validation_messages{0};

// The validation layer's messages: counted, then given to the Context's callback or stderr.
VKAPI_ATTR VkBool32 VKAPI_CALL onValidationMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                   VkDebugUtilsMessageTypeFlagsEXT,
                                                   const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                   void* user) {
  validation_messages.fetch_add(1, std::memory_order_relaxed);
  std::string message =
      severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error: " : "warning: ";
  message += data && data->pMessage ? data->pMessage : "(no text)";
  const auto* sink = static_cast<const std::function<void(const std::string&)>*>(user);
  if (sink && *sink) {
    (*sink)(message);
  } else {
    std::fprintf(stderr, "octovk: Vulkan validation %s\n", message.c_str());
    std::fflush(stderr);
  }
  return VK_FALSE;
}

}  // namespace

namespace detail {

int typeRank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 3;
    default:
      return 4;
  }
}

VkDebugUtilsMessengerCreateInfoEXT messengerInfo(const void* sink) {
  VkDebugUtilsMessengerCreateInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                         VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  info.pfnUserCallback = onValidationMessage;
  info.pUserData = const_cast<void*>(sink);
  return info;
}

bool validationRequested(const ContextOptions& options) {
  if (options.enable_validation) return true;
  const char* env = std::getenv("OCTOVK_VALIDATION");
  return env && *env && std::string(env) != "0";
}

// With `sink`, the instance runs the validation layer (core and synchronization validation) and
// reports to it, also while the instance itself is created and destroyed.
VkResult makeInstance(const std::function<void(const std::string&)>* sink, VkInstance* out) {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "octovk";
  app.apiVersion = VK_API_VERSION_1_2;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &app;
  const char* layer = "VK_LAYER_KHRONOS_validation";
  const char* extension = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
  const VkValidationFeatureEnableEXT enables[] = {
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  VkDebugUtilsMessengerCreateInfoEXT messenger = messengerInfo(sink);
  if (sink) {
    info.enabledLayerCount = 1;
    info.ppEnabledLayerNames = &layer;
    info.enabledExtensionCount = 1;
    info.ppEnabledExtensionNames = &extension;
    features.enabledValidationFeatureCount = 1;
    features.pEnabledValidationFeatures = enables;
    features.pNext = &messenger;
    info.pNext = &features;
  }
  return vkCreateInstance(&info, nullptr, out);
}

std::vector<VkPhysicalDevice> physicalDevices(VkInstance instance) {
  std::uint32_t n = 0;
  if (vkEnumeratePhysicalDevices(instance, &n, nullptr) != VK_SUCCESS) return {};
  std::vector<VkPhysicalDevice> devices(n);
  vkEnumeratePhysicalDevices(instance, &n, devices.data());
  devices.resize(n);
  return devices;
}

bool hasDeviceExtension(const std::vector<VkExtensionProperties>& available, const char* name) {
  for (const VkExtensionProperties& e : available)
    if (std::string_view(e.extensionName) == name) return true;
  return false;
}

std::vector<VkExtensionProperties> deviceExtensions(VkPhysicalDevice pd) {
  std::uint32_t n = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, nullptr);
  std::vector<VkExtensionProperties> available(n);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n, available.data());
  available.resize(n);
  return available;
}

}  // namespace detail

namespace {

// Ray queries need VK_KHR_acceleration_structure (which needs VK_KHR_deferred_host_operations;
// its other dependencies, descriptor indexing, buffer device address and SPIR-V 1.4, are core in
// Vulkan 1.2) and VK_KHR_ray_query, with the features of both. Ray-tracing pipelines are only
// reported: a ray query in a compute shader needs no shader binding table and shares the
// compute passes' pipeline layout and bindings.
struct RayTracingSupport {
  bool ray_query = false;
  bool pipeline = false;
};
RayTracingSupport rayTracingSupport(VkPhysicalDevice pd) {
  using detail::deviceExtensions;
  using detail::hasDeviceExtension;
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(pd, &props);
  if (props.apiVersion < VK_API_VERSION_1_2) return {};
  const auto available = deviceExtensions(pd);
  const bool as = hasDeviceExtension(available, VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME) &&
                  hasDeviceExtension(available, VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME);
  const bool rq = as && hasDeviceExtension(available, VK_KHR_RAY_QUERY_EXTENSION_NAME);
  const bool rtp = as && hasDeviceExtension(available, VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME);
  if (!rq && !rtp) return {};
  VkPhysicalDeviceAccelerationStructureFeaturesKHR asf{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  VkPhysicalDeviceRayQueryFeaturesKHR rqf{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR rtf{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &asf;
  if (rq) {
    rqf.pNext = f2.pNext;
    f2.pNext = &rqf;
  }
  if (rtp) {
    rtf.pNext = f2.pNext;
    f2.pNext = &rtf;
  }
  vkGetPhysicalDeviceFeatures2(pd, &f2);
  return {.ray_query = rq && asf.accelerationStructure && rqf.rayQuery,
          .pipeline = rtp && asf.accelerationStructure && rtf.rayTracingPipeline};
}

}  // namespace

namespace detail {

DeviceInfo describe(VkPhysicalDevice pd, std::uint32_t index) {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(pd, &props);
  VkPhysicalDeviceMemoryProperties mem;
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  DeviceInfo info;
  info.name = props.deviceName;
  info.type = typeName(props.deviceType);
  info.index = index;
  if (props.apiVersion >= VK_API_VERSION_1_2) {
    VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    props2.pNext = &driver;
    vkGetPhysicalDeviceProperties2(pd, &props2);
    info.driver = std::string(driver.driverName) + ": " + driver.driverInfo;
  }
  for (std::uint32_t i = 0; i < mem.memoryHeapCount; ++i)
    if (mem.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      info.memory_bytes = std::max<std::uint64_t>(info.memory_bytes, mem.memoryHeaps[i].size);
  const RayTracingSupport rt = rayTracingSupport(pd);
  info.ray_query = rt.ray_query;
  info.ray_tracing_pipeline = rt.pipeline;
  return info;
}

}  // namespace detail

}  // namespace octovk::vk

namespace octovk {
std::size_t validationMessageCount() noexcept {
  return vk::validation_messages.load(std::memory_order_relaxed);
}
}  // namespace octovk
