#include "vk/device.hpp"

namespace octovk {

Context::Context(std::unique_ptr<vk::Device> device) : device_(std::move(device)) {}
Context::~Context() = default;

Result<std::unique_ptr<Context>> Context::create(const ContextOptions& options) {
  auto device = vk::Device::create(options);
  if (!device) return device.error();
  return std::unique_ptr<Context>(new Context(std::move(device.value())));
}

const DeviceInfo& Context::device() const noexcept { return device_->info(); }

std::vector<DeviceInfo> Context::listDevices() { return vk::Device::enumerate(); }

}  // namespace octovk
