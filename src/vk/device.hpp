// The thin Vulkan layer: device selection, buffers, compute passes and command streams.
// Mapping code asks for "a buffer", "a pass", "a dispatch"; only this folder knows Vulkan.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk::vk {

/// Throws octovk::Error(kVulkan) naming the call, the VkResult and the place when r fails.
void check(VkResult r, const char* call, const char* file, int line);
#define OCTOVK_VK(call) ::octovk::vk::check((call), #call, __FILE__, __LINE__)

const char* resultName(VkResult r);

class Device;

/// A storage buffer with one owner. Device-local unless created host-visible.
class Buffer {
 public:
  Buffer() = default;
  Buffer(Device& device, std::size_t bytes, bool host_visible);
  /// With usages beyond the storage/transfer/indirect/address set every buffer has (the
  /// acceleration-structure ones: only on a device with ray queries enabled).
  Buffer(Device& device, std::size_t bytes, bool host_visible, VkBufferUsageFlags extra_usage);
  ~Buffer();
  Buffer(Buffer&& other) noexcept;
  Buffer& operator=(Buffer&& other) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer handle() const noexcept { return buffer_; }
  std::size_t size() const noexcept { return bytes_; }
  bool valid() const noexcept { return buffer_ != VK_NULL_HANDLE; }
  /// Host pointer of a host-visible buffer (persistently mapped).
  void* mapped() const noexcept { return mapped_; }
  /// Device address (bufferDeviceAddress), for the bindings the shaders reach by address.
  VkDeviceAddress address() const noexcept { return address_; }

 private:
  void release() noexcept;
  Device* device_ = nullptr;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  std::size_t bytes_ = 0;
  void* mapped_ = nullptr;
  VkDeviceAddress address_ = 0;
};

/// One compute pipeline built from embedded SPIR-V; all passes share one pipeline layout.
struct Pass {
  VkPipeline pipeline = VK_NULL_HANDLE;
  std::string name;
};

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

/// Records passes into command buffers and submits them in order on the device's queue. With
/// `frames` > 1 a submission need not be waited for: the next recording uses the next of
/// `frames` command buffers (each with its fence and timestamp range), waiting only when that
/// one's earlier submission is still running. Every recording starts with a full barrier, so a
/// submission sees everything earlier submissions wrote.
class CommandStream {
 public:
  explicit CommandStream(Device& device, std::uint32_t frames = 1);
  ~CommandStream();  // waits for every submission
  CommandStream(const CommandStream&) = delete;
  CommandStream& operator=(const CommandStream&) = delete;

  /// Starts recording into frame nextFrame(), after waiting for its previous submission.
  void begin(const BindingSet& bindings);
  void dispatch(const Pass& pass, std::uint32_t groups, const void* constants,
                std::uint32_t constants_bytes);
  void dispatchIndirect(const Pass& pass, const Buffer& args, std::size_t offset,
                        const void* constants, std::uint32_t constants_bytes);
  /// Makes every earlier shader/transfer write visible to later shaders, transfers and
  /// indirect-argument reads.
  void barrier();
  void copy(const Buffer& src, const Buffer& dst, std::size_t bytes, std::size_t src_offset = 0,
            std::size_t dst_offset = 0);
  /// A copy from a buffer the caller owns (interop), which must have TRANSFER_SRC usage.
  void copyFrom(VkBuffer src, VkDeviceSize src_offset, const Buffer& dst, std::size_t bytes,
                std::size_t dst_offset = 0);
  void fill(const Buffer& dst, std::uint32_t value, std::size_t offset = 0,
            std::size_t bytes = VK_WHOLE_SIZE);
  void update(const Buffer& dst, const void* data, std::size_t bytes, std::size_t offset = 0);
  /// Records a device timestamp once all earlier work is done; returns its index in this
  /// recording. Without timestamp support it records nothing.
  std::uint32_t timestamp();
  /// The next submission waits for `semaphore` (a timeline semaphore: for `value`; a binary
  /// one: signalled, and unsignalled by the wait) before any of its commands run.
  void waitBeforeNextSubmit(VkSemaphore semaphore, std::uint64_t value);
  /// Ends recording and submits; returns the submission's serial (1, 2, ... in order).
  std::uint64_t submit();
  /// Waits until submission `serial` (and so every earlier one) has completed.
  void wait(std::uint64_t serial);
  /// Whether submission `serial` has completed (does not wait).
  bool finished(std::uint64_t serial);
  /// Waits for every submission.
  void waitIdle();
  /// Ends recording, submits and waits for completion.
  void submitAndWait() { wait(submit()); }

  std::uint32_t frames() const noexcept { return static_cast<std::uint32_t>(frames_.size()); }
  /// The frame the next begin() records into.
  std::uint32_t nextFrame() const noexcept {
    return static_cast<std::uint32_t>(submitted_ % frames_.size());
  }
  /// The frame being recorded (or last recorded).
  std::uint32_t frame() const noexcept { return current_; }
  /// Submissions so far, and the waits that found their submission still running (the host
  /// blocked).
  std::uint64_t submissions() const noexcept { return submitted_; }
  std::uint64_t blockingWaits() const noexcept { return blocking_waits_; }
  /// Device times in nanoseconds of the timestamps of frame `frame`'s last submission, once it
  /// has completed (empty if the device has no timestamps).
  std::vector<double> timestampsNs(std::uint32_t frame);
  /// Of the last submission.
  std::vector<double> timestampsNs() { return timestampsNs(current_); }
  /// The command buffer being recorded, for the recorders of this folder (vk/accel.cpp).
  VkCommandBuffer commandBuffer() const noexcept { return frames_[current_].cmd; }

 private:
  struct Frame {
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
    std::uint64_t serial = 0;  // of its last submission (0: none)
    std::uint32_t query_count = 0;
    bool done = false;  // its fence was seen signalled
  };
  VkCommandBuffer cmd() const { return frames_[current_].cmd; }
  void waitFrame(Frame& f);
  Device& device_;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  std::vector<Frame> frames_;
  std::uint32_t current_ = 0;
  std::uint64_t submitted_ = 0;  // serial of the last submission
  std::uint64_t blocking_waits_ = 0;
  VkQueryPool queries_ = VK_NULL_HANDLE;
  bool recording_ = false;
  VkSemaphore wait_semaphore_ = VK_NULL_HANDLE;
  std::uint64_t wait_value_ = 0;
  static constexpr std::uint32_t kMaxQueries = 64;  // per frame
};

/// Instance, physical device, logical device, queue and the shared pipeline layout.
class Device {
 public:
  /// Fails with kNoDevice / kMissingFeature for the ordinary reasons.
  static Result<std::unique_ptr<Device>> create(const ContextOptions& options);
  static std::vector<DeviceInfo> enumerate();
  ~Device();
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  const DeviceInfo& info() const noexcept { return info_; }
  VkDevice handle() const noexcept { return device_; }
  /// Submits to the device's one queue under its lock: every map of a Context records on its
  /// own command pool but shares this queue, which Vulkan requires externally synchronised.
  void submit(const VkSubmitInfo& info, VkFence fence);
  /// The queue, for interop callers, who must hold lockQueue() while they use it.
  VkQueue queue() const noexcept { return queue_; }
  std::unique_lock<std::mutex> lockQueue() { return std::unique_lock<std::mutex>(queue_mutex_); }
  std::uint32_t queueFamily() const noexcept { return queue_family_; }
  VkPipelineLayout pipelineLayout() const noexcept { return pipeline_layout_; }
  VkDescriptorSetLayout setLayout() const noexcept { return set_layout_; }
  /// Nanoseconds per timestamp tick, or 0 when the compute queue has no timestamps.
  double timestampPeriodNs() const noexcept { return timestamp_period_ns_; }
  /// minStorageBufferOffsetAlignment: offsets of bound buffer ranges must be multiples of it.
  VkDeviceSize storageOffsetAlignment() const noexcept { return storage_alignment_; }
  /// maxStorageBufferRange (or ContextOptions::max_binding_bytes if lower): the most bytes one
  /// descriptor binding may reach.
  std::uint64_t maxBindingBytes() const noexcept { return max_binding_bytes_; }
  /// maxComputeWorkGroupCount[0]: the most workgroups an indirect dispatch may ask for.
  std::uint32_t maxGroupsX() const noexcept { return max_groups_x_; }
  VkInstance instance() const noexcept { return instance_; }
  /// Ray queries against acceleration structures (VK_KHR_acceleration_structure and
  /// VK_KHR_ray_query, with their features) are enabled on this device.
  bool rayQuery() const noexcept { return ray_query_ != nullptr; }
  /// The acceleration-structure entry points and limits; only when rayQuery().
  struct RayQueryApi {
    PFN_vkCreateAccelerationStructureKHR create = nullptr;
    PFN_vkDestroyAccelerationStructureKHR destroy = nullptr;
    PFN_vkGetAccelerationStructureBuildSizesKHR buildSizes = nullptr;
    PFN_vkCmdBuildAccelerationStructuresKHR cmdBuild = nullptr;
    PFN_vkGetAccelerationStructureDeviceAddressKHR address = nullptr;
    VkDeviceSize scratch_alignment = 1;  ///< minAccelerationStructureScratchOffsetAlignment
  };
  const RayQueryApi& rayQueryApi() const noexcept { return *ray_query_; }
  /// Whether an optional device extension (external memory / semaphore by fd) was enabled.
  bool hasExtension(std::string_view name) const noexcept {
    for (const std::string& e : extensions_)
      if (e == name) return true;
    return false;
  }
  VkPhysicalDevice physical() const noexcept { return physical_; }

  /// Loop iterations after which the driver ends an invocation's loops (llvmpipe: 65535, counted
  /// for a whole SIMD batch), as the device probe measured it; 0 when it saw no limit.
  std::uint32_t loopLimit() const noexcept { return loop_limit_; }
  void setLoopLimit(std::uint32_t limit) noexcept { loop_limit_ = limit; }
  /// Loop iterations a resumable walk (ray keys, castRay) takes per dispatch: 30000 per 65535 of
  /// the measured limit (room for the loops around the walk and the batch's other lanes), or
  /// all it needs where there is no limit.
  std::uint32_t walkBudget() const noexcept {
    return loop_limit_ == 0
               ? 0x7FFFFFFFu
               : static_cast<std::uint32_t>(std::uint64_t{loop_limit_} * 30000u / 65535u);
  }
  /// Continuation dispatches a resumable walk of at most `worst_iterations` needs after its
  /// first one: enough budgets to cover it where loops are limited, none elsewhere.
  std::uint32_t walkContinuations(std::uint64_t worst_iterations) const noexcept {
    if (loop_limit_ == 0) return 0u;
    const std::uint64_t budget = walkBudget();
    return static_cast<std::uint32_t>((worst_iterations + budget - 1) / budget);
  }

  /// The pass built from the embedded shader `name` (e.g. "ray_keys"), built once, by the
  /// first caller from any thread (the others wait for it).
  const Pass& pass(std::string_view name);

  /// Memory type index for the given requirements; throws kOutOfDeviceMemory if none.
  std::uint32_t memoryType(std::uint32_t type_bits, VkMemoryPropertyFlags wanted,
                           VkMemoryPropertyFlags fallback) const;

 private:
  Device() = default;
  DeviceInfo info_;
  std::function<void(const std::string&)> validation_sink_;  // before the instance that uses it
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout_ = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory_{};
  double timestamp_period_ns_ = 0.0;
  VkDeviceSize storage_alignment_ = 256;
  std::uint32_t max_groups_x_ = 65535;
  std::uint32_t loop_limit_ = 0;
  std::uint64_t max_binding_bytes_ = 1u << 27;
  std::mutex queue_mutex_;   // guards queue_ (vkQueueSubmit)
  struct PassSlot {
    Pass pass;
    std::once_flag built;  // set once pass.pipeline is built
  };
  VkPipeline buildPipeline(std::string_view name);
  std::mutex passes_mutex_;      // guards the deque (not the builds: see pass())
  std::deque<PassSlot> passes_;  // deque: slots never move
  std::vector<std::string> extensions_;     // optional device extensions enabled
  std::unique_ptr<RayQueryApi> ray_query_;  // set when ray queries are enabled
};

}  // namespace octovk::vk
