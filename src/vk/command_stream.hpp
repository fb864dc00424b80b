// Command buffers on the device's queue: passes recorded, submitted in order, waited for.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "vk/binding_set.hpp"
#include "vk/buffer.hpp"

namespace octovk::vk {

class Device;

/// One compute pipeline built from embedded SPIR-V; all passes share one pipeline layout.
struct Pass {
  VkPipeline pipeline = VK_NULL_HANDLE;
  std::string name;
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
  /// recording. Without timestamp support (or host memory for the results) it records nothing.
  std::uint32_t timestamp();
  /// The next submission waits for `semaphore` (a timeline semaphore: for `value`; a binary
  /// one: signalled, and unsignalled by the wait) before any of its commands run.
  void waitBeforeNextSubmit(VkSemaphore semaphore, std::uint64_t value);
  /// The next submission signals `semaphore` (a timeline semaphore: to `value`; a binary one:
  /// signalled) when all of its commands, and every earlier submission's, are done.
  void signalAfterNextSubmit(VkSemaphore semaphore, std::uint64_t value);
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
  /// Each frame's timestamps, copied there by its submission (vkCmdCopyQueryPoolResults): read
  /// once the frame is done without vkGetQueryPoolResults, which some drivers (lavapipe) make
  /// wait for the whole device, the scans submitted after the frame included.
  Buffer timestamps_;
  bool timestamps_off_ = false;  // no memory for timestamps_: none are recorded
  bool recording_ = false;
  VkSemaphore wait_semaphore_ = VK_NULL_HANDLE;
  std::uint64_t wait_value_ = 0;
  VkSemaphore signal_semaphore_ = VK_NULL_HANDLE;
  std::uint64_t signal_value_ = 0;
  static constexpr std::uint32_t kMaxQueries = 64;  // per frame
};

}  // namespace octovk::vk
