// octovk: The Vulkan device every map of a process shares, how to pick it, and what it is.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "octovk/errors.hpp"

namespace octovk {

/// Which device to use: empty picks a real GPU when present, else lavapipe. The OCTOVK_DEVICE
/// environment variable (index or name substring) overrides when `selector` is empty.
struct ContextOptions {
  std::string selector;
  /// Runs every Vulkan call through the Khronos validation layer (core and synchronization
  /// validation; package vulkan-validationlayers). The OCTOVK_VALIDATION environment variable
  /// (set and not "0") turns it on too. For debugging and tests: it is slow.
  bool enable_validation = false;
  /// Receives each validation warning or error (one line each), in the thread of the Vulkan call
  /// that caused it. Without it, messages go to stderr. Either way they are counted
  /// (validationMessageCount()).
  std::function<void(const std::string&)> on_validation_message;
  /// For tests: treat the device's maxStorageBufferRange as at most this many bytes (0: the
  /// device's own), to check that no binding depends on a large range.
  std::uint64_t max_binding_bytes = 0;
  /// Enable ray tracing where the device has it (VK_KHR_acceleration_structure with
  /// VK_KHR_ray_query and/or VK_KHR_ray_tracing_pipeline), for castRay's and the scans'
  /// ray-tracing backends. false: never (the compute walk only).
  bool enable_ray_query = true;
};

/// Validation messages received by every Context of this process so far.
std::size_t validationMessageCount() noexcept;

/// The device a Context runs on.
struct DeviceInfo {
  std::string name;
  std::string type;    ///< "discrete GPU", "integrated GPU", "CPU", ...
  std::string driver;  ///< driver name and version, e.g. "llvmpipe: Mesa 25.0.7 (LLVM 15.0.6)"
  std::uint32_t index = 0;
  std::uint64_t memory_bytes = 0;
  /// The device offers ray queries against acceleration structures (VK_KHR_acceleration_structure
  /// and VK_KHR_ray_query with their features): castRay can use its ray-tracing backend.
  bool ray_query = false;
  /// It offers ray-tracing pipelines (VK_KHR_ray_tracing_pipeline): castRay and traced scans
  /// run through them where ray queries are missing (NVIDIA's GPUs), or when asked for
  /// (CastRayBackend::kRayTracingPipeline).
  bool ray_tracing_pipeline = false;
  /// Ray queries are enabled on this Context's device (Context::device() only; false in
  /// listDevices()).
  bool ray_query_enabled = false;
};

namespace vk {
class Device;
}
class InteropAccess;

/// The Vulkan device every map of a process shares.
///
/// Threads: a Context may be shared by maps used from different threads at once (their
/// submissions to the device's one queue and the pipelines built at first use are serialised
/// inside). One OccupancyMap is used from one thread at a time: its non-const calls, the queries
/// included (they record into the map's own command buffers), must be ordered by the caller
/// against every other call on that map; its const members (host state only) may run beside each
/// other. Different maps need no ordering.
///
/// Lifetime: each map keeps the device alive, so a Context may be destroyed before its maps;
/// the device goes with the last of them.
class Context {
 public:
  static Result<std::unique_ptr<Context>> create(const ContextOptions& options = {});
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device() const noexcept;
  /// Every usable Vulkan device, for --help and error messages.
  static std::vector<DeviceInfo> listDevices();

 private:
  friend struct ContextAccess;  // src/map/context_access.hpp: the library's way to the device
  explicit Context(std::unique_ptr<vk::Device> device);
  std::shared_ptr<vk::Device> device_;
};

/// LP_NUM_THREADS as a process holds it: the worker threads of lavapipe, Mesa's CPU Vulkan driver
/// (GPU drivers ignore it).
struct CpuDriverThreads {
  std::string setting;             ///< its value; empty: unset, lavapipe's default (a thread per core)
  bool chosen_by_octovk = false;   ///< set by preferCpuDriverThreads, not by the environment
};

/// Sets LP_NUM_THREADS to `threads` unless the environment already sets it, and says what holds.
/// The driver reads it once, when the first Context loads it, so call this first (the octovk
/// program does for its mapping commands, the Python module at import). Why 0: a scan is about 50
/// small dispatches, and on 2 cores lavapipe's threads made streams of small scans about 2x slower
/// and collapsed when another process kept the cores busy (docs/benchmarks.md, "The machine").
/// Not thread-safe (it writes the environment): call it before other threads start.
CpuDriverThreads preferCpuDriverThreads(unsigned threads);
/// What holds now, and whether preferCpuDriverThreads chose it.
CpuDriverThreads cpuDriverThreads();

}  // namespace octovk
