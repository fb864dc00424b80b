#include <stdlib.h>  // setenv

#include <cstdlib>
#include <memory>
#include <string>

#include "map/device_probe.hpp"
#include "vk/device.hpp"

namespace octovk {

Context::Context(std::unique_ptr<vk::Device> device) : device_(std::move(device)) {}
// After exit() began (or in a forked child) the device is left to the end of the process, held
// where leak checkers see it (vk::Device::abandoned), as the maps and fields on it are.
Context::~Context() {
  if (device_ && device_->abandoned())
    vk::Device::keepUntilExit(new std::shared_ptr<vk::Device>(std::move(device_)));
}

Result<std::unique_ptr<Context>> Context::create(const ContextOptions& options) {
  auto device = vk::Device::create(options);
  if (!device) return device.error();
  // What the exact walk takes from the device, checked before any map trusts it (or the
  // verdict an earlier process kept for this device, driver and build).
  auto probe = checkDevice(*device.value());
  if (!probe) return probe.error();
  const std::uint32_t limit = probe.value().loop_limit;
  if (limit != 0 && limit < 4096u)
    return Error(ErrorCode::kMissingFeature,
                 "device '" + device.value()->info().name + "' ends shader loops after " +
                     std::to_string(limit) +
                     " iterations, too few for the resumable ray walks; choose another device "
                     "with OCTOVK_DEVICE");
  device.value()->setLoopLimit(limit);
  return std::unique_ptr<Context>(new Context(std::move(device.value())));
}

const DeviceInfo& Context::device() const noexcept { return device_->info(); }

std::vector<DeviceInfo> Context::listDevices() { return vk::Device::enumerate(); }

namespace {
bool g_threads_chosen = false;  // written only by preferCpuDriverThreads, before other threads
}  // namespace

CpuDriverThreads preferCpuDriverThreads(unsigned threads) {
  const char* set = std::getenv("LP_NUM_THREADS");
  if (set == nullptr && ::setenv("LP_NUM_THREADS", std::to_string(threads).c_str(), 0) == 0)
    g_threads_chosen = true;
  return cpuDriverThreads();
}

CpuDriverThreads cpuDriverThreads() {
  const char* set = std::getenv("LP_NUM_THREADS");
  return {set != nullptr ? std::string(set) : std::string(), set != nullptr && g_threads_chosen};
}

}  // namespace octovk
