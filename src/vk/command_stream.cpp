#include "vk/command_stream.hpp"

#include <algorithm>

#include "vk/check.hpp"
#include "vk/device.hpp"

namespace octovk::vk {

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
    if (queries_) vkDestroyQueryPool(device.handle(), queries_, nullptr);
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
  if (!queries_ || f.query_count >= kMaxQueries || timestamps_off_) return f.query_count;
  if (!timestamps_.valid()) {
    // Made at the first timestamp: a stream that records none holds no buffer for them. They
    // are statistics: without memory for them, the stream records none.
    try {
      timestamps_ =
          Buffer(device_, std::size_t{kMaxQueries} * frames() * sizeof(std::uint64_t), true);
    } catch (const Error&) {
      timestamps_off_ = true;
      return f.query_count;
    }
  }
  vkCmdWriteTimestamp(f.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries_,
                      current_ * kMaxQueries + f.query_count);
  return f.query_count++;
}

std::vector<double> CommandStream::timestampsNs(std::uint32_t frame) {
  const Frame& f = frames_.at(frame);
  if (!queries_ || f.query_count == 0 || f.serial == 0 || !f.done) return {};
  const auto* ticks =
      static_cast<const std::uint64_t*>(timestamps_.mapped()) + std::size_t{frame} * kMaxQueries;
  std::vector<double> ns(f.query_count);
  for (std::size_t i = 0; i < ns.size(); ++i)
    ns[i] = static_cast<double>(ticks[i]) * device_.timestampPeriodNs();
  return ns;
}

void CommandStream::waitBeforeNextSubmit(VkSemaphore semaphore, std::uint64_t value) {
  wait_semaphore_ = semaphore;
  wait_value_ = value;
}

void CommandStream::signalAfterNextSubmit(VkSemaphore semaphore, std::uint64_t value) {
  signal_semaphore_ = semaphore;
  signal_value_ = value;
}

std::uint64_t CommandStream::submit() {
  Frame& f = frames_[current_];
  // The frame's timestamps to host memory, read once its fence is signalled (timestampsNs).
  if (f.query_count > 0)
    vkCmdCopyQueryPoolResults(
        f.cmd, queries_, current_ * kMaxQueries, f.query_count, timestamps_.handle(),
        std::size_t{current_} * kMaxQueries * sizeof(std::uint64_t), sizeof(std::uint64_t),
        VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
  // What the submission wrote, visible to the host once the fence is signalled: a fence's
  // memory dependency covers device accesses only (readbacks, captures, timestamps).
  VkMemoryBarrier host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  host.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
  host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(f.cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                       &host, 0, nullptr, 0, nullptr);
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
  // A caller's semaphore to signal (interop output): a semaphore signal covers every command
  // submitted before it on the queue, so the caller's submissions that wait for it see them.
  const VkSemaphore signal = signal_semaphore_;
  const std::uint64_t signal_value = signal_value_;
  signal_semaphore_ = VK_NULL_HANDLE;
  if (signal != VK_NULL_HANDLE) {
    timeline.signalSemaphoreValueCount = 1;
    timeline.pSignalSemaphoreValues = &signal_value;
    submit.pNext = &timeline;
    submit.signalSemaphoreCount = 1;
    submit.pSignalSemaphores = &signal;
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

}  // namespace octovk::vk
