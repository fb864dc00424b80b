// A caller's buffer for the interop tests: a host-visible, host-coherent storage buffer made with
// the Vulkan API alone on the context's device, as an application would make one; and a GPU
// consumer that waits on the device for a timeline value octovk signals.
#pragma once

#include <gtest/gtest.h>
#include <vulkan/vulkan.h>

#include "octovk/vulkan_interop.hpp"

namespace octovk::test {

/// Call before destroying a semaphore that octovk's calls waited on. By the spec it could go as
/// soon as they returned: every batch that used it has completed (octovk's calls wait for their
/// fences). But Mesa's common queue (lavapipe 22.3 at least), once a wait-before-signal has put
/// it in threaded submit mode, releases a submission's wait on a timeline only after the driver
/// ran it, so the fence can signal first; a semaphore destroyed in that gap leaks the driver's
/// time point (160 + 112 bytes; LeakSanitizer saw it in 1 of 10 runs of the distance field's
/// interop test) after the driver touches the freed semaphore. vkQueueWaitIdle goes through the
/// same submit thread, so it returns after that release.
inline void idleQueueBeforeDestroyingSemaphores(Context& context, const VulkanHandles& vk) {
  const auto lock = lockQueue(context);
  EXPECT_EQ(vkQueueWaitIdle(vk.queue), VK_SUCCESS);
}

class CallerBuffer {
 public:
  CallerBuffer(const VulkanHandles& vk, VkDeviceSize bytes) : device_(vk.device) {
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = bytes;
    // TRANSFER_DST too: a test's own consumer copies results into one (a caller's submission).
    info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                 VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    EXPECT_EQ(vkCreateBuffer(device_, &info, nullptr, &buffer_), VK_SUCCESS);
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, buffer_, &req);
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(vk.physical_device, &props);
    const VkMemoryPropertyFlags want =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    std::uint32_t type = 0;
    while (type < props.memoryTypeCount &&
           !((req.memoryTypeBits & (1u << type)) &&
             (props.memoryTypes[type].propertyFlags & want) == want))
      ++type;
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = type;
    EXPECT_EQ(vkAllocateMemory(device_, &alloc, nullptr, &memory_), VK_SUCCESS);
    vkBindBufferMemory(device_, buffer_, memory_, 0);
    vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_);
  }
  ~CallerBuffer() {
    vkDestroyBuffer(device_, buffer_, nullptr);
    vkFreeMemory(device_, memory_, nullptr);
  }
  CallerBuffer(const CallerBuffer&) = delete;
  CallerBuffer& operator=(const CallerBuffer&) = delete;
  BufferRange range() const { return {buffer_, 0, VK_WHOLE_SIZE}; }
  void* data() const { return mapped_; }

 private:
  VkDevice device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
};

/// A GPU consumer of octovk's results: its own timeline semaphore (for octovk's SignalSemaphore
/// or WaitSemaphore), and copyAfter(), a submission of its own that waits on the device for a
/// value of that semaphore, then copies a caller buffer into another. What it copied is what
/// the device held once the value was reached.
class DeviceConsumer {
 public:
  DeviceConsumer(Context& context, const VulkanHandles& vk) : context_(context), vk_(vk) {
    VkSemaphoreTypeCreateInfo type{VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO};
    type.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
    VkSemaphoreCreateInfo sem_info{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    sem_info.pNext = &type;
    EXPECT_EQ(vkCreateSemaphore(vk.device, &sem_info, nullptr, &timeline_), VK_SUCCESS);
    VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool_info.queueFamilyIndex = vk.queue_family;
    EXPECT_EQ(vkCreateCommandPool(vk.device, &pool_info, nullptr, &pool_), VK_SUCCESS);
    VkFenceCreateInfo fence_info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    EXPECT_EQ(vkCreateFence(vk.device, &fence_info, nullptr, &fence_), VK_SUCCESS);
  }
  ~DeviceConsumer() {
    idleQueueBeforeDestroyingSemaphores(context_, vk_);
    vkDestroyFence(vk_.device, fence_, nullptr);
    vkDestroyCommandPool(vk_.device, pool_, nullptr);
    vkDestroySemaphore(vk_.device, timeline_, nullptr);
  }
  DeviceConsumer(const DeviceConsumer&) = delete;
  DeviceConsumer& operator=(const DeviceConsumer&) = delete;

  VkSemaphore timeline() const { return timeline_; }

  /// The host signals the timeline to `value` (a producer's stand-in).
  void signalFromHost(std::uint64_t value) {
    VkSemaphoreSignalInfo signal{VK_STRUCTURE_TYPE_SEMAPHORE_SIGNAL_INFO};
    signal.semaphore = timeline_;
    signal.value = value;
    EXPECT_EQ(vkSignalSemaphore(vk_.device, &signal), VK_SUCCESS);
  }

  /// A producer on the device: a submission that copies `bytes` of `from` into `to` and then
  /// signals the timeline to `value`, submitted now and not waited for (finishProducer() waits).
  /// Submitted before a call that waits for `value` on the Context's shared queue, it keeps
  /// forward progress (a signal submitted after the wait on one queue would not).
  void produceThenSignal(const CallerBuffer& from, const CallerBuffer& to, VkDeviceSize bytes,
                         std::uint64_t value) {
    producer_cmd_ = beginCopy(from, to, bytes);
    ASSERT_NE(producer_cmd_, VK_NULL_HANDLE);
    ASSERT_EQ(vkEndCommandBuffer(producer_cmd_), VK_SUCCESS);
    VkTimelineSemaphoreSubmitInfo values{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
    values.signalSemaphoreValueCount = 1;
    values.pSignalSemaphoreValues = &value;
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.pNext = &values;
    submit.signalSemaphoreCount = 1;
    submit.pSignalSemaphores = &timeline_;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &producer_cmd_;
    const auto lock = lockQueue(context_);  // the Context's queue is shared
    ASSERT_EQ(vkQueueSubmit(vk_.queue, 1, &submit, fence_), VK_SUCCESS);
  }
  /// Waits for produceThenSignal's submission.
  void finishProducer() {
    waitFence();
    vkFreeCommandBuffers(vk_.device, pool_, 1, &producer_cmd_);
    producer_cmd_ = VK_NULL_HANDLE;
  }

  /// Waits on the device for `value`, then copies `bytes` of `from` into `to`; returns when the
  /// copy is done (and checks that the timeline reached `value`).
  void copyAfter(const CallerBuffer& from, const CallerBuffer& to, VkDeviceSize bytes,
                 std::uint64_t value) {
    VkCommandBuffer cmd = beginCopy(from, to, bytes);
    ASSERT_NE(cmd, VK_NULL_HANDLE);
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                         &to_host, 0, nullptr, 0, nullptr);
    ASSERT_EQ(vkEndCommandBuffer(cmd), VK_SUCCESS);
    VkTimelineSemaphoreSubmitInfo values{VK_STRUCTURE_TYPE_TIMELINE_SEMAPHORE_SUBMIT_INFO};
    values.waitSemaphoreValueCount = 1;
    values.pWaitSemaphoreValues = &value;
    const VkPipelineStageFlags stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.pNext = &values;
    submit.waitSemaphoreCount = 1;
    submit.pWaitSemaphores = &timeline_;
    submit.pWaitDstStageMask = &stage;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    {
      // The Context's queue is shared: held while submitting.
      const auto lock = lockQueue(context_);
      ASSERT_EQ(vkQueueSubmit(vk_.queue, 1, &submit, fence_), VK_SUCCESS);
    }
    waitFence();
    vkFreeCommandBuffers(vk_.device, pool_, 1, &cmd);
    std::uint64_t reached = 0;
    ASSERT_EQ(vkGetSemaphoreCounterValue(vk_.device, timeline_, &reached), VK_SUCCESS);
    EXPECT_GE(reached, value);
  }

 private:
  // A one-time command buffer from the pool, begun, holding a copy of `bytes` of `from` into
  // `to`; VK_NULL_HANDLE (and a failure recorded) if it could not be made.
  VkCommandBuffer beginCopy(const CallerBuffer& from, const CallerBuffer& to, VkDeviceSize bytes) {
    VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    alloc.commandPool = pool_;
    alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    alloc.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    if (vkAllocateCommandBuffers(vk_.device, &alloc, &cmd) != VK_SUCCESS) {
      ADD_FAILURE() << "vkAllocateCommandBuffers failed";
      return VK_NULL_HANDLE;
    }
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    if (vkBeginCommandBuffer(cmd, &begin) != VK_SUCCESS) {
      ADD_FAILURE() << "vkBeginCommandBuffer failed";
      vkFreeCommandBuffers(vk_.device, pool_, 1, &cmd);
      return VK_NULL_HANDLE;
    }
    const VkBufferCopy region{0, 0, bytes};
    vkCmdCopyBuffer(cmd, from.range().buffer, to.range().buffer, 1, &region);
    return cmd;
  }
  // Waits for this consumer's one submission in flight (10 s at most) and resets its fence.
  void waitFence() {
    ASSERT_EQ(vkWaitForFences(vk_.device, 1, &fence_, VK_TRUE, 10'000'000'000ull), VK_SUCCESS);
    ASSERT_EQ(vkResetFences(vk_.device, 1, &fence_), VK_SUCCESS);
  }

  Context& context_;
  VulkanHandles vk_;
  VkSemaphore timeline_ = VK_NULL_HANDLE;
  VkCommandBuffer producer_cmd_ = VK_NULL_HANDLE;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
};

}  // namespace octovk::test
