#include "vk/device.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "gpu/gpu_types.h"
#include "shader_ids.hpp"
#include "vk/disk_cache.hpp"
#include "vk/instance.hpp"
#include "vk/ray_pipeline.hpp"
#include "vk/shader_registry.hpp"
#include "vk/startup_trace.hpp"

namespace octovk::vk {

using detail::describe;
using detail::deviceExtensions;
using detail::hasDeviceExtension;
using detail::kNoDeviceHint;
using detail::makeInstance;
using detail::physicalDevices;

std::vector<DeviceInfo> Device::enumerate() {
  detail::InstanceHandle inst;
  if (makeInstance(nullptr, &inst.instance) != VK_SUCCESS) return {};
  std::vector<DeviceInfo> out;
  auto devices = physicalDevices(inst.instance);
  for (std::uint32_t i = 0; i < devices.size(); ++i) out.push_back(describe(devices[i], i));
  return out;
}

Device::Device() = default;

namespace {

// Set by an exit handler registered after the first device was made, so after those its driver
// registered while starting: exit() runs handlers newest first, so this one runs before the
// driver's and before the destructors of statics made before the device.
std::atomic<bool> g_process_exiting{false};

void markProcessExiting() { g_process_exiting.store(true, std::memory_order_relaxed); }

}  // namespace

// Each step throws Error for the ordinary failures (no driver, no such device, a missing
// feature) and for a failed Vulkan call; create() returns it. What a step made is released by
// ~Device, whichever step failed.
Result<std::unique_ptr<Device>> Device::create(const ContextOptions& options) {
  std::unique_ptr<Device> dev(new Device());
  dev->creator_pid_ = static_cast<long>(::getpid());
  try {
    auto t = std::chrono::steady_clock::now();
    dev->createInstance(options);
    traceStep("Vulkan instance", t);
    t = std::chrono::steady_clock::now();
    dev->pickPhysicalDevice(options);
    const VkPhysicalDeviceVulkan12Features supported = dev->requireFeatures();
    dev->pickQueueFamily(options);
    traceStep("physical device", t);
    t = std::chrono::steady_clock::now();
    // Either kind of ray tracing the device offers (ray queries, ray-tracing pipelines).
    const bool ray_query = options.enable_ray_query && dev->info_.ray_query;
    const bool ray_pipeline = options.enable_ray_query && dev->info_.ray_tracing_pipeline;
    dev->createLogicalDevice(supported, ray_query, ray_pipeline);
    if (ray_query || ray_pipeline) dev->loadAccelApi();
    dev->ray_query_ = ray_query;
    dev->info_.ray_query_enabled = ray_query;
    if (ray_pipeline) dev->loadRayPipelineApi();
    vkGetPhysicalDeviceMemoryProperties(dev->physical_, &dev->memory_);
    dev->createLayouts();
    traceStep("logical device", t);
  } catch (const Error& e) {
    return e;
  }
  [[maybe_unused]] static const bool exit_handler = std::atexit(markProcessExiting) == 0;
  return dev;
}

// The instance, with the validation layer and its messenger when asked for.
void Device::createInstance(const ContextOptions& options) {
  const bool validation = detail::validationRequested(options);
  validation_sink_ = options.on_validation_message;
  VkResult r = makeInstance(validation ? &validation_sink_ : nullptr, &instance_);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER || r == VK_ERROR_INITIALIZATION_FAILED)
    throw Error(ErrorCode::kNoDevice, kNoDeviceHint);
  if (r == VK_ERROR_LAYER_NOT_PRESENT)
    throw Error(ErrorCode::kNoDevice,
                "Vulkan validation layer requested but not installed: apt-get install "
                "vulkan-validationlayers");
  if (r == VK_ERROR_EXTENSION_NOT_PRESENT)
    throw Error(ErrorCode::kNoDevice,
                "Vulkan validation requested but VK_EXT_debug_utils is missing: apt-get install "
                "vulkan-validationlayers");
  if (r != VK_SUCCESS) check(r, "vkCreateInstance", __FILE__, __LINE__);  // in words, detail()
  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    const VkDebugUtilsMessengerCreateInfoEXT info = detail::messengerInfo(&validation_sink_);
    if (!create || create(instance_, &info, nullptr, &messenger_) != VK_SUCCESS)
      throw Error(ErrorCode::kVulkan,
                  "the Vulkan validation layer's message channel could not be set up: run "
                  "without OCTOVK_VALIDATION, or reinstall vulkan-validationlayers");
  }
}

namespace {

// The device `selector` names, by index or by part of its name; -1 when none does.
std::int64_t deviceNamed(const std::vector<VkPhysicalDevice>& devices,
                         const std::string& selector) {
  std::int64_t chosen = -1;
  const bool numeric =
      selector.size() <= 9 && std::all_of(selector.begin(), selector.end(),
                                          [](unsigned char c) { return c >= '0' && c <= '9'; });
  if (numeric) {
    const std::size_t idx = std::stoul(selector);
    if (idx < devices.size()) chosen = static_cast<std::int64_t>(idx);
  } else {
    for (std::uint32_t i = 0; i < devices.size() && chosen < 0; ++i)
      if (describe(devices[i], i).name.find(selector) != std::string::npos) chosen = i;
  }
  return chosen;
}

// The first Vulkan 1.2 device of the best type (discrete GPU first); -1 when there is none.
std::int64_t bestDevice(const std::vector<VkPhysicalDevice>& devices) {
  std::int64_t chosen = -1;
  int best_rank = 99;
  for (std::uint32_t i = 0; i < devices.size(); ++i) {
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(devices[i], &props);
    if (props.apiVersion < VK_API_VERSION_1_2) continue;
    if (detail::typeRank(props.deviceType) < best_rank) {
      best_rank = detail::typeRank(props.deviceType);
      chosen = i;
    }
  }
  return chosen;
}

}  // namespace

// The device the selector names (ContextOptions::selector, else OCTOVK_DEVICE), else the best.
void Device::pickPhysicalDevice(const ContextOptions& options) {
  auto devices = physicalDevices(instance_);
  if (devices.empty()) throw Error(ErrorCode::kNoDevice, kNoDeviceHint);

  std::string selector = options.selector;
  const char* source = "ContextOptions::selector";
  if (selector.empty()) {
    if (const char* env = std::getenv("OCTOVK_DEVICE")) selector = env;
    source = "OCTOVK_DEVICE";
  }
  std::int64_t chosen = -1;
  if (!selector.empty()) {
    chosen = deviceNamed(devices, selector);
    if (chosen < 0) {
      std::string names;
      for (std::uint32_t i = 0; i < devices.size(); ++i)
        names +=
            std::string(i ? "; " : "") + std::to_string(i) + ": " + describe(devices[i], i).name;
      throw Error(ErrorCode::kNoDevice, std::string("device selector '") + selector + "' (" +
                                            source +
                                            ") matches no Vulkan device; available: " + names);
    }
  } else {
    chosen = bestDevice(devices);
    if (chosen < 0)
      throw Error(ErrorCode::kMissingFeature,
                  "no Vulkan 1.2 device found; octovk needs Vulkan 1.2 (Mesa's lavapipe from "
                  "mesa-vulkan-drivers provides it)");
  }
  physical_ = devices[static_cast<std::size_t>(chosen)];
  info_ = describe(physical_, static_cast<std::uint32_t>(chosen));

  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(physical_, &props);
  if (props.apiVersion < VK_API_VERSION_1_2)
    throw Error(ErrorCode::kMissingFeature,
                "device '" + info_.name + "' supports only Vulkan " +
                    std::to_string(VK_API_VERSION_MAJOR(props.apiVersion)) + "." +
                    std::to_string(VK_API_VERSION_MINOR(props.apiVersion)) +
                    "; octovk needs Vulkan 1.2");
  describeForCache(props);
}

namespace {

std::string hexBytes(const std::uint8_t* bytes, std::size_t n) {
  std::string out;
  char pair[3];
  for (std::size_t i = 0; i < n; ++i) {
    std::snprintf(pair, sizeof pair, "%02x", bytes[i]);
    out += pair;
  }
  return out;
}

std::string hex64(std::uint64_t v) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(v));
  return text;
}

// This build's shaders: every embedded SPIR-V module, hashed (once per process).
std::uint64_t shaderSetHash() {
  static const std::uint64_t hash = [] {
    std::uint64_t h = disk::hash64(std::string_view("octovk shaders"));
    for (std::string_view name : kShaderNames) {
      h = disk::hash64(name, h);
      h = disk::hash64(std::as_bytes(findShader(name)), h);
    }
    return h;
  }();
  return hash;
}

}  // namespace

// The key of the records kept between runs: the device and its driver as Vulkan names them
// (IDs, UUIDs, driver name, info and version, pipelineCacheUUID), then this build's shaders.
void Device::describeForCache(const VkPhysicalDeviceProperties& props) {
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceIDProperties ids{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES};
  ids.pNext = &driver;
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &ids;
  vkGetPhysicalDeviceProperties2(physical_, &props2);
  std::string device =
      std::string("device ") + props.deviceName + " vendor " + std::to_string(props.vendorID) +
      " id " + std::to_string(props.deviceID) + " uuid " + hexBytes(ids.deviceUUID, VK_UUID_SIZE) +
      "; driver " + driver.driverName + " (" + driver.driverInfo + ") id " +
      std::to_string(driver.driverID) + " version " + std::to_string(props.driverVersion) +
      " uuid " + hexBytes(ids.driverUUID, VK_UUID_SIZE) + " pipeline cache uuid " +
      hexBytes(props.pipelineCacheUUID, VK_UUID_SIZE);
  properties_ = props;
  cache_name_ = hex64(disk::hash64(device));
  cache_key_ = device + "; octovk shaders " + hex64(shaderSetHash());
}

std::filesystem::path Device::cacheFile(std::string_view kind) const {
  const std::filesystem::path dir = disk::folder();
  if (dir.empty()) return {};
  return dir / (std::string(kind) + "-" + cache_name_ + ".bin");
}

// Features octovk needs, checked by name; returns the device's Vulkan 1.2 features, for the
// optional ones.
VkPhysicalDeviceVulkan12Features Device::requireFeatures() const {
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &f12;
  vkGetPhysicalDeviceFeatures2(physical_, &f2);
  std::vector<std::string> missing;
  if (!f2.features.shaderInt64) missing.push_back("shaderInt64 (64-bit integers)");
  if (!f2.features.shaderFloat64) missing.push_back("shaderFloat64 (the exact ray walk)");
  if (!f12.shaderBufferInt64Atomics)
    missing.push_back("shaderBufferInt64Atomics (64-bit atomics of the hash set)");
  if (!f12.bufferDeviceAddress)
    missing.push_back("bufferDeviceAddress (maps larger than one descriptor's range)");
  if (!missing.empty()) {
    std::string list;
    for (auto& m : missing) list += (list.empty() ? "" : ", ") + m;
    throw Error(ErrorCode::kMissingFeature, "device '" + info_.name +
                                                "' lacks required features: " + list +
                                                "; choose another device with OCTOVK_DEVICE");
  }
  return f12;
}

// The first queue family with compute, and the limits octovk works within.
void Device::pickQueueFamily(const ContextOptions& options) {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(physical_, &props);
  std::uint32_t qn = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(physical_, &qn, nullptr);
  std::vector<VkQueueFamilyProperties> qprops(qn);
  vkGetPhysicalDeviceQueueFamilyProperties(physical_, &qn, qprops.data());
  bool found = false;
  for (std::uint32_t i = 0; i < qn && !found; ++i) {
    if (qprops[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
      queue_family_ = i;
      found = true;
      if (qprops[i].timestampValidBits >= 36)
        timestamp_period_ns_ = static_cast<double>(props.limits.timestampPeriod);
      storage_alignment_ = props.limits.minStorageBufferOffsetAlignment;
      max_groups_x_ = props.limits.maxComputeWorkGroupCount[0];
      max_binding_bytes_ = props.limits.maxStorageBufferRange;
      if (options.max_binding_bytes != 0)
        max_binding_bytes_ = std::min<std::uint64_t>(max_binding_bytes_, options.max_binding_bytes);
    }
  }
  if (!found)
    throw Error(ErrorCode::kMissingFeature, "device '" + info_.name + "' has no compute queue");
}

// The logical device and its one queue: the required features, the optional ones the device
// has (timeline semaphores; external memory and semaphores by fd) and, with `ray_query` or
// `ray_pipeline`, the acceleration-structure extension with the ray-query or ray-tracing
// pipeline extension.
void Device::createLogicalDevice(const VkPhysicalDeviceVulkan12Features& supported, bool ray_query,
                                 bool ray_pipeline) {
  float priority = 1.0f;
  VkDeviceQueueCreateInfo qinfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qinfo.queueFamilyIndex = queue_family_;
  qinfo.queueCount = 1;
  qinfo.pQueuePriorities = &priority;
  VkPhysicalDeviceVulkan12Features want12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  want12.shaderBufferInt64Atomics = VK_TRUE;
  want12.bufferDeviceAddress = VK_TRUE;
  // Optional: lets callers hand input over with a timeline semaphore (vulkan_interop.hpp).
  want12.timelineSemaphore = supported.timelineSemaphore;
  VkPhysicalDeviceFeatures2 want{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  want.pNext = &want12;
  want.features.shaderInt64 = VK_TRUE;
  want.features.shaderFloat64 = VK_TRUE;
  // Optional: memory and semaphores shared with other APIs (CUDA, another Vulkan device) by
  // POSIX file descriptor, for callers that hand input over on the device (vulkan_interop.hpp).
  const std::vector<VkExtensionProperties> available = deviceExtensions(physical_);
  std::vector<const char*> extensions;
  for (const char* name :
       {VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME, VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME})
    if (hasDeviceExtension(available, name)) {
      extensions.push_back(name);
      extensions_.emplace_back(name);
    }
  // Optional: ray queries and ray-tracing pipelines for the ray-tracing backends (see
  // rayTracingSupport).
  VkPhysicalDeviceAccelerationStructureFeaturesKHR want_as{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  VkPhysicalDeviceRayQueryFeaturesKHR want_rq{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};
  VkPhysicalDeviceRayTracingPipelineFeaturesKHR want_rtp{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};
  const auto enable = [&](const char* name) {
    extensions.push_back(name);
    extensions_.emplace_back(name);
  };
  if (ray_query || ray_pipeline) {
    enable(VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME);
    enable(VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME);
    want_as.accelerationStructure = VK_TRUE;
    want_as.pNext = want12.pNext;
    want12.pNext = &want_as;
  }
  if (ray_query) {
    enable(VK_KHR_RAY_QUERY_EXTENSION_NAME);
    want_rq.rayQuery = VK_TRUE;
    want_rq.pNext = want12.pNext;
    want12.pNext = &want_rq;
  }
  if (ray_pipeline) {
    enable(VK_KHR_RAY_TRACING_PIPELINE_EXTENSION_NAME);
    want_rtp.rayTracingPipeline = VK_TRUE;
    want_rtp.pNext = want12.pNext;
    want12.pNext = &want_rtp;
  }
  VkDeviceCreateInfo dinfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dinfo.pNext = &want;
  dinfo.queueCreateInfoCount = 1;
  dinfo.pQueueCreateInfos = &qinfo;
  dinfo.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  dinfo.ppEnabledExtensionNames = extensions.data();
  OCTOVK_VK(vkCreateDevice(physical_, &dinfo, nullptr, &device_));
  vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
}

// The acceleration-structure entry points and the scratch alignment (accelApi()).
void Device::loadAccelApi() {
  auto api = std::make_unique<AccelApi>();
  const auto load = [&](const char* name) { return vkGetDeviceProcAddr(device_, name); };
  api->create = reinterpret_cast<PFN_vkCreateAccelerationStructureKHR>(
      load("vkCreateAccelerationStructureKHR"));
  api->destroy = reinterpret_cast<PFN_vkDestroyAccelerationStructureKHR>(
      load("vkDestroyAccelerationStructureKHR"));
  api->buildSizes = reinterpret_cast<PFN_vkGetAccelerationStructureBuildSizesKHR>(
      load("vkGetAccelerationStructureBuildSizesKHR"));
  api->cmdBuild = reinterpret_cast<PFN_vkCmdBuildAccelerationStructuresKHR>(
      load("vkCmdBuildAccelerationStructuresKHR"));
  api->address = reinterpret_cast<PFN_vkGetAccelerationStructureDeviceAddressKHR>(
      load("vkGetAccelerationStructureDeviceAddressKHR"));
  VkPhysicalDeviceAccelerationStructurePropertiesKHR asp{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &asp;
  vkGetPhysicalDeviceProperties2(physical_, &props2);
  api->scratch_alignment =
      std::max<VkDeviceSize>(asp.minAccelerationStructureScratchOffsetAlignment, 1);
  if (!api->create || !api->destroy || !api->buildSizes || !api->cmdBuild || !api->address)
    throw Error(ErrorCode::kVulkan, "device '" + info_.name +
                                        "' enabled VK_KHR_acceleration_structure but lacks "
                                        "its entry points; create the Context with "
                                        "ContextOptions::enable_ray_query = false");
  accel_api_ = std::move(api);
}

// The ray-tracing pipeline entry points and the shader binding table's rules (rayPipelineApi()).
void Device::loadRayPipelineApi() {
  auto api = std::make_unique<RayPipelineApi>();
  const auto load = [&](const char* name) { return vkGetDeviceProcAddr(device_, name); };
  api->create =
      reinterpret_cast<PFN_vkCreateRayTracingPipelinesKHR>(load("vkCreateRayTracingPipelinesKHR"));
  api->groupHandles = reinterpret_cast<PFN_vkGetRayTracingShaderGroupHandlesKHR>(
      load("vkGetRayTracingShaderGroupHandlesKHR"));
  api->cmdTrace = reinterpret_cast<PFN_vkCmdTraceRaysKHR>(load("vkCmdTraceRaysKHR"));
  VkPhysicalDeviceRayTracingPipelinePropertiesKHR rtp{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &rtp;
  vkGetPhysicalDeviceProperties2(physical_, &props2);
  api->handle_size = rtp.shaderGroupHandleSize;
  api->handle_alignment = std::max(rtp.shaderGroupHandleAlignment, 1u);
  api->base_alignment = std::max(rtp.shaderGroupBaseAlignment, 1u);
  api->max_invocations = rtp.maxRayDispatchInvocationCount;
  if (!api->create || !api->groupHandles || !api->cmdTrace || api->handle_size == 0)
    throw Error(ErrorCode::kVulkan, "device '" + info_.name +
                                        "' enabled VK_KHR_ray_tracing_pipeline but lacks its "
                                        "entry points; create the Context with "
                                        "ContextOptions::enable_ray_query = false");
  ray_pipeline_api_ = std::move(api);
  ray_pipelines_ = std::make_unique<RayPipelines>(*this);
}

const RayPipeline& Device::rayPipeline(std::string_view raygen) {
  return ray_pipelines_->get(raygen, pipelineCache());
}

// The one descriptor set layout (the map's bindings, then the address table at kBindAddresses)
// and the one pipeline layout every pass shares.
void Device::createLayouts() {
  // The ray-tracing pipelines' stages read the same bindings; their push constants follow the
  // compute passes' (ranges of different stages may not overlap).
  const VkShaderStageFlags rayStages = ray_pipeline_api_ ? RayPipeline::kStages : 0;
  std::vector<VkDescriptorSetLayoutBinding> bindings(gpu::kBindingCount + 1);
  for (std::uint32_t i = 0; i <= gpu::kBindingCount; ++i) {
    bindings[i] = {};
    bindings[i].binding = i;
    bindings[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    bindings[i].descriptorCount = 1;
    bindings[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT | rayStages;
  }
  VkDescriptorSetLayoutCreateInfo linfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  linfo.bindingCount = gpu::kBindingCount + 1;
  linfo.pBindings = bindings.data();
  OCTOVK_VK(vkCreateDescriptorSetLayout(device_, &linfo, nullptr, &set_layout_));
  const VkPushConstantRange ranges[2] = {
      {VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::PassConstants)},
      {rayStages, RayPipeline::kConstantsOffset, sizeof(gpu::PassConstants)}};
  VkPipelineLayoutCreateInfo pinfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pinfo.setLayoutCount = 1;
  pinfo.pSetLayouts = &set_layout_;
  pinfo.pushConstantRangeCount = rayStages ? 2 : 1;
  pinfo.pPushConstantRanges = ranges;
  OCTOVK_VK(vkCreatePipelineLayout(device_, &pinfo, nullptr, &pipeline_layout_));
}

bool Device::forkedAway() const noexcept { return static_cast<long>(::getpid()) != creator_pid_; }

bool Device::abandoned() const noexcept {
  return forkedAway() || g_process_exiting.load(std::memory_order_relaxed);
}

void Device::keepUntilExit(void* object) noexcept {
  // Never freed (it is used while the process exits): a root for leak checkers.
  static auto* mutex = new std::mutex();
  static auto* kept = new std::vector<void*>();
  try {
    std::lock_guard<std::mutex> lock(*mutex);
    kept->push_back(object);
  } catch (...) {  // no memory for the note: the object stays alive all the same
  }
}

void Device::checkNotForked(std::string_view what) const {
  if (forkedAway())
    throw Error(ErrorCode::kInvalidArgument,
                std::string(what) + ": its Vulkan device was made by process " +
                    std::to_string(creator_pid_) + ", and this is a child forked from it (pid " +
                    std::to_string(::getpid()) +
                    "); a device cannot be used across fork(): create the Context and the map in "
                    "the child, or fork before making them");
}

Device::~Device() {
  // In a forked child the device is the parent's: any call could wait on the driver's threads,
  // which the child does not have, and the pipeline cache is the parent's to save. Once exit()
  // ran the handlers the driver may be gone. Leave it (the ray-tracing pipelines and their
  // tables too).
  if (abandoned()) {
    static_cast<void>(ray_pipelines_.release());
    return;
  }
  if (device_) {
    vkDeviceWaitIdle(device_);
    if (pipeline_cache_) {
      const auto t = std::chrono::steady_clock::now();
      const std::size_t saved = pipeline_cache_->save();
      if (traceStartup()) traceStep("pipeline cache saved " + std::to_string(saved) + " bytes", t);
      pipeline_cache_.reset();
    }
    for (auto& slot : passes_)
      if (slot.pass.pipeline) vkDestroyPipeline(device_, slot.pass.pipeline, nullptr);
    ray_pipelines_.reset();
    if (pipeline_layout_) vkDestroyPipelineLayout(device_, pipeline_layout_, nullptr);
    if (set_layout_) vkDestroyDescriptorSetLayout(device_, set_layout_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

void Device::submit(const VkSubmitInfo& info, VkFence fence) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  const auto t = std::chrono::steady_clock::now();
  OCTOVK_VK(vkQueueSubmit(queue_, 1, &info, fence));
  if (traceStartup() && submissions_++ == 0) traceStep("first submission (vkQueueSubmit)", t);
}

const Pass& Device::pass(std::string_view name) {
  // The lock covers only finding the pass's slot: maps on other threads build other passes at
  // the same time, and a second caller of the same pass waits on its once_flag.
  PassSlot* slot = nullptr;
  {
    std::lock_guard<std::mutex> lock(passes_mutex_);
    for (PassSlot& s : passes_) {
      if (s.pass.name == name) {
        slot = &s;
        break;
      }
    }
    if (!slot) {
      slot = &passes_.emplace_back();
      slot->pass.name = std::string(name);
    }
  }
  // A build that throws leaves the flag unset: the next caller tries again.
  std::call_once(slot->built, [&] { slot->pass.pipeline = buildPipeline(name); });
  return slot->pass;
}

void Device::buildPasses(std::span<const std::string_view> names) {
  std::atomic<std::size_t> next{0};
  auto build = [&]() noexcept {
    for (std::size_t i; (i = next.fetch_add(1)) < names.size();) {
      try {
        pass(names[i]);
      } catch (...) {  // pass() builds it again at first use and reports there
      }
    }
  };
  const std::size_t threads =
      std::min<std::size_t>(names.size(), std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> helpers;
  for (std::size_t t = 1; t < threads; ++t) {
    try {
      helpers.emplace_back(build);
    } catch (...) {  // no thread: the ones started (and this one) build them all
      break;
    }
  }
  build();
  for (std::thread& t : helpers) t.join();
}

// The cache kept between runs, loaded by the first pipeline built; VK_NULL_HANDLE when turned
// off or when no cache could be created (the pipelines are the same either way).
VkPipelineCache Device::pipelineCache() {
  std::call_once(pipeline_cache_loaded_, [&] {
    if (!pipelineCacheEnabled()) return;
    const auto t = std::chrono::steady_clock::now();
    try {
      pipeline_cache_ =
          std::make_unique<PipelineCache>(device_, properties_, cacheFile("pipelines"), cache_key_);
    } catch (...) {  // no memory for the file's name or the cache: build without one
      pipeline_cache_.reset();
      return;
    }
    if (traceStartup())
      traceStep(
          "pipeline cache loaded " + std::to_string(pipeline_cache_->loadedBytes()) + " bytes", t);
  });
  return pipeline_cache_ ? pipeline_cache_->handle() : VK_NULL_HANDLE;
}

VkPipeline Device::buildPipeline(std::string_view name) {
  const std::span<const std::uint32_t> code = findShader(name);
  if (code.empty())
    throw Error(ErrorCode::kInternal, "no embedded shader named '" + std::string(name) + "'");
  VkShaderModuleCreateInfo minfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  minfo.codeSize = code.size() * sizeof(std::uint32_t);
  minfo.pCode = code.data();
  VkShaderModule module;
  OCTOVK_VK(vkCreateShaderModule(device_, &minfo, nullptr, &module));
  VkComputePipelineCreateInfo cinfo{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  cinfo.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  cinfo.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cinfo.stage.module = module;
  cinfo.stage.pName = "main";
  cinfo.layout = pipeline_layout_;
  VkPipeline pipeline = VK_NULL_HANDLE;
  const VkPipelineCache cache = pipelineCache();
  const auto t = std::chrono::steady_clock::now();
  const VkResult r = vkCreateComputePipelines(device_, cache, 1, &cinfo, nullptr, &pipeline);
  vkDestroyShaderModule(device_, module, nullptr);
  check(r, "vkCreateComputePipelines", __FILE__, __LINE__);
  if (traceStartup()) traceStep("pipeline " + std::string(name), t);
  return pipeline;
}

std::uint32_t Device::memoryType(std::uint32_t type_bits, VkMemoryPropertyFlags wanted,
                                 VkMemoryPropertyFlags fallback) const {
  for (VkMemoryPropertyFlags flags : {wanted, fallback}) {
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i)
      if ((type_bits & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & flags) == flags)
        return i;
  }
  throw Error(ErrorCode::kOutOfDeviceMemory, "no suitable Vulkan memory type for a buffer");
}

}  // namespace octovk::vk
