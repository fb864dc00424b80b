#include "vk/device.hpp"
#include "vk/fault_injection.hpp"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <utility>

#include "octovk/gpu_types.h"
#include "vk/shader_registry.hpp"

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

void check(VkResult r, const char* call, const char* file, int line) {
  if (r == VK_SUCCESS) return;
  std::ostringstream msg;
  msg << call << " failed with " << resultName(r) << " (" << int(r) << ") at " << file << ":"
      << line;
  const bool oom = r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY;
  throw Error(oom ? ErrorCode::kOutOfDeviceMemory : ErrorCode::kVulkan, msg.str());
}

// ---------------------------------------------------------------------------------------------
// Buffer

namespace fault {
namespace {
std::atomic<std::uint64_t> fail_at{0};
std::atomic<std::uint64_t> allocations{0};
}  // namespace

void failDeviceAllocation(std::uint64_t n) noexcept {
  allocations.store(0);
  fail_at.store(n);
}
std::uint64_t deviceAllocations() noexcept { return allocations.load(); }
bool deviceAllocationFails() noexcept {
  const std::uint64_t n = allocations.fetch_add(1) + 1;
  return n == fail_at.load();
}
}  // namespace fault

Buffer::Buffer(Device& device, std::size_t bytes, bool host_visible)
    : Buffer(device, bytes, host_visible, 0) {}

Buffer::Buffer(Device& device, std::size_t bytes, bool host_visible, VkBufferUsageFlags extra_usage)
    : device_(&device) {
  bytes_ = std::max<std::size_t>(bytes, 16);
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = bytes_;
  info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
               VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT |
               VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | extra_usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  OCTOVK_VK(vkCreateBuffer(device.handle(), &info, nullptr, &buffer_));
  try {
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device.handle(), buffer_, &req);
    VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
    flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.pNext = &flags;
    alloc.allocationSize = req.size;
    if (host_visible) {
      alloc.memoryTypeIndex = device.memoryType(
          req.memoryTypeBits,
          VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT |
              VK_MEMORY_PROPERTY_HOST_CACHED_BIT,
          VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    } else {
      alloc.memoryTypeIndex =
          device.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
    }
    OCTOVK_VK(fault::deviceAllocationFails()
                  ? VK_ERROR_OUT_OF_DEVICE_MEMORY
                  : vkAllocateMemory(device.handle(), &alloc, nullptr, &memory_));
    OCTOVK_VK(vkBindBufferMemory(device.handle(), buffer_, memory_, 0));
    if (host_visible)
      OCTOVK_VK(vkMapMemory(device.handle(), memory_, 0, VK_WHOLE_SIZE, 0, &mapped_));
    VkBufferDeviceAddressInfo address{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    address.buffer = buffer_;
    address_ = vkGetBufferDeviceAddress(device.handle(), &address);
  } catch (...) {
    release();
    throw;
  }
}

Buffer::~Buffer() { release(); }

Buffer::Buffer(Buffer&& other) noexcept { *this = std::move(other); }

Buffer& Buffer::operator=(Buffer&& other) noexcept {
  if (this != &other) {
    release();
    device_ = other.device_;
    buffer_ = std::exchange(other.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(other.memory_, VK_NULL_HANDLE);
    bytes_ = std::exchange(other.bytes_, 0);
    mapped_ = std::exchange(other.mapped_, nullptr);
    address_ = std::exchange(other.address_, 0);
  }
  return *this;
}

void Buffer::release() noexcept {
  if (!device_) return;
  if (buffer_) vkDestroyBuffer(device_->handle(), buffer_, nullptr);
  if (memory_) vkFreeMemory(device_->handle(), memory_, nullptr);
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  bytes_ = 0;
  address_ = 0;
}

// ---------------------------------------------------------------------------------------------
// BindingSet

BindingSet::BindingSet(Device& device)
    : device_(&device),
      addresses_(device, gpu::kBindingCount * sizeof(std::uint64_t), /*host_visible=*/true) {
  std::memset(addresses_.mapped(), 0, addresses_.size());
  VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, gpu::kBindingCount + 1};
  VkDescriptorPoolCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  info.maxSets = 1;
  info.poolSizeCount = 1;
  info.pPoolSizes = &size;
  OCTOVK_VK(vkCreateDescriptorPool(device.handle(), &info, nullptr, &pool_));
  VkDescriptorSetLayout layout = device.setLayout();
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = pool_;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &layout;
  try {
    OCTOVK_VK(vkAllocateDescriptorSets(device.handle(), &alloc, &set_));
    write(gpu::kBindAddresses, addresses_.handle(), 0, VK_WHOLE_SIZE);
  } catch (...) {
    release();
    throw;
  }
}

BindingSet::~BindingSet() { release(); }

BindingSet::BindingSet(BindingSet&& other) noexcept { *this = std::move(other); }

BindingSet& BindingSet::operator=(BindingSet&& other) noexcept {
  if (this != &other) {
    release();
    device_ = other.device_;
    pool_ = std::exchange(other.pool_, VK_NULL_HANDLE);
    set_ = std::exchange(other.set_, VK_NULL_HANDLE);
    addresses_ = std::move(other.addresses_);
  }
  return *this;
}

void BindingSet::release() noexcept {
  if (device_ && pool_) vkDestroyDescriptorPool(device_->handle(), pool_, nullptr);
  pool_ = VK_NULL_HANDLE;
  set_ = VK_NULL_HANDLE;
}

void BindingSet::update(std::span<const Buffer* const> buffers) {
  auto* table = static_cast<std::uint64_t*>(addresses_.mapped());
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    const auto binding = static_cast<std::uint32_t>(i);
    if (gpu::kAddressedBindings & (1u << binding))
      table[binding] = buffers[i]->address();
    else
      write(binding, buffers[i]->handle(), 0, buffers[i]->size());
  }
}

void BindingSet::updateRange(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset,
                             VkDeviceSize size) {
  write(binding, buffer, offset, size);
}

void BindingSet::write(std::uint32_t binding, VkBuffer buffer, VkDeviceSize offset,
                       VkDeviceSize size) {
  // A storage buffer descriptor may not reach further than maxStorageBufferRange: what could
  // (the map's arrays) goes by device address, and what is bound here must fit.
  if (size != VK_WHOLE_SIZE && size > device_->maxBindingBytes())
    throw Error(ErrorCode::kInvalidArgument,
                "a buffer range of " + std::to_string(size) + " bytes at binding " +
                    std::to_string(binding) +
                    " exceeds what one binding may hold on this device (" +
                    std::to_string(device_->maxBindingBytes()) +
                    " bytes, maxStorageBufferRange); split the batch");
  VkDescriptorBufferInfo info{buffer, offset, size};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  write.pBufferInfo = &info;
  vkUpdateDescriptorSets(device_->handle(), 1, &write, 0, nullptr);
}

// ---------------------------------------------------------------------------------------------
// CommandStream

CommandStream::CommandStream(Device& device, std::uint32_t frames)
    : device_(device), frames_(std::max<std::uint32_t>(frames, 1)) {
  VkCommandPoolCreateInfo info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  info.queueFamilyIndex = device.queueFamily();
  OCTOVK_VK(vkCreateCommandPool(device.handle(), &info, nullptr, &pool_));
  VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  alloc.commandPool = pool_;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  VkFenceCreateInfo fence{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  try {
    for (Frame& f : frames_) {
      OCTOVK_VK(vkAllocateCommandBuffers(device.handle(), &alloc, &f.cmd));
      OCTOVK_VK(vkCreateFence(device.handle(), &fence, nullptr, &f.fence));
    }
    if (device.timestampPeriodNs() > 0) {
      VkQueryPoolCreateInfo qinfo{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      qinfo.queryType = VK_QUERY_TYPE_TIMESTAMP;
      qinfo.queryCount = kMaxQueries * this->frames();
      OCTOVK_VK(vkCreateQueryPool(device.handle(), &qinfo, nullptr, &queries_));
    }
  } catch (...) {
    for (Frame& f : frames_)
      if (f.fence) vkDestroyFence(device.handle(), f.fence, nullptr);
    vkDestroyCommandPool(device.handle(), pool_, nullptr);
    throw;
  }
}

CommandStream::~CommandStream() {
  for (Frame& f : frames_)  // nothing may be destroyed under a running submission
    if (f.serial != 0 && !f.done)
      vkWaitForFences(device_.handle(), 1, &f.fence, VK_TRUE, UINT64_MAX);
  if (recording_) vkEndCommandBuffer(cmd());
  if (queries_) vkDestroyQueryPool(device_.handle(), queries_, nullptr);
  for (Frame& f : frames_) vkDestroyFence(device_.handle(), f.fence, nullptr);
  vkDestroyCommandPool(device_.handle(), pool_, nullptr);
}

// Each submission's own fence says it is done (and makes its writes available to the host):
// nothing is inferred from a later submission's fence.
void CommandStream::waitFrame(Frame& f) {
  if (f.serial == 0 || f.done) return;
  const VkResult status = vkGetFenceStatus(device_.handle(), f.fence);
  if (status == VK_NOT_READY) {
    ++blocking_waits_;
    OCTOVK_VK(vkWaitForFences(device_.handle(), 1, &f.fence, VK_TRUE, UINT64_MAX));
  } else {
    OCTOVK_VK(status);
  }
  f.done = true;
}

void CommandStream::begin(const BindingSet& bindings) {
  current_ = nextFrame();
  Frame& f = frames_[current_];
  waitFrame(f);
  OCTOVK_VK(vkResetCommandBuffer(f.cmd, 0));
  VkCommandBufferBeginInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  info.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  OCTOVK_VK(vkBeginCommandBuffer(f.cmd, &info));
  recording_ = true;
  f.query_count = 0;
  if (queries_) vkCmdResetQueryPool(f.cmd, queries_, current_ * kMaxQueries, kMaxQueries);
  VkDescriptorSet set = bindings.handle();
  vkCmdBindDescriptorSets(f.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, device_.pipelineLayout(), 0, 1,
                          &set, 0, nullptr);
  // The previous submissions' writes (the same queue, in submission order) before this one's.
  barrier();
}

void CommandStream::dispatch(const Pass& pass, std::uint32_t groups, const void* constants,
                             std::uint32_t constants_bytes) {
  if (groups == 0) return;
  vkCmdBindPipeline(cmd(), VK_PIPELINE_BIND_POINT_COMPUTE, pass.pipeline);
  if (constants_bytes)
    vkCmdPushConstants(cmd(), device_.pipelineLayout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       constants_bytes, constants);
  // Large 1-D workloads are folded into y so no dimension exceeds the guaranteed 65535.
  const std::uint32_t x = std::min<std::uint32_t>(groups, 65535u);
  const std::uint32_t y = (groups + x - 1) / x;
  vkCmdDispatch(cmd(), x, y, 1);
}

void CommandStream::dispatchIndirect(const Pass& pass, const Buffer& args, std::size_t offset,
                                     const void* constants, std::uint32_t constants_bytes) {
  vkCmdBindPipeline(cmd(), VK_PIPELINE_BIND_POINT_COMPUTE, pass.pipeline);
  if (constants_bytes)
    vkCmdPushConstants(cmd(), device_.pipelineLayout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       constants_bytes, constants);
  vkCmdDispatchIndirect(cmd(), args.handle(), offset);
}

void CommandStream::barrier() {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  b.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                    VK_ACCESS_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                    VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(cmd(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                           VK_PIPELINE_STAGE_DRAW_INDIRECT_BIT,
                       0, 1, &b, 0, nullptr, 0, nullptr);
}

void CommandStream::copy(const Buffer& src, const Buffer& dst, std::size_t bytes,
                         std::size_t src_offset, std::size_t dst_offset) {
  if (bytes == 0) return;
  VkBufferCopy region{src_offset, dst_offset, bytes};
  vkCmdCopyBuffer(cmd(), src.handle(), dst.handle(), 1, &region);
}

void CommandStream::copyFrom(VkBuffer src, VkDeviceSize src_offset, const Buffer& dst,
                             std::size_t bytes, std::size_t dst_offset) {
  if (bytes == 0) return;
  VkBufferCopy region{src_offset, dst_offset, bytes};
  vkCmdCopyBuffer(cmd(), src, dst.handle(), 1, &region);
}

void CommandStream::fill(const Buffer& dst, std::uint32_t value, std::size_t offset,
                         std::size_t bytes) {
  vkCmdFillBuffer(cmd(), dst.handle(), offset, bytes, value);
}

void CommandStream::update(const Buffer& dst, const void* data, std::size_t bytes,
                           std::size_t offset) {
  vkCmdUpdateBuffer(cmd(), dst.handle(), offset, bytes, data);
}

std::uint32_t CommandStream::timestamp() {
  Frame& f = frames_[current_];
  if (!queries_ || f.query_count >= kMaxQueries) return f.query_count;
  vkCmdWriteTimestamp(f.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_,
                      current_ * kMaxQueries + f.query_count);
  return f.query_count++;
}

std::vector<double> CommandStream::timestampsNs(std::uint32_t frame) {
  const Frame& f = frames_.at(frame);
  if (!queries_ || f.query_count == 0 || f.serial == 0 || !f.done) return {};
  std::vector<std::uint64_t> ticks(f.query_count);
  const VkResult r =
      vkGetQueryPoolResults(device_.handle(), queries_, frame * kMaxQueries, f.query_count,
                            ticks.size() * sizeof(std::uint64_t), ticks.data(),
                            sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT);
  if (r != VK_SUCCESS) return {};
  std::vector<double> ns(ticks.size());
  for (std::size_t i = 0; i < ticks.size(); ++i)
    ns[i] = static_cast<double>(ticks[i]) * device_.timestampPeriodNs();
  return ns;
}

void CommandStream::waitBeforeNextSubmit(VkSemaphore semaphore, std::uint64_t value) {
  wait_semaphore_ = semaphore;
  wait_value_ = value;
}

std::uint64_t CommandStream::submit() {
  Frame& f = frames_[current_];
  OCTOVK_VK(vkEndCommandBuffer(f.cmd));
  recording_ = false;
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &f.cmd;
  // A caller's semaphore (interop input): every stage of this submission waits for it. The
  // value is read for a timeline semaphore and ignored for a binary one.
  const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  VkTimelineSemaphoreSubmitInfo timeline{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
  const VkSemaphore wait = wait_semaphore_;
  const std::uint64_t wait_value = wait_value_;
  wait_semaphore_ = VK_NULL_HANDLE;
  if (wait != VK_NULL_HANDLE) {
    timeline.waitSemaphoreValueCount = 1;
    timeline.pWaitSemaphoreValues = &wait_value;
    submit.pNext = &timeline;
    submit.waitSemaphoreCount = 1;
    submit.pWaitSemaphores = &wait;
    submit.pWaitDstStageMask = &wait_stage;
  }
  OCTOVK_VK(vkResetFences(device_.handle(), 1, &f.fence));
  device_.submit(submit, f.fence);
  f.serial = ++submitted_;
  f.done = false;
  return f.serial;
}

// A serial no frame holds any more was waited for when its frame was reused.
void CommandStream::wait(std::uint64_t serial) {
  if (serial == 0) return;
  for (Frame& f : frames_)
    if (f.serial == serial) return waitFrame(f);
}

bool CommandStream::finished(std::uint64_t serial) {
  if (serial == 0) return true;  // nothing was submitted
  for (Frame& f : frames_) {
    if (f.serial != serial) continue;
    if (f.done) return true;
    const VkResult r = vkGetFenceStatus(device_.handle(), f.fence);
    if (r == VK_NOT_READY) return false;
    OCTOVK_VK(r);
    f.done = true;
    return true;
  }
  return true;
}

void CommandStream::waitIdle() {
  for (Frame& f : frames_) waitFrame(f);
}

// ---------------------------------------------------------------------------------------------
// Device

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

struct InstanceHandle {
  VkInstance instance = VK_NULL_HANDLE;
  ~InstanceHandle() {
    if (instance) vkDestroyInstance(instance, nullptr);
  }
};

const char* kNoDeviceHint =
    "no Vulkan device found: install Mesa's CPU driver with `apt-get install "
    "mesa-vulkan-drivers` (lavapipe) or a GPU driver, and check `vulkaninfo --summary`";

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

}  // namespace

std::vector<DeviceInfo> Device::enumerate() {
  InstanceHandle inst;
  if (makeInstance(nullptr, &inst.instance) != VK_SUCCESS) return {};
  std::vector<DeviceInfo> out;
  auto devices = physicalDevices(inst.instance);
  for (std::uint32_t i = 0; i < devices.size(); ++i) out.push_back(describe(devices[i], i));
  return out;
}

Result<std::unique_ptr<Device>> Device::create(const ContextOptions& options) {
  std::unique_ptr<Device> dev(new Device());
  const bool validation = validationRequested(options);
  dev->validation_sink_ = options.on_validation_message;
  VkResult r = makeInstance(validation ? &dev->validation_sink_ : nullptr, &dev->instance_);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER || r == VK_ERROR_INITIALIZATION_FAILED)
    return Error(ErrorCode::kNoDevice, kNoDeviceHint);
  if (r == VK_ERROR_LAYER_NOT_PRESENT)
    return Error(ErrorCode::kNoDevice,
                 "Vulkan validation layer requested but not installed: apt-get install "
                 "vulkan-validationlayers");
  if (r == VK_ERROR_EXTENSION_NOT_PRESENT)
    return Error(ErrorCode::kNoDevice,
                 "Vulkan validation requested but VK_EXT_debug_utils is missing: apt-get install "
                 "vulkan-validationlayers");
  if (r != VK_SUCCESS)
    return Error(ErrorCode::kVulkan, std::string("vkCreateInstance failed with ") + resultName(r));
  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(dev->instance_, "vkCreateDebugUtilsMessengerEXT"));
    const VkDebugUtilsMessengerCreateInfoEXT info = messengerInfo(&dev->validation_sink_);
    if (!create || create(dev->instance_, &info, nullptr, &dev->messenger_) != VK_SUCCESS)
      return Error(ErrorCode::kVulkan, "vkCreateDebugUtilsMessengerEXT failed");
  }

  auto devices = physicalDevices(dev->instance_);
  if (devices.empty()) return Error(ErrorCode::kNoDevice, kNoDeviceHint);

  std::string selector = options.selector;
  const char* source = "ContextOptions::selector";
  if (selector.empty()) {
    if (const char* env = std::getenv("OCTOVK_DEVICE")) selector = env;
    source = "OCTOVK_DEVICE";
  }
  std::int64_t chosen = -1;
  if (!selector.empty()) {
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
    if (chosen < 0) {
      std::string names;
      for (std::uint32_t i = 0; i < devices.size(); ++i)
        names +=
            std::string(i ? "; " : "") + std::to_string(i) + ": " + describe(devices[i], i).name;
      return Error(ErrorCode::kNoDevice, std::string("device selector '") + selector + "' (" +
                                             source +
                                             ") matches no Vulkan device; available: " + names);
    }
  } else {
    int best_rank = 99;
    for (std::uint32_t i = 0; i < devices.size(); ++i) {
      VkPhysicalDeviceProperties props;
      vkGetPhysicalDeviceProperties(devices[i], &props);
      if (props.apiVersion < VK_API_VERSION_1_2) continue;
      if (typeRank(props.deviceType) < best_rank) {
        best_rank = typeRank(props.deviceType);
        chosen = i;
      }
    }
    if (chosen < 0)
      return Error(ErrorCode::kMissingFeature,
                   "no Vulkan 1.2 device found; octovk needs Vulkan 1.2 (Mesa's lavapipe from "
                   "mesa-vulkan-drivers provides it)");
  }
  dev->physical_ = devices[static_cast<std::size_t>(chosen)];
  dev->info_ = describe(dev->physical_, static_cast<std::uint32_t>(chosen));

  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(dev->physical_, &props);
  if (props.apiVersion < VK_API_VERSION_1_2)
    return Error(ErrorCode::kMissingFeature,
                 "device '" + dev->info_.name + "' supports only Vulkan " +
                     std::to_string(VK_API_VERSION_MAJOR(props.apiVersion)) + "." +
                     std::to_string(VK_API_VERSION_MINOR(props.apiVersion)) +
                     "; octovk needs Vulkan 1.2");

  // Features octovk needs, checked by name.
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &f12;
  vkGetPhysicalDeviceFeatures2(dev->physical_, &f2);
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
    return Error(ErrorCode::kMissingFeature, "device '" + dev->info_.name +
                                                 "' lacks required features: " + list +
                                                 "; choose another device with OCTOVK_DEVICE");
  }

  std::uint32_t qn = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(dev->physical_, &qn, nullptr);
  std::vector<VkQueueFamilyProperties> qprops(qn);
  vkGetPhysicalDeviceQueueFamilyProperties(dev->physical_, &qn, qprops.data());
  bool found = false;
  for (std::uint32_t i = 0; i < qn && !found; ++i) {
    if (qprops[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
      dev->queue_family_ = i;
      found = true;
      if (qprops[i].timestampValidBits >= 36)
        dev->timestamp_period_ns_ = static_cast<double>(props.limits.timestampPeriod);
      dev->storage_alignment_ = props.limits.minStorageBufferOffsetAlignment;
      dev->max_groups_x_ = props.limits.maxComputeWorkGroupCount[0];
      dev->max_binding_bytes_ = props.limits.maxStorageBufferRange;
      if (options.max_binding_bytes != 0)
        dev->max_binding_bytes_ =
            std::min<std::uint64_t>(dev->max_binding_bytes_, options.max_binding_bytes);
    }
  }
  if (!found)
    return Error(ErrorCode::kMissingFeature,
                 "device '" + dev->info_.name + "' has no compute queue");

  float priority = 1.0f;
  VkDeviceQueueCreateInfo qinfo{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qinfo.queueFamilyIndex = dev->queue_family_;
  qinfo.queueCount = 1;
  qinfo.pQueuePriorities = &priority;
  VkPhysicalDeviceVulkan12Features want12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  want12.shaderBufferInt64Atomics = VK_TRUE;
  want12.bufferDeviceAddress = VK_TRUE;
  // Optional: lets callers hand input over with a timeline semaphore (vulkan_interop.hpp).
  want12.timelineSemaphore = f12.timelineSemaphore;
  VkPhysicalDeviceFeatures2 want{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  want.pNext = &want12;
  want.features.shaderInt64 = VK_TRUE;
  want.features.shaderFloat64 = VK_TRUE;
  // Optional: memory and semaphores shared with other APIs (CUDA, another Vulkan device) by
  // POSIX file descriptor, for callers that hand input over on the device (vulkan_interop.hpp).
  const std::vector<VkExtensionProperties> available = deviceExtensions(dev->physical_);
  std::vector<const char*> extensions;
  for (const char* name :
       {VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME, VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME})
    if (hasDeviceExtension(available, name)) {
      extensions.push_back(name);
      dev->extensions_.emplace_back(name);
    }
  // Optional: ray queries for castRay's ray-tracing backend (see rayTracingSupport).
  VkPhysicalDeviceAccelerationStructureFeaturesKHR want_as{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
  VkPhysicalDeviceRayQueryFeaturesKHR want_rq{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};
  const bool ray_query = options.enable_ray_query && dev->info_.ray_query;
  if (ray_query) {
    for (const char* name :
         {VK_KHR_DEFERRED_HOST_OPERATIONS_EXTENSION_NAME,
          VK_KHR_ACCELERATION_STRUCTURE_EXTENSION_NAME, VK_KHR_RAY_QUERY_EXTENSION_NAME}) {
      extensions.push_back(name);
      dev->extensions_.emplace_back(name);
    }
    want_as.accelerationStructure = VK_TRUE;
    want_rq.rayQuery = VK_TRUE;
    want_rq.pNext = &want_as;
    want12.pNext = &want_rq;
  }
  VkDeviceCreateInfo dinfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dinfo.pNext = &want;
  dinfo.queueCreateInfoCount = 1;
  dinfo.pQueueCreateInfos = &qinfo;
  dinfo.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  dinfo.ppEnabledExtensionNames = extensions.data();
  try {
    OCTOVK_VK(vkCreateDevice(dev->physical_, &dinfo, nullptr, &dev->device_));
    vkGetDeviceQueue(dev->device_, dev->queue_family_, 0, &dev->queue_);
    if (ray_query) {
      auto api = std::make_unique<RayQueryApi>();
      const auto load = [&](const char* name) { return vkGetDeviceProcAddr(dev->device_, name); };
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
      vkGetPhysicalDeviceProperties2(dev->physical_, &props2);
      api->scratch_alignment =
          std::max<VkDeviceSize>(asp.minAccelerationStructureScratchOffsetAlignment, 1);
      if (!api->create || !api->destroy || !api->buildSizes || !api->cmdBuild || !api->address)
        return Error(ErrorCode::kVulkan, "device '" + dev->info_.name +
                                             "' enabled VK_KHR_acceleration_structure but lacks "
                                             "its entry points; create the Context with "
                                             "ContextOptions::enable_ray_query = false");
      dev->ray_query_ = std::move(api);
      dev->info_.ray_query_enabled = true;
    }
    vkGetPhysicalDeviceMemoryProperties(dev->physical_, &dev->memory_);

    // The map's bindings, then the address table (kBindAddresses).
    std::vector<VkDescriptorSetLayoutBinding> bindings(gpu::kBindingCount + 1);
    for (std::uint32_t i = 0; i <= gpu::kBindingCount; ++i) {
      bindings[i] = {};
      bindings[i].binding = i;
      bindings[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      bindings[i].descriptorCount = 1;
      bindings[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo linfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    linfo.bindingCount = gpu::kBindingCount + 1;
    linfo.pBindings = bindings.data();
    OCTOVK_VK(vkCreateDescriptorSetLayout(dev->device_, &linfo, nullptr, &dev->set_layout_));
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::PassConstants)};
    VkPipelineLayoutCreateInfo pinfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pinfo.setLayoutCount = 1;
    pinfo.pSetLayouts = &dev->set_layout_;
    pinfo.pushConstantRangeCount = 1;
    pinfo.pPushConstantRanges = &range;
    OCTOVK_VK(vkCreatePipelineLayout(dev->device_, &pinfo, nullptr, &dev->pipeline_layout_));
  } catch (const Error& e) {
    return e;
  }
  return dev;
}

Device::~Device() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    for (auto& slot : passes_)
      if (slot.pass.pipeline) vkDestroyPipeline(device_, slot.pass.pipeline, nullptr);
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
  OCTOVK_VK(vkQueueSubmit(queue_, 1, &info, fence));
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
  const VkResult r =
      vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cinfo, nullptr, &pipeline);
  vkDestroyShaderModule(device_, module, nullptr);
  check(r, "vkCreateComputePipelines", __FILE__, __LINE__);
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

namespace octovk {
std::size_t validationMessageCount() noexcept {
  return vk::validation_messages.load(std::memory_order_relaxed);
}
}  // namespace octovk
